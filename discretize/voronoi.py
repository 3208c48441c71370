"""Voronoi discretization of a map's free space into Markov states.

The thesis (3.2.2, Fig. 3.5) cut the table into N = 41 states with Voronoi cells.
Here:

1. **Eroded free space.** Free pixels (occupancy 0; unknown counts as blocked, and
   so does everything beyond the image border) whose clearance to the nearest
   non-free pixel is at least the robot radius (default 0.113 m, the half-diagonal
   of the 138 x 178 mm TurtleBot3 Burger footprint). Clearance of a pixel centre =
   Euclidean distance transform to the nearest non-free pixel centre minus half a
   pixel (distance to that pixel's edge). By default only the largest 8-connected
   component is kept: the robot cannot reach the others (e.g. free specks seen
   through a gap behind a wall).
2. **Centres.** Either ``n_states`` centres (default 41) placed by a centroidal
   Voronoi tessellation of the eroded free pixels: farthest-point initialisation
   from the first eroded pixel in row-major order, then Lloyd iterations (each
   centre moves to the mean of the pixels nearest to it) until the assignment no
   longer changes, or the cell-radius rule ``radius=r`` (thesis r_V = 0.09 m): as
   many centres as circles of radius ``r`` fit in the eroded area,
   ``N = max(1, round(area / (pi r^2)))``, then the same placement. Each final
   centre is snapped to the nearest eroded free pixel centre, so every centre lies
   in eroded free space. Everything is deterministic (no random numbers).
   Centres can instead come from a text file of ``x y`` or ``id x y theta`` lines
   (a real robot's; see :func:`read_centres_table`).
3. **Numbering** row-major from the top-left: centres sorted by y (top first) are
   cut into rows greedily: a row starts at the highest remaining centre and holds
   every remaining centre at most ``row_tolerance`` below it (default half the
   median nearest-neighbour distance between centres); rows go top to bottom,
   centres within a row left to right. Centres loaded from a file keep the file's
   order unless renumbering is asked for (their state numbers are what the real
   robot's data refer to).
4. **States.** ``state_of(xy)`` = index of the nearest centre (scipy cKDTree; a single
   pose by brute force, with boundary ties left to the tree); every
   point of the plane has exactly one state, including poses a little off the
   eroded area.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from discretize.gridmap import OccupancyMap
from simlab.base import validation
from simlab.base.errors import ConfigError, DataError
from simlab.base.io import NESTED_TOO_DEEPLY, atomic_write_json, ensure_new

#: Half-diagonal of the TurtleBot3 Burger footprint 138 x 178 mm, metres.
TURTLEBOT3_BURGER_RADIUS = 0.5 * math.hypot(0.138, 0.178)
DEFAULT_ROBOT_RADIUS = 0.113
DEFAULT_N_STATES = 41
FORMAT = "simlab-discretizer"
FORMAT_VERSION = 1


# ----------------------------------------------------------------- free space
def eroded_free_mask(
    grid: OccupancyMap, robot_radius: float = DEFAULT_ROBOT_RADIUS, component: str = "largest"
) -> np.ndarray:
    """``(H, W)`` bool: free pixels where a robot of ``robot_radius`` (m) fits.

    Args:
        grid: the map.
        robot_radius: clearance needed, metres (>= 0).
        component: ``"largest"`` keeps the largest 8-connected region (ties: the
            one whose first pixel comes first in row-major order); ``"all"`` keeps
            every region.
    """
    if not robot_radius >= 0:
        raise ValueError(f"robot_radius: expected >= 0, got {robot_radius}")
    if component not in ("largest", "all"):
        raise ValueError(f"component: expected 'largest' or 'all', got {component!r}")
    free = grid.free_mask()
    padded = np.pad(free, 1, constant_values=False)
    dist = ndimage.distance_transform_edt(padded)[1:-1, 1:-1] * grid.resolution
    eroded = free & (dist - 0.5 * grid.resolution >= robot_radius - 1e-12)
    if component == "largest" and eroded.any():
        labels, n = ndimage.label(eroded, structure=np.ones((3, 3), dtype=bool))
        if n > 1:
            sizes = np.bincount(labels.ravel())[1:]
            eroded = labels == (int(np.argmax(sizes)) + 1)
    return eroded


# ------------------------------------------------------------------ placement
def _farthest_point_init(points: np.ndarray, n: int) -> np.ndarray:
    """Indices of ``n`` points chosen greedily farthest from those already chosen.

    Starts at ``points[0]``; ties go to the lowest index (``argmax``).
    """
    chosen = np.empty(n, dtype=np.int64)
    chosen[0] = 0
    d2 = np.sum((points - points[0]) ** 2, axis=1)
    for k in range(1, n):
        idx = int(np.argmax(d2))
        chosen[k] = idx
        d2 = np.minimum(d2, np.sum((points - points[idx]) ** 2, axis=1))
    return chosen


def lloyd_centres(
    points: np.ndarray, n: int, max_iter: int = 500, progress: bool = False
) -> tuple[np.ndarray, int]:
    """Centroidal Voronoi centres of a point set (k-means with a deterministic start).

    Args:
        points: ``(M, 2)`` metres (pixel centres), M >= n.
        n: number of centres.
        max_iter: bound on Lloyd iterations.
        progress: show a tqdm bar over iterations.
    Returns:
        ``(centres (n, 2), iterations)``; iterations stop when no point changes cell.
    """
    from tqdm import tqdm

    centres = points[_farthest_point_init(points, n)].copy()
    labels = None
    it = 0
    bar = tqdm(total=max_iter, desc="Lloyd iterations", unit="it", disable=not progress, leave=False)
    try:
        for it in range(1, max_iter + 1):  # noqa: B007 - the count is returned
            _, new_labels = cKDTree(centres).query(points)
            if labels is not None and np.array_equal(new_labels, labels):
                break
            labels = new_labels
            counts = np.bincount(labels, minlength=n).astype(np.float64)
            sx = np.bincount(labels, weights=points[:, 0], minlength=n)
            sy = np.bincount(labels, weights=points[:, 1], minlength=n)
            nonempty = counts > 0
            centres[nonempty, 0] = sx[nonempty] / counts[nonempty]
            centres[nonempty, 1] = sy[nonempty] / counts[nonempty]
            bar.update(1)
    finally:
        bar.close()
    return centres, it


def row_major_order(centres: np.ndarray, row_tolerance: float | None = None) -> np.ndarray:
    """Permutation putting ``centres`` ``(N, 2)`` in row-major order from the top-left.

    Rows are built greedily from the top (see the module docstring). Returns
    ``order`` such that ``centres[order]`` is the numbered sequence.
    """
    centres = np.asarray(centres, dtype=np.float64)
    n = len(centres)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    if row_tolerance is None:
        row_tolerance = default_row_tolerance(centres)
    by_y = np.lexsort((centres[:, 0], -centres[:, 1]))  # y descending, then x
    order: list[int] = []
    start = 0
    while start < n:
        y_top = centres[by_y[start], 1]
        stop = start
        while stop < n and centres[by_y[stop], 1] >= y_top - row_tolerance:
            stop += 1
        row = by_y[start:stop]
        row = row[np.lexsort((-centres[row, 1], centres[row, 0]))]  # x ascending, then top
        order.extend(int(i) for i in row)
        start = stop
    return np.asarray(order, dtype=np.int64)


def default_row_tolerance(centres: np.ndarray) -> float:
    """Half the median nearest-neighbour distance between ``centres`` (metres)."""
    centres = np.asarray(centres, dtype=np.float64)
    if len(centres) < 2:
        return 0.0
    d, _ = cKDTree(centres).query(centres, k=2)
    return 0.5 * float(np.median(d[:, 1]))


# ----------------------------------------------------------------- discretizer
def _centres_hash(centres: np.ndarray) -> str:
    h = hashlib.sha256()
    h.update(b"simlab-discretizer-v1\0")
    h.update(np.ascontiguousarray(centres, dtype="<f8").tobytes())
    return h.hexdigest()


@dataclass(frozen=True, eq=False)
class Discretizer:
    """Nearest-centre (Voronoi) partition of the plane into ``n_states`` states.

    Attributes:
        centres: ``(N, 2)`` float64 world coordinates in metres; state ``i`` is the
            cell of ``centres[i]``. Stored read-only.
        map_hash: :meth:`OccupancyMap.content_hash` of the map the centres were
            placed on (None if unknown).
        method: ``"lloyd"``, ``"radius"`` or ``"file"``.
        params: JSON-able parameters of the construction (robot radius, requested
            count, iterations, row tolerance, ...), recorded for provenance.
    """

    centres: np.ndarray
    map_hash: str | None = None
    method: str = "lloyd"
    params: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        c = np.array(self.centres, dtype=np.float64, copy=True)
        if c.ndim != 2 or c.shape[1] != 2 or c.shape[0] < 1:
            raise ValueError(f"centres: expected a non-empty (N, 2) array, got shape {c.shape}")
        if not np.all(np.isfinite(c)):
            raise ValueError("centres: coordinates must be finite")
        if len(np.unique(c, axis=0)) != len(c):
            raise ValueError("centres: two centres coincide")
        c.setflags(write=False)
        object.__setattr__(self, "centres", c)
        object.__setattr__(self, "params", dict(self.params))
        object.__setattr__(self, "_tree", cKDTree(c))
        object.__setattr__(self, "_centre_list", [tuple(xy) for xy in c.tolist()])

    @property
    def n_states(self) -> int:
        return int(self.centres.shape[0])

    def state_of(self, xy: np.ndarray) -> np.ndarray:
        """State index of each pose: ``xy (..., 2)`` metres (extra columns such as yaw
        are ignored) -> int64 ``(...)``. The nearest centre wins."""
        xy = np.asarray(xy, dtype=np.float64)
        if xy.ndim == 0 or xy.shape[-1] < 2:
            raise ValueError(f"xy: expected shape (..., 2), got {xy.shape}")
        pts = xy[..., :2]
        if pts.size == 2:  # one pose (the replay's hot path): floats, no tree walk
            x, y = pts.ravel().tolist()
            if not (math.isfinite(x) and math.isfinite(y)):
                raise ValueError("xy: poses must be finite")
            return np.array(self._nearest_one(x, y), dtype=np.int64).reshape(pts.shape[:-1])
        if not np.all(np.isfinite(pts)):
            raise ValueError("xy: poses must be finite")
        _, idx = self._tree.query(pts.reshape(-1, 2))  # type: ignore[attr-defined]
        return np.asarray(idx, dtype=np.int64).reshape(pts.shape[:-1])

    #: a brute-force nearest centre is trusted when the runner-up is farther by this
    #: fraction of its squared distance (rounding is ~1e-16 of it)
    _TIE_MARGIN = 1e-9

    def _nearest_one(self, x: float, y: float) -> int:
        """Nearest centre of one point by brute force in Python floats (~10x cheaper than a
        cKDTree query for the ~40 centres of a table). When the two nearest are
        equally far within rounding (on a cell boundary) the tree decides, so that ties
        break exactly as :meth:`state_of` always broke them."""
        best = second = math.inf
        best_i = 0
        for i, (cx, cy) in enumerate(self._centre_list):  # type: ignore[attr-defined]
            dx, dy = x - cx, y - cy
            d = dx * dx + dy * dy
            if d < best:
                best, second, best_i = d, best, i
            elif d < second:
                second = d
        if second - best > self._TIE_MARGIN * second:
            return best_i
        return int(self._tree.query((x, y))[1])  # type: ignore[attr-defined]

    def label_image(self, grid: OccupancyMap) -> np.ndarray:
        """``(H, W)`` int64 state of every pixel centre of ``grid`` (for plots)."""
        return self.state_of(grid.pixel_centres()).reshape(grid.shape)

    def content_hash(self) -> str:
        """SHA-256 (hex) of the partition: the centres in state order (float64 bytes).

        Two discretizers with equal hashes map every pose to the same state.
        """
        return _centres_hash(self.centres)

    # ------------------------------------------------------------------- files
    def to_json(self) -> dict[str, Any]:
        """The JSON document :meth:`save` writes."""
        return {
            "format": FORMAT,
            "version": FORMAT_VERSION,
            "n_states": self.n_states,
            "centres": [[float(x), float(y)] for x, y in self.centres],
            "map_hash": self.map_hash,
            "method": self.method,
            "params": dict(self.params),
            "content_hash": self.content_hash(),
        }

    def save(self, path: str | os.PathLike[str], *, overwrite: bool = False) -> Path:
        """Write JSON atomically (``centres`` as ``[[x, y], ...]``); refuses to replace
        an existing file unless ``overwrite``."""
        path = ensure_new(path, overwrite=overwrite, what="states file")
        atomic_write_json(path, self.to_json())
        return path

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Discretizer:
        """Read a file written by :meth:`save`. Raises :class:`DataError` if it is
        malformed or its ``content_hash`` does not match its centres."""
        path = Path(path)
        validation.existing_file(path, what="states file")
        try:
            doc = json.loads(path.read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError) as exc:
            raise DataError(f"{path}: not valid JSON ({exc})") from None
        except RecursionError:
            raise DataError(f"{path}: {NESTED_TOO_DEEPLY}") from None
        if not isinstance(doc, dict) or "centres" not in doc:
            raise DataError(f"{path}: not a states file (no 'centres' list)")
        raw = doc["centres"]
        try:
            centres = np.asarray(raw, dtype=np.float64)
        except (TypeError, ValueError):
            raise DataError(f"{path}: centres: expected a list of [x, y] numbers") from None
        if centres.ndim != 2 or centres.shape[1] != 2 or len(centres) == 0:
            raise DataError(f"{path}: centres: expected a non-empty list of [x, y] pairs")
        stored = doc.get("content_hash")
        try:
            disc = cls(
                centres=centres,
                map_hash=doc.get("map_hash"),
                method=str(doc.get("method", "file")),
                params=doc.get("params") or {},
            )
        except ValueError as exc:
            raise DataError(f"{path}: {exc}") from None
        if stored is not None and stored != disc.content_hash():
            raise DataError(
                f"{path}: content_hash does not match the centres (file edited?); "
                "delete the content_hash key to accept the edited centres"
            )
        return disc

    # ------------------------------------------------------------ construction
    @classmethod
    def from_map(
        cls,
        grid: OccupancyMap,
        n_states: int | None = None,
        *,
        radius: float | None = None,
        robot_radius: float = DEFAULT_ROBOT_RADIUS,
        component: str = "largest",
        max_iter: int = 500,
        row_tolerance: float | None = None,
        progress: bool = False,
        source: str | os.PathLike[str] | None = None,
    ) -> Discretizer:
        """Place centres on ``grid``'s eroded free space (see the module docstring).

        Give ``n_states`` (default 41) or ``radius`` (cell-radius rule, metres), not both.
        ``source`` names the map file in error messages.
        """
        if n_states is not None and radius is not None:
            raise ConfigError("give either a number of states or a cell radius, not both", key="states")
        if radius is not None and not (math.isfinite(radius) and radius > 0):
            raise ConfigError(f"expected a cell radius > 0 m, got {radius!r}", key="radius")
        if radius is None and n_states is None:
            n_states = DEFAULT_N_STATES
        if n_states is not None:
            validation.whole(n_states, "states", minimum=1)
        if not (math.isfinite(robot_radius) and robot_radius >= 0):
            raise ConfigError(f"expected a radius >= 0 m, got {robot_radius!r}", key="robot_radius")
        eroded = eroded_free_mask(grid, robot_radius, component)
        n_free = int(eroded.sum())
        if n_free == 0:
            raise ConfigError(
                f"no free space left after eroding by the robot radius {robot_radius} m "
                f"({int(grid.free_mask().sum())} free pixels before erosion)",
                path=source,
                fix="check the map (free pixels must be white) or lower --robot-radius",
            )
        area = n_free * grid.resolution**2
        if radius is not None:
            method = "radius"
            n = max(1, round(area / (math.pi * radius**2)))
        else:
            method = "lloyd"
            n = int(n_states)  # type: ignore[arg-type]
        if n > n_free:
            raise ConfigError(
                f"{n} states requested but the eroded free space has only {n_free} pixels",
                path=source,
                key="states",
                fix="ask for fewer states or use a finer map",
            )
        points = grid.pixel_centres(eroded)
        centroids, iterations = lloyd_centres(points, n, max_iter=max_iter, progress=progress)
        _, snap = cKDTree(points).query(centroids)
        centres = points[snap]
        if len(np.unique(snap)) != n:  # pragma: no cover - only with degenerate inputs
            raise ConfigError(
                f"{n} states do not fit: two centres snap to the same pixel",
                path=source,
                key="states",
                fix="ask for fewer states or use a finer map",
            )
        tol = default_row_tolerance(centres) if row_tolerance is None else float(row_tolerance)
        centres = centres[row_major_order(centres, tol)]
        params = {
            "robot_radius": float(robot_radius),
            "states_requested": None if n_states is None else int(n_states),
            "radius": None if radius is None else float(radius),
            "component": component,
            "lloyd_iterations": int(iterations),
            "max_iter": int(max_iter),
            "numbering": "row-major-top-left",
            "row_tolerance": tol,
            "eroded_area_m2": area,
            "map_resolution": grid.resolution,
        }
        return cls(centres=centres, map_hash=grid.content_hash(), method=method, params=params)

    @classmethod
    def from_centres(
        cls,
        centres: np.ndarray,
        *,
        grid: OccupancyMap | None = None,
        renumber: bool = False,
        row_tolerance: float | None = None,
        source: str | os.PathLike[str] | None = None,
    ) -> Discretizer:
        """Wrap given centres ``(N, 2)`` (metres). With ``grid``, each centre must lie
        inside the map on a free pixel (catches wrong frames, units or a flipped image):
        every centre that does not is listed (:mod:`discretize.mapcheck`)."""
        centres = np.asarray(centres, dtype=np.float64)
        if len(np.unique(centres, axis=0)) != len(centres):
            raise ConfigError("two centres coincide", path=source)
        map_hash = None
        if grid is not None:
            from discretize.mapcheck import check_points

            check = check_points(grid, centres, what="centre")
            if not check.ok:
                raise ConfigError(
                    check.message(), path=source,
                    fix=None if check.flip_suggested else
                    "centres must be in the map frame, in metres, on free pixels",
                )
            map_hash = grid.content_hash()
        params: dict[str, Any] = {"numbering": "file-order"}
        if renumber:
            tol = default_row_tolerance(centres) if row_tolerance is None else float(row_tolerance)
            centres = centres[row_major_order(centres, tol)]
            params = {"numbering": "row-major-top-left", "row_tolerance": tol}
        if source is not None:
            params["source"] = str(source)
        return cls(centres=centres, map_hash=map_hash, method="file", params=params)


_CENTRE_COLUMNS = {2: ("x", "y"), 4: ("id", "x", "y", "theta")}
_CENTRE_NAMES = {"id": "id", "x": "x", "y": "y", "theta": "theta", "yaw": "theta"}


def _centre_header(tokens: list[str], path: Path, lineno: int) -> tuple[str, ...] | None:
    """Column names if ``tokens`` is a header line (no number in it), else None."""
    try:
        [float(tok) for tok in tokens]
        return None
    except ValueError:
        pass
    names = tuple(_CENTRE_NAMES.get(tok.lower(), "") for tok in tokens)
    if "" in names or not {"x", "y"} <= set(names) or len(set(names)) != len(names):
        raise ConfigError(f"header {' '.join(tokens)!r}: expected columns 'x y' or "
                          "'id x y theta'", path=path, key=f"line {lineno}")
    return names


def read_centres_table(path: str | os.PathLike[str]) -> tuple[np.ndarray, np.ndarray | None]:
    """Read a centres text file: ``(centres (N, 2) m, theta (N,) rad or None)``.

    Two layouts, told apart by an optional header line (``x y`` or ``id x y theta``;
    ``yaw`` is accepted for ``theta``) or else by the column count: ``x y`` lines, or
    ``id x y theta`` lines (the ISIR export). With ids, the ids define the state
    numbering: they must be whole numbers ``0..N-1``, each once, and the rows are
    returned sorted by id. Blank lines and ``#`` comments are skipped; commas may
    separate the numbers. Raises :class:`ConfigError` naming the file and line.
    """
    path = Path(path)
    validation.existing_file(path, what="centres file")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ConfigError("not a text file", path=path) from None
    names: tuple[str, ...] | None = None
    rows: list[list[float]] = []
    lines: list[int] = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        body = line.split("#", 1)[0].replace(",", " ").split()
        if not body:
            continue
        if names is None and not rows:
            names = _centre_header(body, path, lineno)
            if names is not None:
                continue
        if names is None:
            names = _CENTRE_COLUMNS.get(len(body))
            if names is None:
                raise ConfigError(f"expected 'x y' or 'id x y theta' (2 or 4 numbers), got "
                                  f"{line.strip()!r}", path=path, key=f"line {lineno}")
        if len(body) != len(names):
            raise ConfigError(f"expected {len(names)} numbers '{' '.join(names)}', got "
                              f"{line.strip()!r}", path=path, key=f"line {lineno}")
        try:
            values = [float(tok) for tok in body]
        except ValueError:
            raise ConfigError(f"expected numbers '{' '.join(names)}', got {line.strip()!r}",
                              path=path, key=f"line {lineno}") from None
        if not all(math.isfinite(v) for v in values):
            raise ConfigError("coordinates must be finite", path=path, key=f"line {lineno}")
        rows.append(values)
        lines.append(lineno)
    if not rows or names is None:
        raise ConfigError("no centres in the file", path=path,
                          fix="write one 'x y' (or 'id x y theta') line per centre")
    data = np.asarray(rows, dtype=np.float64)
    col = {name: data[:, k] for k, name in enumerate(names)}
    centres = np.column_stack([col["x"], col["y"]])
    theta = col.get("theta")
    if "id" in col:
        ids = col["id"]
        for k, v in enumerate(ids):
            if not v.is_integer():
                raise ConfigError(f"id {v:g} is not a whole number", path=path,
                                  key=f"line {lines[k]}")
        seen: set[float] = set()
        for k, v in enumerate(ids):
            if v in seen:
                raise ConfigError(f"id {v:g} appears twice", path=path, key=f"line {lines[k]}",
                                  fix="number the states 0..N-1, each once")
            seen.add(v)
        order = np.argsort(ids, kind="stable")
        if not np.array_equal(ids[order], np.arange(len(ids))):
            raise ConfigError(f"ids must be 0..{len(ids) - 1}, got {ids.min():g}..{ids.max():g}",
                              path=path, key="id", fix="number the states 0..N-1, each once")
        centres, theta = centres[order], None if theta is None else theta[order]
    return centres, theta


def load_centres_txt(path: str | os.PathLike[str]) -> np.ndarray:
    """Centres ``(N, 2)`` (metres) of a centres text file (see :func:`read_centres_table`:
    ``x y`` or ``id x y theta`` lines; with ids, in id order)."""
    return read_centres_table(path)[0]


def load_states(path: str | os.PathLike[str]) -> Discretizer:
    """A discretizer from a states file: ``simlab discretize`` JSON (``.json`` or content
    starting with ``{``) or a centres text file (file order / ids = state numbers)."""
    path = Path(path)
    validation.existing_file(path, what="states file")
    head = path.read_bytes()[:4096].lstrip()
    if path.suffix.lower() == ".json" or head.startswith(b"{"):
        return Discretizer.load(path)
    return Discretizer.from_centres(load_centres_txt(path), source=path)
