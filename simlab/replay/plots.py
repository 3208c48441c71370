"""The cumulative-reward figure of the replay (thesis Fig. 4.10), headless (Agg)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from simlab.base.io import atomic_write


@dataclass(frozen=True)
class RewardCurve:
    """A step curve: ``times`` (n,) robot seconds at which each reward was earned, the
    run's total duration ``duration`` (s) and a legend ``label``."""

    label: str
    times: NDArray[np.float64]
    duration: float


def cumulative_steps(times: NDArray[np.float64], duration: float
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(x hours, y cumulative reward)`` of a step curve from 0 to ``duration`` seconds."""
    t = np.sort(np.asarray(times, dtype=np.float64))
    x = np.concatenate([[0.0], t, [max(duration, t[-1] if t.size else 0.0)]]) / 3600.0
    y = np.concatenate([[0], np.arange(1, t.size + 1), [t.size]]).astype(np.float64)
    return x, y


def plot_cumulative_reward(path: str | os.PathLike[str], curves: Sequence[RewardCurve],
                           predicted: Sequence[tuple[str, float]] = (), *,
                           hours: float | None = None, title: str | None = None) -> None:
    """Save the figure: each curve as steps, each ``(label, rate per hour)`` of
    ``predicted`` as a straight dashed line from the origin."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.8), dpi=110)
    try:
        colors = ["tab:blue", "tab:gray", "tab:orange", "tab:green"]
        x_end = hours or 0.0
        for i, c in enumerate(curves):
            x, y = cumulative_steps(c.times, c.duration)
            ax.step(x, y, where="post", color=colors[i % len(colors)], lw=1.8, label=c.label)
            x_end = max(x_end, float(x[-1]))
        styles = ["--", ":"]
        for i, (label, rate) in enumerate(predicted):
            if rate is None or not np.isfinite(rate):
                continue
            ax.plot([0, x_end], [0, rate * x_end], styles[i % 2], color="tab:red", lw=1.4,
                    label=label)
        ax.set_xlabel("simulated robot time (h)")
        ax.set_ylabel("cumulative reward (goals reached)")
        ax.set_xlim(0, x_end if x_end > 0 else None)
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", fontsize=8.5)
        if title:
            ax.set_title(title, fontsize=10)
        fig.tight_layout()
        with atomic_write(path, "wb") as fh:
            fig.savefig(fh, format="png")
    finally:
        plt.close(fig)
