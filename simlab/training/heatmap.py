"""Q-value heat maps over the arena's Voronoi cells (thesis Fig. 4.3 / 4.11).

Each cell (the points nearest to a centre, rasterised on a pixel grid with a
``scipy.spatial.cKDTree``) is coloured by ``max_a Q(s, a)``; an arrow from the
centre shows ``argmax_a Q(s, a)``: direction ``a % 8`` in the order UP, DOWN,
LEFT, RIGHT, UP_LEFT, UP_RIGHT, DOWN_LEFT, DOWN_RIGHT (UP = +y, map frame), length
growing with the speed ``a // 8`` (slow, fast). Goal cells are outlined. States
whose Q row is constant (nothing learned) get no arrow. An occupancy map (for
example a ``discretize`` :class:`OccupancyMap` or any object with ``occupancy``
(H, W), ``resolution`` m/px and ``origin`` (x, y, yaw)) can be drawn underneath.

Coordinates are metres; ``bounds`` is ``(x_min, y_min, x_max, y_max)`` as in
:attr:`simlab.physics.arena.ArenaConfig.bounds`.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from simlab.base.actions import SIMLAB16, ActionSet
from simlab.base.errors import ConfigError
from simlab.base.io import atomic_write_bytes

__all__ = [
    "ARROW_DIRECTIONS",
    "HeatmapScene",
    "HeatmapStyle",
    "arrow_vectors",
    "bounds_from_centres",
    "figure_png",
    "masked_q",
    "plot_q_heatmap",
    "rasterize_cells",
    "render_q_heatmap",
    "save_heatmap_grid",
    "save_q_heatmap",
]

_D = np.sqrt(0.5)
#: (8, 2) unit vectors (x, y) of the direction part ``a % 8`` of an action; UP is +y.
ARROW_DIRECTIONS = np.array(
    [[0, 1], [0, -1], [-1, 0], [1, 0], [-_D, _D], [_D, _D], [-_D, -_D], [_D, -_D]], dtype=float
)


def bounds_from_centres(centres: np.ndarray) -> tuple[float, float, float, float]:
    """Bounds enclosing the centres plus half the median nearest-neighbour spacing.

    A fallback when the arena is unknown: cells then reach about as far past the
    outer centres as they do between centres.
    """
    c = np.asarray(centres, dtype=float)
    if len(c) > 1:
        d, _ = cKDTree(c).query(c, k=2)
        pad = 0.5 * float(np.median(d[:, 1]))
    else:
        pad = 0.5
    return (c[:, 0].min() - pad, c[:, 1].min() - pad, c[:, 0].max() + pad, c[:, 1].max() + pad)


def rasterize_cells(
    centres: np.ndarray, bounds: Sequence[float], resolution: float | None = None
) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    """Label every pixel of ``bounds`` with the index of its nearest centre.

    Returns ``(labels (H, W) int64, extent)``; row 0 is the top (largest y), as
    ``imshow(origin="upper", extent=extent)`` expects; ``extent`` is
    ``(x_min, x_max, y_min, y_max)``. ``resolution`` m/px (default: 400 px across).
    """
    x0, y0, x1, y1 = (float(b) for b in bounds)
    if resolution is None:
        resolution = max(x1 - x0, y1 - y0) / 400
    W = max(1, round((x1 - x0) / resolution))
    H = max(1, round((y1 - y0) / resolution))
    xs = x0 + (np.arange(W) + 0.5) * (x1 - x0) / W
    ys = y1 - (np.arange(H) + 0.5) * (y1 - y0) / H
    gx, gy = np.meshgrid(xs, ys)
    _, labels = cKDTree(np.asarray(centres, dtype=float)).query(
        np.column_stack([gx.ravel(), gy.ravel()])
    )
    return labels.reshape(H, W).astype(np.int64), (x0, x1, y0, y1)


@functools.lru_cache(maxsize=4)
def _cells(centres: bytes, n: int, bounds: tuple[float, ...], resolution: float | None
           ) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    """:func:`rasterize_cells` remembered (read-only labels): the 9 heat maps and 9 grid
    panels of ``simlab train`` share one raster, ~70 ms of nearest-centre queries each."""
    labels, extent = rasterize_cells(np.frombuffer(centres).reshape(n, 2), bounds, resolution)
    labels.flags.writeable = False
    return labels, extent


def masked_q(Q: np.ndarray, valid: np.ndarray | None) -> np.ndarray:
    """``Q`` (S, A) with invalid actions at ``-inf`` (rows with no valid action unchanged)."""
    Q = np.asarray(Q, dtype=float)
    if valid is None:
        return Q
    v = np.asarray(valid, dtype=bool)
    if v.shape != Q.shape:
        raise ConfigError(f"expected {Q.shape} bool, got {v.shape}", key="valid")
    v = v | ~v.any(axis=1, keepdims=True)
    return np.where(v, Q, -np.inf)


def arrow_vectors(Q: np.ndarray, action_set: ActionSet) -> tuple[np.ndarray, np.ndarray]:
    """``(argmax (S,), arrows (S, 2))``: the greedy action of each state and its arrow.

    The arrow is the unit vector of the action's map-frame direction times its relative
    length ``0.15 + 0.3 * (1 + speed) / n_speeds`` (speed 0 slow, 1 fast; one speed for an
    8-action set), in units of the cell spacing.
    """
    best = np.asarray(Q).argmax(axis=1)
    n_speeds = 2 if action_set.n_actions == 16 else 1
    dirs = np.array([int(action_set.direction(a)) for a in best], dtype=np.int64)
    speed = np.array([action_set.speed_index(a) for a in best]) if n_speeds == 2 else 0
    length = 0.15 + 0.3 * (1 + speed) / n_speeds
    return best, ARROW_DIRECTIONS[dirs] * np.reshape(length, (-1, 1))


def _check_inputs(centres: np.ndarray, Q: np.ndarray, goal_mask: np.ndarray | None) -> None:
    if centres.ndim != 2 or centres.shape[1] != 2:
        raise ConfigError(f"expected (S, 2) metres, got shape {centres.shape}", key="centres")
    if Q.ndim != 2 or Q.shape[0] != centres.shape[0]:
        raise ConfigError(
            f"expected (S, A) with S = {centres.shape[0]} (the centres), got {Q.shape}", key="Q"
        )
    if goal_mask is not None and np.shape(goal_mask) != (centres.shape[0],):
        raise ConfigError(f"expected ({centres.shape[0]},) bool, got {np.shape(goal_mask)}",
                          key="goal_mask")  # fmt: skip


def _draw_background(ax, background: Any) -> None:
    occ = np.asarray(background.occupancy, dtype=float)
    res = float(background.resolution)
    ox, oy = float(background.origin[0]), float(background.origin[1])
    H, W = occ.shape
    shade = np.where(occ < 0, 0.75, 1.0 - np.clip(occ, 0, 100) / 100.0)  # unknown grey
    ax.imshow(shade, cmap="gray", vmin=0, vmax=1, origin="upper",
              extent=(ox, ox + W * res, oy, oy + H * res), zorder=0)  # fmt: skip


@dataclass(frozen=True, eq=False)
class HeatmapScene:
    """What every heat map of one arena shares (one goal's panel adds its Q and goal cells).

    Attributes:
        centres: (S, 2) state centres, metres.
        bounds: ``(x_min, y_min, x_max, y_max)`` metres drawn (None:
            :func:`bounds_from_centres`).
        background: an occupancy map drawn underneath (``occupancy`` (H, W), ``resolution``
            m/px, ``origin`` (x, y, yaw)), or None.
        action_set: how to read an action as an arrow; None: simlab's 16 primitives for a
            16-action Q, no arrows otherwise.
        valid: (S, A) bool, the actions a state may take (untried ones are neither
            coloured nor drawn as arrows); None: every action.
        resolution: raster cell size, m/px (None: 400 px across the bounds).
    """

    centres: np.ndarray
    bounds: Sequence[float] | None = None
    background: Any = None
    action_set: ActionSet | None = None
    valid: np.ndarray | None = None
    resolution: float | None = None


@dataclass(frozen=True)
class HeatmapStyle:
    """How a heat map looks: the colour map and its range (None: the data's), the argmax
    arrows and the panel's own colour bar (off when panels share one)."""

    cmap: str = "Blues"
    vmin: float | None = None
    vmax: float | None = None
    arrows: bool = True
    colorbar: bool = True


def plot_q_heatmap(ax, scene: HeatmapScene, Q: np.ndarray, goal_mask: np.ndarray | None = None,
                   *, title: str | None = None, style: HeatmapStyle = HeatmapStyle()):
    """Draw the heat map of ``Q`` (S, A) over the cells of ``scene.centres`` on ``ax``,
    the cells of ``goal_mask`` (S,) bool outlined.

    Returns the ``AxesImage`` of the cells (for a shared colour bar).
    """
    centres = np.asarray(scene.centres, dtype=float)
    Q = np.asarray(Q, dtype=float)
    _check_inputs(centres, Q, goal_mask)
    action_set = _action_set(scene.action_set, Q)
    Qv = masked_q(Q, scene.valid)
    bounds = bounds_from_centres(centres) if scene.bounds is None else scene.bounds
    labels, extent = _cells(centres.tobytes(), len(centres), tuple(float(b) for b in bounds),
                            scene.resolution)
    if scene.background is not None:
        _draw_background(ax, scene.background)
    img = ax.imshow(Qv.max(axis=1)[labels], cmap=style.cmap, origin="upper", extent=extent,
                    vmin=style.vmin, vmax=style.vmax,
                    alpha=0.85 if scene.background is not None else 1.0, zorder=1,
                    interpolation="nearest")  # fmt: skip
    _draw_cell_borders(ax, labels, extent)
    if goal_mask is not None and np.any(goal_mask):
        _draw_goal_outline(ax, labels, extent, goal_mask)
    if style.arrows and action_set is not None:
        _draw_arrows(ax, centres, Qv, action_set, extent)
    ax.plot(centres[:, 0], centres[:, 1], ".", color="0.2", ms=2, zorder=5)
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    if title:
        ax.set_title(title, fontsize=9)
    if style.colorbar:
        ax.figure.colorbar(img, ax=ax, fraction=0.046, pad=0.04, label="max_a Q(s, a)")
    return img


def _action_set(action_set: ActionSet | None, Q: np.ndarray) -> ActionSet | None:
    """The action set the arrows read: the given one (refused when its size is not Q's),
    simlab's 16 primitives for a 16-action Q, else None (no arrows)."""
    if action_set is None and Q.shape[1] == SIMLAB16.n_actions:
        action_set = SIMLAB16
    if action_set is not None and action_set.n_actions != Q.shape[1]:
        raise ConfigError(f"Q has {Q.shape[1]} actions but the action set "
                          f"{action_set.describe()}", key="action_set")
    return action_set


def _draw_cell_borders(ax, labels: np.ndarray, extent: tuple[float, ...]) -> None:
    """Cell borders: the pixels whose right or lower neighbour has another label."""
    edge = np.zeros(labels.shape, dtype=bool)
    edge[:, 1:] |= labels[:, 1:] != labels[:, :-1]
    edge[1:, :] |= labels[1:, :] != labels[:-1, :]
    ax.imshow(np.ma.masked_where(~edge, edge), cmap="Greys", vmin=0, vmax=1, origin="upper",
              extent=extent, alpha=0.35, zorder=2, interpolation="nearest")  # fmt: skip


def _draw_goal_outline(ax, labels: np.ndarray, extent: tuple[float, ...],
                       goal_mask: np.ndarray) -> None:
    """The outline of the goal cells (``goal_mask`` (S,) bool), crimson."""
    inside = np.asarray(goal_mask, dtype=bool)[labels].astype(float)
    xs = np.linspace(extent[0], extent[1], labels.shape[1])
    ys = np.linspace(extent[3], extent[2], labels.shape[0])
    ax.contour(xs, ys, inside, levels=[0.5], colors="crimson", linewidths=2, zorder=4)


def _draw_arrows(ax, centres: np.ndarray, Qv: np.ndarray, action_set: ActionSet,
                 extent: tuple[float, ...]) -> None:
    """The argmax arrow of every state whose (masked) row ``Qv`` is not constant, its
    length in units of the mean cell spacing (:func:`arrow_vectors`)."""
    _, d = arrow_vectors(Qv, action_set)
    learned = Qv.max(axis=1) > np.where(np.isfinite(Qv), Qv, np.inf).min(axis=1)
    spacing = np.sqrt((extent[1] - extent[0]) * (extent[3] - extent[2]) / max(len(centres), 1))
    d = d * spacing
    ax.quiver(centres[learned, 0], centres[learned, 1], d[learned, 0], d[learned, 1],
              angles="xy", scale_units="xy", scale=1, color="darkorange", width=0.006,
              zorder=5, pivot="tail")  # fmt: skip


def figure_png(fig) -> bytes:
    """The PNG bytes (110 dpi) of ``fig``, then closed: rendering is separate from writing
    so a worker process can draw a figure that this process writes
    (:func:`simlab.training.train`)."""
    import io

    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()


def render_q_heatmap(scene: HeatmapScene, Q: np.ndarray, goal_mask: np.ndarray | None = None,
                     *, title: str | None = None, style: HeatmapStyle = HeatmapStyle()
                     ) -> bytes:
    """The PNG bytes of one heat map (:func:`plot_q_heatmap`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.2, 4.6))
    plot_q_heatmap(ax, scene, Q, goal_mask, title=title, style=style)
    fig.tight_layout()
    return figure_png(fig)


def save_q_heatmap(path: str | os.PathLike[str], scene: HeatmapScene, Q: np.ndarray,
                   goal_mask: np.ndarray | None = None, *, title: str | None = None) -> None:
    """Save one heat map as a PNG (atomic write; the caller checks overwrite)."""
    atomic_write_bytes(path, render_q_heatmap(scene, Q, goal_mask, title=title))


def save_heatmap_grid(
    path: str | os.PathLike[str],
    scene: HeatmapScene,
    Qs: Sequence[np.ndarray],
    goal_masks: Sequence[np.ndarray],
    names: Sequence[str],
    *,
    suptitle: str | None = None,
) -> None:
    """Save one figure with a heat map per goal (3 columns; a 3 x 3 grid for 9 goals).

    All panels share one colour scale so goals can be compared.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(Qs)
    if not (n == len(goal_masks) == len(names)) or n == 0:
        raise ConfigError("need one Q, goal mask and name per goal", key="Qs")
    vmin = min(float(np.max(masked_q(Q, scene.valid), axis=1).min()) for Q in Qs)
    vmax = max(float(np.max(masked_q(Q, scene.valid), axis=1).max()) for Q in Qs)
    style = HeatmapStyle(vmin=vmin, vmax=vmax, colorbar=False)
    cols = min(3, n)
    rows = -(-n // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.6 * cols, 3.4 * rows), squeeze=False)
    img = None
    for ax, Q, mask, name in zip(axes.flat, Qs, goal_masks, names, strict=False):
        img = plot_q_heatmap(ax, scene, Q, mask, title=name, style=style)
        ax.set_xlabel("")
        ax.set_ylabel("")
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    fig.subplots_adjust(left=0.06, right=0.87, bottom=0.05, top=0.92, wspace=0.3, hspace=0.3)
    cax = fig.add_axes((0.9, 0.2, 0.015, 0.6))
    fig.colorbar(img, cax=cax, label="max_a Q(s, a)")
    if suptitle:
        fig.suptitle(suptitle, fontsize=10)
    atomic_write_bytes(path, figure_png(fig))
