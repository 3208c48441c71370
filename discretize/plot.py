"""Figure of a discretized map, after thesis Fig. 3.5.

The map (occupied black, free white, unknown grey; the axes cropped to the known part),
the Voronoi cells restricted to the free space (boundaries drawn where the nearest-centre label of neighbouring
pixels changes), the eroded free space's edge (dashed), the centres with their state
numbers, and, when visit counts are given, each cell coloured by ``log10(visits)``
(the thesis legend; unvisited cells hatched grey).
"""

from __future__ import annotations

import io
import os
from pathlib import Path

import numpy as np

from discretize.gridmap import UNKNOWN, OccupancyMap
from discretize.voronoi import DEFAULT_ROBOT_RADIUS, Discretizer, eroded_free_mask
from simlab.base.errors import ConfigError, DataError
from simlab.base.io import atomic_write, ensure_new


def visits_from_dataset(path: str | os.PathLike[str], n_states: int) -> np.ndarray:
    """Visits per state ``(n_states,)`` int64 from a directory of Parquet parts.

    Counts the int column ``s`` (the state a transition starts from) over every
    part, read with ``pyarrow.dataset``. Raises :class:`ConfigError` if the
    directory is missing, :class:`DataError` if the column is missing or a state
    is outside ``0..n_states-1`` (the dataset used another discretizer).
    """
    import pyarrow as pa
    import pyarrow.dataset as ds

    path = Path(path)
    if not path.exists():
        raise ConfigError("dataset not found", path=path, fix="give a directory of Parquet parts")
    try:
        dataset = ds.dataset(str(path), format="parquet")
        if "s" not in dataset.schema.names:
            raise DataError(f"{path}: the dataset has no column 's' (state)")
        column = dataset.to_table(columns=["s"]).column("s")
    except (pa.ArrowInvalid, OSError) as exc:
        raise DataError(f"{path}: cannot read the Parquet dataset ({exc})") from None
    s = np.asarray(column.to_numpy(zero_copy_only=False))
    if s.size == 0:
        return np.zeros(n_states, dtype=np.int64)
    if not np.issubdtype(s.dtype, np.integer):
        raise DataError(f"{path}: column 's' must hold integers, got {s.dtype}")
    if s.min() < 0 or s.max() >= n_states:
        raise DataError(
            f"{path}: states range {int(s.min())}..{int(s.max())} does not fit the "
            f"{n_states} states of this discretizer (another discretizer?)"
        )
    return np.bincount(s.astype(np.int64), minlength=n_states)


def _local_xy(grid: OccupancyMap, xy: np.ndarray) -> np.ndarray:
    """Map-frame coordinates (the image axes, metres from the origin corner) of world points."""
    rc = grid.world_to_pixel_float(xy)
    x = grid.origin[0] + rc[..., 1] * grid.resolution
    y = grid.origin[1] + (grid.height - rc[..., 0]) * grid.resolution
    return np.stack([x, y], axis=-1)


def known_bounds(grid: OccupancyMap, points: np.ndarray | None = None, margin_px: int = 5
                 ) -> tuple[float, float, float, float]:
    """``(x_min, x_max, y_min, y_max)`` (m, the figure's map-frame axes) of the known
    (not unknown) pixels, grown to hold ``points`` (already in figure coordinates) and
    ``margin_px`` pixels of margin; the whole image when nothing is known.

    A GMapping map is mostly unknown grey around the lab; figures crop to this box.
    """
    known = grid.occupancy != UNKNOWN
    h, w = grid.shape
    res = grid.resolution
    if known.any():
        rows = np.flatnonzero(known.any(axis=1))
        cols = np.flatnonzero(known.any(axis=0))
        r0, r1, c0, c1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    else:
        r0, r1, c0, c1 = 0, h, 0, w
    x0, y0 = grid.origin[0], grid.origin[1]
    box = [x0 + c0 * res, x0 + c1 * res, y0 + (h - r1) * res, y0 + (h - r0) * res]
    if points is not None and len(points):
        box = [min(box[0], float(points[:, 0].min())), max(box[1], float(points[:, 0].max())),
               min(box[2], float(points[:, 1].min())), max(box[3], float(points[:, 1].max()))]
    m = margin_px * res
    return (box[0] - m, box[1] + m, box[2] - m, box[3] + m)


def draw_states(
    ax,
    grid: OccupancyMap,
    disc: Discretizer,
    visits: np.ndarray | None = None,
    *,
    robot_radius: float | None = DEFAULT_ROBOT_RADIUS,
    numbers: bool = True,
    crop: bool = True,
):
    """Draw the figure into matplotlib axes ``ax``; returns the colour-mapped image (or None).

    Layers, bottom to top: the map (free white, occupied black, unknown grey), the cells
    (tinted by state, or by ``visits`` (S,) on a log scale) with their boundaries, the
    eroded free space's border (``robot_radius`` m; None: not drawn) and the numbered
    centres. ``crop`` limits the axes to the known part of the map (and the centres):
    :func:`known_bounds`.
    """
    extent = _extent(grid)
    ax.imshow(_map_image(grid), extent=extent, interpolation="nearest", origin="upper")
    overlay, mappable = _cells_overlay(grid, disc, visits)
    ax.imshow(overlay, extent=extent, interpolation="nearest", origin="upper")
    if robot_radius is not None:
        _draw_eroded_border(ax, grid, robot_radius)
    pts = _local_xy(grid, disc.centres)
    _draw_centres(ax, pts, numbers)
    _legend(ax, robot_radius)
    if crop:
        x_min, x_max, y_min, y_max = known_bounds(grid, pts)
        ax.set_xlim(x_min, x_max)
        ax.set_ylim(y_min, y_max)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal")
    return mappable


def _extent(grid: OccupancyMap) -> tuple[float, float, float, float]:
    """``(left, right, bottom, top)`` of the map image in metres (matplotlib's extent)."""
    h, w = grid.shape
    return (
        grid.origin[0],
        grid.origin[0] + w * grid.resolution,
        grid.origin[1],
        grid.origin[1] + h * grid.resolution,
    )


def _map_image(grid: OccupancyMap) -> np.ndarray:
    """``(H, W, 3)`` RGB in [0, 1]: free 1.0, occupied 0.0, unknown 0.78."""
    base = np.full((*grid.shape, 3), 0.78)
    base[grid.free_mask()] = 1.0
    base[grid.occupied_mask()] = 0.0
    return base


def _cell_colours(disc: Discretizer, visits: np.ndarray | None):
    """``(S, 4)`` RGBA per state and the colour scale (None without visits): visits on a
    log10 viridis scale (unvisited light grey), else a repeating 20-colour palette."""
    import matplotlib as mpl
    from matplotlib.colors import Normalize

    if visits is None:
        palette = mpl.colormaps["tab20"](np.arange(20) % 20)
        colours = palette[np.arange(disc.n_states) % 20].copy()
        colours[:, 3] = 0.35
        return colours, None
    visits = np.asarray(visits)
    if visits.shape != (disc.n_states,):
        raise ValueError(f"visits: expected shape ({disc.n_states},), got {visits.shape}")
    logv = np.log10(np.maximum(visits, 1).astype(np.float64))
    vmax = max(1.0, float(logv.max()))
    cmap = mpl.colormaps["viridis"]
    norm = Normalize(vmin=0.0, vmax=vmax)
    colours = cmap(norm(logv))
    colours[visits == 0] = (0.85, 0.85, 0.85, 1.0)
    colours[:, 3] = 0.75
    return colours, mpl.cm.ScalarMappable(norm=norm, cmap=cmap)


def _cells_overlay(grid: OccupancyMap, disc: Discretizer, visits: np.ndarray | None):
    """``(H, W, 4)`` RGBA of the free pixels in their state's colour, cell boundaries dark,
    and the colour scale of :func:`_cell_colours`."""
    free = grid.free_mask()
    labels = disc.label_image(grid)
    colours, mappable = _cell_colours(disc, visits)
    overlay = np.zeros((*grid.shape, 4))
    overlay[free] = colours[labels[free]]
    # Cell boundaries: a pixel whose right or lower neighbour has another label.
    edge = np.zeros(grid.shape, dtype=bool)
    edge[:, 1:] |= (labels[:, 1:] != labels[:, :-1]) & free[:, 1:] & free[:, :-1]
    edge[1:, :] |= (labels[1:, :] != labels[:-1, :]) & free[1:, :] & free[:-1, :]
    overlay[edge] = (0.1, 0.1, 0.1, 0.9)
    return overlay, mappable


def _draw_eroded_border(ax, grid: OccupancyMap, robot_radius: float) -> None:
    """The border of the free space eroded by ``robot_radius`` (m), dashed red (nothing
    when the eroded space is empty or everything)."""
    h, w = grid.shape
    eroded = eroded_free_mask(grid, robot_radius).astype(float)
    ys = grid.origin[1] + (h - np.arange(h) - 0.5) * grid.resolution
    xs = grid.origin[0] + (np.arange(w) + 0.5) * grid.resolution
    if 0 < eroded.sum() < eroded.size:
        ax.contour(xs, ys, eroded, levels=[0.5], colors="tab:red", linewidths=0.8,
                   linestyles="--")


def _legend(ax, robot_radius: float | None) -> None:
    """What the red dots and the dashed red line are."""
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], ls="none", marker="o", color="tab:red", markersize=3,
                      label="state centres (numbered)")]
    if robot_radius is not None:
        handles.append(Line2D([], [], color="tab:red", lw=0.8, ls="--",
                              label=f"free space eroded by the robot radius ({robot_radius:.3f} m)"))
    ax.legend(handles=handles, fontsize=7, loc="upper right", framealpha=0.8)


def _draw_centres(ax, pts: np.ndarray, numbers: bool) -> None:
    """The centres ``pts`` (S, 2) in the axes' frame as red dots, numbered if asked."""
    ax.plot(pts[:, 0], pts[:, 1], "o", color="tab:red", markersize=3)
    if numbers:
        for k, (x, y) in enumerate(pts):
            ax.annotate(str(k), (x, y), xytext=(2, 2), textcoords="offset points",
                        fontsize=7, color="black", fontweight="bold")


def render_states_png(
    grid: OccupancyMap,
    disc: Discretizer,
    visits: np.ndarray | None = None,
    *,
    robot_radius: float | None = DEFAULT_ROBOT_RADIUS,
    title: str | None = None,
    dpi: int = 150,
) -> bytes:
    """The figure as PNG bytes (Agg backend, nothing written to disk)."""
    fig = states_figure(grid, disc, visits, robot_radius=robot_radius, title=title)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def states_figure(
    grid: OccupancyMap,
    disc: Discretizer,
    visits: np.ndarray | None = None,
    *,
    robot_radius: float | None = DEFAULT_ROBOT_RADIUS,
    title: str | None = None,
):
    """The figure (a matplotlib Figure, no pyplot state): :func:`draw_states` with a title
    and, when ``visits`` are given, a colour bar of visits per state."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.4, 6.4 if visits is None else 7.2))
    ax = fig.add_subplot(1, 1, 1)
    mappable = draw_states(ax, grid, disc, visits, robot_radius=robot_radius)
    if title is None:
        title = f"{disc.n_states} states"
        if visits is not None:
            title += f", {int(np.sum(visits))} visits"
    ax.set_title(title)
    if mappable is not None:
        cbar = fig.colorbar(mappable, ax=ax, orientation="horizontal", fraction=0.05, pad=0.08)
        cbar.set_label("visits per state (log10 of the count)")
    fig.tight_layout()
    return fig


def plot_states(
    path: str | os.PathLike[str],
    grid: OccupancyMap,
    disc: Discretizer,
    visits: np.ndarray | None = None,
    *,
    robot_radius: float | None = DEFAULT_ROBOT_RADIUS,
    title: str | None = None,
    overwrite: bool = False,
) -> Path:
    """Write the figure to ``path`` (PNG) atomically; refuses to replace a file unless ``overwrite``."""
    path = ensure_new(path, overwrite=overwrite, what="figure")
    data = render_states_png(grid, disc, visits, robot_radius=robot_radius, title=title)
    with atomic_write(path, "wb") as fh:
        fh.write(data)
    return path
