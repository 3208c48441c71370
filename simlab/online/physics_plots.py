"""The figures of ``simlab online --arena``: ``physics.png`` and ``visits.png``.

* ``physics.png``: per arm, the share of blocked primitives and the simulated seconds per
  decision, averaged per window of decisions; a window is drawn at the middle of the
  decisions it holds, so the last, partial window stays inside the run (x from 0 to the
  run's last decision), and the change is a dashed line.
* ``visits.png``: per arm, where the robot was after each decision (hexagonal bins of
  every run's positions, on the arena's walls), with a colour bar of positions per bin
  (log scale), axes in metres and a legend of the markers: start states, goal states, the
  new goal of a goal change and the boxes added by a change.

The functions return matplotlib Figures (Agg, no pyplot state) so that tests can read
their axes; :func:`physics_figures` renders both as PNG bytes.
"""

from __future__ import annotations

import io
from typing import Any

import numpy as np

from simlab.online.report import window_centres, windows

__all__ = ["physics_figure", "physics_figures", "visits_figure"]

#: Logs of one arm: one dict of columns per run (``blocked``, ``duration``, ``x``, ``y``...).
Logs = dict[str, list[dict[str, np.ndarray]]]


def physics_figure(logs: Logs, task: Any, window: int) -> Any:
    """Blocked primitives (share) and simulated seconds per decision, per window of
    ``window`` decisions, per arm; x from 0 to the runs' length (decisions)."""
    from matplotlib.figure import Figure

    at = task.changes[0].at if task.changes else None
    fig = Figure(figsize=(6.4, 6.0), layout="constrained")
    axes = fig.subplots(2, 1, sharex=True)
    n = 0
    for name, runs in logs.items():
        for ax, col in zip(axes, ("blocked", "duration"), strict=True):
            x = np.stack([r[col] for r in runs]).astype(float)
            n = max(n, x.shape[1])
            ax.plot(window_centres(x.shape[1], window), windows(x, window).mean(0), marker="o",
                    ms=3, label=name)
    for ax, label in zip(axes, ("blocked primitives (share of decisions)",
                                "simulated time per decision (s)"), strict=True):
        if at is not None:
            ax.axvline(at, color="k", ls="--", lw=1, label="change")
        ax.set_ylabel(label)
    axes[0].legend(fontsize=7)
    axes[1].set_xlabel(f"decision (count; means over windows of {window})")
    axes[1].set_xlim(0, n)
    return fig


def visits_figure(logs: Logs, lab: Any, task: Any) -> Any:
    """One panel per arm: the robot's positions after its decisions (m), binned."""
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch, Rectangle
    from matplotlib.transforms import Affine2D

    from simlab.physics.render import draw_arena_on

    x0, y0, x1, y1 = lab.arena.bounds
    n = len(logs)
    aspect = (y1 - y0) / max(x1 - x0, 1e-9)
    if aspect > 1:  # a tall lab: panels side by side
        fig = Figure(figsize=(3.4 + 3.0 * n / aspect ** 0.5, 3.0 * aspect ** 0.5 + 1.2),
                     layout="constrained")
        axes = np.atleast_1d(fig.subplots(1, n))
    else:
        fig = Figure(figsize=(8.0, (7.0 * aspect + 0.8) * n + 0.8), layout="constrained")
        axes = np.atleast_1d(fig.subplots(n, 1))
    centres = np.asarray(lab.discretizer.centres, dtype=float)
    boxes = next((r["boxes"] for runs in logs.values() for r in runs[:1]), np.zeros((0, 5)))
    new_goals = [c for c in task.changes if c.kind == "goal"]
    bins = None
    for ax, (name, runs) in zip(axes, logs.items(), strict=True):
        draw_arena_on(ax, lab.arena)
        xs = np.concatenate([r["x"] for r in runs])
        ys = np.concatenate([r["y"] for r in runs])
        bins = ax.hexbin(xs, ys, gridsize=int(max(8, (x1 - x0) / 0.15)), mincnt=1,
                         cmap="viridis", bins="log", alpha=0.85, extent=(x0, x1, y0, y1))
        ax.plot(*centres[list(task.start_states)].T, "o", ms=6, mfc="none", mec="tab:blue")
        ax.plot(*centres[list(task.goal)].T, "*", ms=11, color="tab:red")
        for c in new_goals:
            ax.plot(*centres[list(c.goal)].T, "*", ms=11, color="tab:orange")
        for bx, by, sx, sy, yaw in boxes:
            rect = Rectangle((bx - sx / 2, by - sy / 2), sx, sy, color="tab:red", alpha=0.8)
            rect.set_transform(Affine2D().rotate_around(bx, by, yaw) + ax.transData)
            ax.add_patch(rect)
        ax.set_title(f"{name}: positions after each decision", fontsize=9)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_aspect("equal")
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
    if bins is not None:
        fig.colorbar(bins, ax=axes.tolist(), shrink=0.8,
                     label="positions per bin (all runs, log scale)")
    handles = [Line2D([], [], ls="none", marker="o", ms=6, mfc="none", mec="tab:blue",
                      label="start states"),
               Line2D([], [], ls="none", marker="*", ms=11, color="tab:red", label="goal states")]
    if new_goals:
        handles.append(Line2D([], [], ls="none", marker="*", ms=11, color="tab:orange",
                              label="goal after the change"))
    if len(boxes):
        handles.append(Patch(color="tab:red", alpha=0.8, label="box added by the change"))
    axes[0].legend(handles=handles, fontsize=7, loc="upper right", framealpha=0.8)
    return fig


def _png(fig: Any) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    return buf.getvalue()


def physics_figures(logs: Logs, lab: Any, task: Any, window: int) -> dict[str, bytes]:
    """``physics.png`` (:func:`physics_figure`) and ``visits.png`` (:func:`visits_figure`)
    as PNG bytes."""
    import matplotlib

    matplotlib.use("Agg")
    return {"physics.png": _png(physics_figure(logs, task, window)),
            "visits.png": _png(visits_figure(logs, lab, task))}
