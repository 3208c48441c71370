"""Plots of the empirical MDP (matplotlib, Agg backend, saved atomically)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from simlab.base.io import atomic_write

SLOW_COLOUR = "#4477aa"
FAST_COLOUR = "#ee6677"


def _direction_names() -> list[str]:
    """Short labels of the 8 directions in action order (UP, DOWN, LEFT, RIGHT, ...)."""
    return ["U", "D", "L", "R", "UL", "UR", "DL", "DR"]


def plot_entropy_per_action(
    mean_entropy: ArrayLike,
    path: str | os.PathLike[str],
    *,
    slow_mean: float | None = None,
    fast_mean: float | None = None,
    title: str | None = None,
) -> Path:
    """Bar plot of the mean Shannon entropy (bits) of T(s, a, .) per action (Fig. 4.8).

    ``mean_entropy`` is ``(A,)``; with 16 actions the slow ones (0-7) and the fast ones
    (8-15) get two colours and a dashed line at their means (``slow_mean``,
    ``fast_mean``; NaN-ignoring means of the bars if not given). NaN bars (an action
    never tried) are left empty. The PNG is written atomically to ``path``.
    """
    # A bare Figure (no pyplot) renders with Agg and touches no global backend state.
    from matplotlib.figure import Figure

    h = np.asarray(mean_entropy, dtype=np.float64)
    n = len(h)
    fig = Figure(figsize=(9, 4.2), layout="constrained")
    ax = fig.add_subplot()
    x = np.arange(n)
    heights = np.nan_to_num(h, nan=0.0)
    if n == 16:
        colours = [SLOW_COLOUR] * 8 + [FAST_COLOUR] * 8
        ax.bar(x[:8], heights[:8], color=colours[:8], label="slow (0-7)")
        ax.bar(x[8:], heights[8:], color=colours[8:], label="fast (8-15)")
        with np.errstate(all="ignore"):
            slow = float(np.nanmean(h[:8])) if slow_mean is None else slow_mean
            fast = float(np.nanmean(h[8:])) if fast_mean is None else fast_mean
        if np.isfinite(slow):
            ax.hlines(slow, -0.5, 7.5, colors=SLOW_COLOUR, linestyles="--",
                      label=f"slow mean {slow:.2f} bits")
        if np.isfinite(fast):
            ax.hlines(fast, 7.5, 15.5, colors=FAST_COLOUR, linestyles="--",
                      label=f"fast mean {fast:.2f} bits")
        names = _direction_names()
        ax.set_xticks(x, [f"{i}\n{names[i % 8]}" for i in x], fontsize=8)
        top = float(np.nanmax(heights)) if heights.size else 1.0
        ax.set_ylim(0.0, 1.3 * top if top > 0 else 1.0)
        ax.legend(loc="upper center", ncols=4, fontsize=8)
    else:
        ax.bar(x, heights, color=SLOW_COLOUR)
        ax.set_xticks(x)
    ax.set_xlim(-0.6, n - 0.4)
    ax.set_xlabel("action")
    ax.set_ylabel("mean entropy of T(s, a, ·) [bits]")
    ax.set_title(title or "Mean Shannon entropy of next-state distributions per action")
    ax.grid(axis="y", alpha=0.3)
    path = Path(path)
    with atomic_write(path, "wb") as fh:
        fig.savefig(fh, format="png", dpi=120)
    return path
