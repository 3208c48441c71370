"""Learning curves in the thesis's Fig. 4.1 style.

The thesis reduces a run of E episodes to 100 points: point k is the mean reward
of the k-th block of ``E / 100`` consecutive episodes (20 episodes for 2000),
and the shaded band is the standard deviation inside that block. With several
runs, a block pools the ``runs x block`` rewards, so the band shows both the
within-run and the between-run spread.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence

import numpy as np

from simlab.base.errors import ConfigError

__all__ = ["curve_points", "plot_learning_curves", "render_learning_curves", "save_learning_curves"]


def curve_points(
    rewards: np.ndarray, n_points: int = 100
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Block means and standard deviations of ``rewards`` (runs, episodes) or (episodes,).

    The episodes are cut into ``min(n_points, episodes)`` consecutive blocks of
    equal size (the last ``episodes % n_points`` episodes are dropped so every
    point averages the same number of rewards). Returns ``(x, mean, std)``, each
    (n,): ``x`` is the block's last episode number (1-based), ``mean``/``std`` the
    mean and population standard deviation of the pooled rewards of the block.
    """
    r = np.asarray(rewards, dtype=np.float64)
    if r.ndim == 1:
        r = r[None, :]
    if r.ndim != 2 or r.shape[1] == 0:
        raise ConfigError(f"expected (runs, episodes) rewards, got shape {r.shape}", key="rewards")
    if n_points < 1:
        raise ConfigError(f"expected n_points >= 1, got {n_points}", key="n_points")
    episodes = r.shape[1]
    n = min(n_points, episodes)
    block = episodes // n
    blocks = r[:, : n * block].reshape(r.shape[0], n, block)
    pooled = blocks.transpose(1, 0, 2).reshape(n, -1)
    x = (np.arange(1, n + 1) * block).astype(np.float64)
    return x, pooled.mean(axis=1), pooled.std(axis=1)


def plot_learning_curves(
    ax,
    curves: Mapping[str, np.ndarray],
    *,
    n_points: int = 100,
    reference: float | None = None,
    reference_label: str = "optimal (VI)",
    title: str | None = None,
) -> None:
    """Draw one mean line + std band per entry of ``curves`` (label -> rewards) on ``ax``.

    ``reference`` draws a dashed horizontal line (e.g. the optimal expected return).
    """
    for label, rewards in curves.items():
        x, mean, std = curve_points(rewards, n_points)
        (line,) = ax.plot(x, mean, label=label, lw=1.5)
        ax.fill_between(x, mean - std, mean + std, color=line.get_color(), alpha=0.25, lw=0)
    if reference is not None:
        ax.axhline(reference, color="0.3", ls="--", lw=1, label=reference_label)
    ax.set_xlabel("trial (episode)")
    ax.set_ylabel("reward per trial")
    if title:
        ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)


def render_learning_curves(
    panels: Sequence[tuple[str, Mapping[str, np.ndarray], float | None]],
    *,
    n_points: int = 100,
    suptitle: str | None = None,
) -> bytes:
    """The PNG bytes of :func:`save_learning_curves`'s figure (a worker process can draw
    it while this process does other work)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from simlab.training.heatmap import figure_png

    n = len(panels)
    cols = min(3, n)
    rows = -(-n // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.2 * rows), squeeze=False,
                             sharey=True)  # fmt: skip
    for ax, (title, curves, reference) in zip(axes.flat, panels, strict=False):
        plot_learning_curves(ax, curves, n_points=n_points, reference=reference, title=title)
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=7, loc="lower right")
    if suptitle:
        fig.suptitle(suptitle, fontsize=10)
    fig.tight_layout()
    return figure_png(fig)


def save_learning_curves(
    path: str | os.PathLike[str],
    panels: Sequence[tuple[str, Mapping[str, np.ndarray], float | None]],
    *,
    n_points: int = 100,
    suptitle: str | None = None,
) -> None:
    """Save a PNG with one panel per ``(title, curves, reference)`` (grid up to 3 columns).

    Written atomically (temporary file then rename); the caller checks overwrite.
    """
    from simlab.base.io import atomic_write_bytes

    atomic_write_bytes(path, render_learning_curves(panels, n_points=n_points,
                                                    suptitle=suptitle))
