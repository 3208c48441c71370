"""Figures of the Visit-the-lab results (thesis Figs. 4.1-4.7, IMOL poster Figs. 4-5).

Every function draws with matplotlib's object API (no global pyplot state, headless)
and writes a PNG atomically (:func:`simlab.base.io.atomic_write`). Curves use the thesis's
smoothing (:func:`~simlab.visitlab.curves.smooth_curve`: 100 windows of
``n_trials / 100`` trials, mean over seeds and window, band of one standard deviation
within the window).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from simlab.base.io import atomic_write
from simlab.visitlab.actions import ACTION_DIR, DIR_DELTA
from simlab.visitlab.curves import smooth_curve
from simlab.visitlab.grid import Layout

#: One curve: (legend label, values per trial (n_seeds, n_trials)).
Curve = tuple[str, np.ndarray]


def _save(fig, path: str | os.PathLike[str], dpi: int = 110) -> Path:
    path = Path(path)
    with atomic_write(path, "wb") as fh:
        fig.savefig(fh, format="png", dpi=dpi)
    return path


def _figure(width: float, height: float):
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), layout="constrained")


def plot_curve_panels(panels: Sequence[tuple[str, Sequence[Curve]]], path: str | os.PathLike[str],
                      *, ylabel: str = "reward per trial", title: str = "",
                      marks: Sequence[Sequence[float]] = (), n_points: int = 100) -> Path:
    """One panel per ``(title, curves)``: smoothed mean and a band of one standard
    deviation per curve; ``marks[i]``: trials of panel ``i`` marked by a dotted line."""
    n = max(1, len(panels))
    fig = _figure(4.6 * n, 3.6)
    axes = fig.subplots(1, n, squeeze=False)[0]
    for i, (ax, (panel_title, curves)) in enumerate(zip(axes, panels, strict=False)):
        for label, values in curves:
            x, mean, std = smooth_curve(values, n_points)
            (line,) = ax.plot(x, mean, lw=1.6, label=label)
            ax.fill_between(x, mean - std, mean + std, color=line.get_color(), alpha=0.18, lw=0)
        for m in marks[i] if i < len(marks) else ():
            ax.axvline(m, color="0.4", ls=":", lw=1)
        ax.set_title(panel_title, fontsize=10)
        ax.set_xlabel("trials")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="best")
    if title:
        fig.suptitle(title, fontsize=11)
    return _save(fig, path)


def _value_map(layout: Layout, values: np.ndarray, goal: int) -> np.ndarray:
    n = layout.n_cells
    return values[goal * n:(goal + 1) * n].reshape(layout.height, layout.width)


def _draw_walls(ax, layout: Layout) -> None:
    for r, c in zip(*np.nonzero(layout.walls_h), strict=True):
        ax.plot([c - 0.5, c + 0.5], [r - 0.5, r - 0.5], color="k", lw=1.2)
    for r, c in zip(*np.nonzero(layout.walls_v), strict=True):
        ax.plot([c - 0.5, c - 0.5], [r - 0.5, r + 0.5], color="k", lw=1.2)


def _goal_outline(ax, layout: Layout, goal: int) -> None:
    mask = layout.labels == goal
    ax.contour(mask.astype(float), levels=[0.5], colors="#d62728", linewidths=1.2,
               extent=(-0.5, layout.width - 0.5, layout.height - 0.5, -0.5), origin="upper")


def plot_nav_heatmaps(layout: Layout, values: np.ndarray, path: str | os.PathLike[str], *,
                      goals: Sequence[int] | None = None, title: str = "",
                      arrows_q: np.ndarray | None = None) -> Path:
    """Thesis Fig. 4.3: a value per cell for each goal room (bluer = higher), the goal
    room outlined in red.

    ``values`` ``(n_labels * n_cells,)`` for the goal-conditioned navigation states
    (e.g. ``max_a Q`` averaged over seeds); ``arrows_q`` an optional Q table
    ``(n_labels * n_cells, 25)`` whose greedy direction is drawn as an arrow per cell
    (moves only, cells with some value, outside the goal room).
    """
    goals = list(layout.goal_labels if goals is None else goals)
    cols = min(3, len(goals))
    rows = -(-len(goals) // cols)
    fig = _figure(3.0 * cols + 0.6, 3.0 * rows + 0.4)
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    vmax = float(max(values.max(), 1e-9))
    im = None
    n = layout.n_cells
    for ax, g in zip(axes, goals, strict=False):
        im = ax.imshow(_value_map(layout, values, g), cmap="Blues", vmin=0.0, vmax=vmax,
                       interpolation="nearest")
        _draw_walls(ax, layout)
        _goal_outline(ax, layout, g)
        if arrows_q is not None:
            block = arrows_q[g * n:(g + 1) * n]
            best = block[:, :24].argmax(axis=1)
            d = DIR_DELTA[ACTION_DIR[best]]
            rows_i, cols_i = np.divmod(np.arange(n), layout.width)
            keep = (block.max(axis=1) > 0) & (layout.cell_labels != g)
            ax.quiver(cols_i[keep], rows_i[keep], d[keep, 1], -d[keep, 0], angles="xy",
                      scale=1.6, scale_units="xy", width=0.004, color="0.25", alpha=0.7)
        ax.set_title(layout.room_names[g], fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    for ax in axes[len(goals):]:
        ax.set_visible(False)
    if im is not None:
        fig.colorbar(im, ax=axes.tolist(), shrink=0.8, label="max_a Q(s, a)")
    if title:
        fig.suptitle(title, fontsize=11)
    return _save(fig, path)


def plot_q_maps(layout: Layout, tables: Sequence[tuple[str, np.ndarray]], goal: int,
                path: str | os.PathLike[str], *, title: str = "") -> Path:
    """Poster Fig. 5 (top): value maps of several agents for one goal room, on a common
    colour scale (dark blue = high, white = low). ``tables``: ``(label, values)`` with
    ``values`` ``(n_labels * n_cells,)``, e.g. ``max_a Q`` averaged over seeds."""
    fig = _figure(3.2 * len(tables) + 0.6, 3.4)
    axes = fig.subplots(1, len(tables), squeeze=False)[0]
    vmax = float(max(max(v.max() for _, v in tables), 1e-9))
    im = None
    for ax, (label, v) in zip(axes, tables, strict=True):
        im = ax.imshow(_value_map(layout, v, goal), cmap="Blues", vmin=0.0, vmax=vmax,
                       interpolation="nearest")
        _draw_walls(ax, layout)
        _goal_outline(ax, layout, goal)
        ax.set_title(label, fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    if im is not None:
        fig.colorbar(im, ax=axes.tolist(), shrink=0.85, label="max_a Q(s, a)")
    if title:
        fig.suptitle(title, fontsize=11)
    return _save(fig, path)


def plot_q_vs_vstar(series: Sequence[tuple[str, np.ndarray, np.ndarray]],
                    path: str | os.PathLike[str], *, title: str = "",
                    max_points: int = 4000) -> Path:
    """Poster Fig. 5 (bottom): learned ``max_a Q(s)`` against the optimal ``V*(s)``.

    ``series``: ``(label, v_star (k,), v_learned (k,))`` per agent (all states, goals and
    runs pooled). The points (at most ``max_points``, an even stride through them), and
    per distinct value of V* (the possible values of the deterministic task) the median
    and the 10-90 % range of the learned values; the diagonal is a perfect estimate.
    """
    fig = _figure(3.4 * len(series) + 0.4, 3.4)
    axes = fig.subplots(1, len(series), squeeze=False, sharey=True)[0]
    top = max(float(max(v.max(), w.max())) for _, v, w in series)
    for ax, (label, v_star, learned) in zip(axes, series, strict=True):
        key = np.round(v_star, 6)
        levels = np.unique(key)
        med = np.array([np.median(learned[key == x]) for x in levels])
        lo = np.array([np.quantile(learned[key == x], 0.1) for x in levels])
        hi = np.array([np.quantile(learned[key == x], 0.9) for x in levels])
        step = max(1, learned.size // max_points)
        ax.scatter(v_star[::step], learned[::step], s=3, alpha=0.15, color="0.35", lw=0)
        ax.fill_between(levels, lo, hi, alpha=0.25, lw=0, step="mid")
        ax.plot(levels, med, marker="o", ms=2.5, lw=1.2)
        ax.plot([0, top], [0, top], color="k", ls="--", lw=0.8)
        ax.set_title(label, fontsize=9)
        ax.set_xlabel("V*(s)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("learned max_a Q(s, a)")
    if title:
        fig.suptitle(title, fontsize=11)
    return _save(fig, path)


def plot_histograms(series: Sequence[tuple[str, np.ndarray]], path: str | os.PathLike[str], *,
                    xlabel: str, title: str = "") -> Path:
    """Side-by-side bar histograms of integer counts (e.g. goals per trial)."""
    fig = _figure(5.6, 3.6)
    ax = fig.subplots()
    top = int(max(max(int(v.max()) for _, v in series), 1))
    bins = np.arange(top + 2) - 0.5
    width = 0.8 / max(1, len(series))
    for i, (label, values) in enumerate(series):
        counts, _ = np.histogram(values, bins=bins)
        ax.bar(np.arange(top + 1) - 0.4 + (i + 0.5) * width, counts / max(1, values.size),
               width=width, label=f"{label} (mean {values.mean():.2f})")
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel(xlabel)
    ax.set_ylabel("fraction of trials")
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=8)
    if title:
        ax.set_title(title, fontsize=10)
    return _save(fig, path)
