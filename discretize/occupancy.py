"""Log-odds occupancy grid built from range scans and sensor poses.

The grid knows nothing of a simulator: a scan is plain arrays (ranges in metres,
beam angles in the sensor frame in radians) plus the sensor pose ``(x, y, yaw)`` in
the map frame. Image orientation is the map_server one (row 0 = top = largest y,
see :mod:`discretize.gridmap`).

Update rule per scan (the standard inverse sensor model, Thrun et al.,
*Probabilistic Robotics* ch. 9), traced exactly cell by cell with the
Amanatides-Woo grid traversal in a numba kernel:

* a finite reading ``range_min <= r <= range_max`` is a hit: the cells the beam
  crosses before the endpoint's cell get ``l_free``, the endpoint's cell
  ``l_occ``;
* an ``inf`` (or ``> range_max``) reading means "nothing within range": the beam
  marks cells free up to ``inf_free_range`` (default ``range_max``; ``0`` ignores
  such beams) and sets no endpoint;
* NaN readings and readings below ``range_min`` are ignored.

Within one scan a cell is updated at most once, and a cell that is the endpoint of
any beam of the scan is not also marked free by a neighbouring grazing beam
(otherwise walls seen at shallow angles wash out). Log-odds are clamped to
``[l_min, l_max]`` so the map can still change when the world does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from discretize.gridmap import FREE, OCCUPIED, UNKNOWN, OccupancyMap


@dataclass(frozen=True)
class LogOddsParams:
    """Inverse sensor model and export thresholds.

    Attributes:
        l_occ: log-odds added to a beam's endpoint cell (> 0). Default ``ln(0.7/0.3)``.
        l_free: log-odds added to a crossed cell (< 0). Default ``ln(0.4/0.6)``.
        l_min, l_max: clamping bounds of the log-odds.
        occupied_thresh: probability above which a cell is exported occupied.
        free_thresh: probability below which a cell is exported free.
    """

    l_occ: float = 0.8473
    l_free: float = -0.4055
    l_min: float = -4.0
    l_max: float = 4.0
    occupied_thresh: float = 0.65
    free_thresh: float = 0.196

    def __post_init__(self) -> None:
        if not self.l_occ > 0:
            raise ValueError(f"l_occ: expected > 0, got {self.l_occ}")
        if not self.l_free < 0:
            raise ValueError(f"l_free: expected < 0, got {self.l_free}")
        if not self.l_min < 0 < self.l_max:
            raise ValueError(f"l_min, l_max: expected l_min < 0 < l_max, got {self.l_min}, {self.l_max}")
        if not 0.0 <= self.free_thresh < self.occupied_thresh <= 1.0:
            raise ValueError(
                "free_thresh, occupied_thresh: expected 0 <= free_thresh < occupied_thresh <= 1, "
                f"got {self.free_thresh}, {self.occupied_thresh}"
            )


@numba.njit(cache=True, nogil=True)
def _integrate_kernel(
    log_odds: np.ndarray,
    hit_stamp: np.ndarray,
    free_stamp: np.ndarray,
    stamp: np.int64,
    sx: float,
    sy: float,
    ex: np.ndarray,
    ey: np.ndarray,
    is_hit: np.ndarray,
    l_free: float,
    l_occ: float,
    l_min: float,
    l_max: float,
) -> int:
    """Trace beams from ``(sx, sy)`` to ``(ex[k], ey[k])`` (grid units, y up).

    Cell ``(i, j)`` (column, row from the bottom) is ``log_odds[H-1-j, i]``. Returns
    the number of cell updates.
    """
    height, width = log_odds.shape
    n = ex.shape[0]
    i0 = int(np.floor(sx))
    j0 = int(np.floor(sy))
    # Endpoints first, so that free updates can skip them.
    for k in range(n):
        if is_hit[k]:
            i = int(np.floor(ex[k]))
            j = int(np.floor(ey[k]))
            if 0 <= i < width and 0 <= j < height:
                hit_stamp[height - 1 - j, i] = stamp
    updates = 0
    for k in range(n):
        dx = ex[k] - sx
        dy = ey[k] - sy
        i1 = int(np.floor(ex[k]))
        j1 = int(np.floor(ey[k]))
        steps = abs(i1 - i0) + abs(j1 - j0)
        step_i = 1 if dx > 0 else -1
        step_j = 1 if dy > 0 else -1
        if dx != 0.0:
            t_delta_i = abs(1.0 / dx)
            t_max_i = ((i0 + 1 - sx) if dx > 0 else (sx - i0)) * t_delta_i
        else:
            t_delta_i = np.inf
            t_max_i = np.inf
        if dy != 0.0:
            t_delta_j = abs(1.0 / dy)
            t_max_j = ((j0 + 1 - sy) if dy > 0 else (sy - j0)) * t_delta_j
        else:
            t_delta_j = np.inf
            t_max_j = np.inf
        i = i0
        j = j0
        for _ in range(steps):
            if 0 <= i < width and 0 <= j < height:
                r = height - 1 - j
                if hit_stamp[r, i] != stamp and free_stamp[r, i] != stamp:
                    free_stamp[r, i] = stamp
                    v = log_odds[r, i] + l_free
                    log_odds[r, i] = l_min if v < l_min else v
                    updates += 1
            if t_max_i < t_max_j:
                i += step_i
                t_max_i += t_delta_i
            else:
                j += step_j
                t_max_j += t_delta_j
        if is_hit[k] and 0 <= i1 < width and 0 <= j1 < height:
            r = height - 1 - j1
            # hit_stamp == stamp for every endpoint; use free_stamp = -stamp to add
            # l_occ once per cell and scan.
            if free_stamp[r, i1] != -stamp:
                free_stamp[r, i1] = -stamp
                v = log_odds[r, i1] + l_occ
                log_odds[r, i1] = l_max if v > l_max else v
                updates += 1
    return updates


def beam_endpoints(
    ranges: np.ndarray,
    angles: np.ndarray,
    sensor_pose: np.ndarray,
    range_min: float,
    range_max: float,
    inf_free_range: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """World endpoints ``(K, 2)`` and hit flags ``(K,)`` of the usable beams of a scan.

    Args:
        ranges: ``(B,)`` metres; ``inf`` = nothing within range, NaN = invalid.
        angles: ``(B,)`` beam directions in the sensor frame, radians (CCW).
        sensor_pose: ``(3,)`` sensor ``(x, y, yaw)`` in the map frame.
        range_min, range_max: valid range interval (metres).
        inf_free_range: free length traced for no-return beams (default
            ``range_max``; ``0`` drops them).
    """
    ranges = np.asarray(ranges, dtype=np.float64)
    angles = np.asarray(angles, dtype=np.float64)
    if ranges.shape != angles.shape or ranges.ndim != 1:
        raise ValueError(f"ranges, angles: expected equal (B,) shapes, got {ranges.shape}, {angles.shape}")
    x, y, yaw = (float(v) for v in np.asarray(sensor_pose, dtype=np.float64).reshape(3))
    free_len = range_max if inf_free_range is None else float(inf_free_range)
    hit = np.isfinite(ranges) & (ranges >= range_min) & (ranges <= range_max)
    miss = (ranges > range_max) & (free_len > 0)  # includes +inf
    use = hit | miss
    length = np.where(hit, ranges, free_len)[use]
    theta = yaw + angles[use]
    ends = np.empty((length.size, 2))
    ends[:, 0] = x + length * np.cos(theta)
    ends[:, 1] = y + length * np.sin(theta)
    return ends, hit[use]


class OccupancyGrid:
    """A mutable log-odds grid (the only mutable object of the package: it accumulates scans).

    Args:
        shape: ``(H, W)`` pixels.
        resolution: metres per pixel (default 0.01).
        origin_xy: world ``(x, y)`` of the lower-left image corner (metres); yaw is 0.
        params: :class:`LogOddsParams`.
    """

    def __init__(
        self,
        shape: tuple[int, int],
        resolution: float = 0.01,
        origin_xy: tuple[float, float] = (0.0, 0.0),
        params: LogOddsParams | None = None,
    ) -> None:
        height, width = (int(v) for v in shape)
        if height < 1 or width < 1:
            raise ValueError(f"shape: expected positive (H, W), got {shape}")
        if not resolution > 0:
            raise ValueError(f"resolution: expected > 0, got {resolution}")
        from simlab.base.guards import array_bytes, check_memory

        # log-odds + two stamps (8 bytes each) and the int8 map made from them
        check_memory(array_bytes((height, width), 25), key="resolution",
                     what=f"a {height} x {width} occupancy grid",
                     fix="map a smaller arena or choose a coarser --resolution")
        self.resolution = float(resolution)
        self.origin_xy = (float(origin_xy[0]), float(origin_xy[1]))
        self.params = params if params is not None else LogOddsParams()
        self.log_odds = np.zeros((height, width), dtype=np.float64)
        self._hit_stamp = np.zeros((height, width), dtype=np.int64)
        self._free_stamp = np.zeros((height, width), dtype=np.int64)
        self._stamp = 0
        self.n_scans = 0

    @classmethod
    def covering(
        cls,
        bounds: tuple[float, float, float, float],
        resolution: float = 0.01,
        margin: float = 0.25,
        params: LogOddsParams | None = None,
    ) -> OccupancyGrid:
        """A grid covering ``bounds = (x_min, y_min, x_max, y_max)`` plus ``margin`` (m).

        The origin is ``(x_min - m, y_min - m)`` with ``m`` the margin rounded up to
        whole pixels, so pixel edges fall on the bounds when they are multiples of
        the resolution from each other.
        """
        x_min, y_min, x_max, y_max = (float(v) for v in bounds)
        pad = int(np.ceil(margin / resolution - 1e-9))
        width = int(np.ceil((x_max - x_min) / resolution - 1e-9)) + 2 * pad
        height = int(np.ceil((y_max - y_min) / resolution - 1e-9)) + 2 * pad
        origin = (x_min - pad * resolution, y_min - pad * resolution)
        return cls((height, width), resolution, origin, params)

    @property
    def shape(self) -> tuple[int, int]:
        return self.log_odds.shape  # type: ignore[return-value]

    def integrate(
        self,
        ranges: np.ndarray,
        angles: np.ndarray,
        sensor_pose: np.ndarray,
        range_min: float,
        range_max: float,
        inf_free_range: float | None = None,
        *,
        backend: str = "numba",
    ) -> int:
        """Add one scan. Arguments as :func:`beam_endpoints`; returns the number of cell updates.

        ``backend="python"`` runs the same kernel interpreted, beam by beam (the
        baseline of ``benchmarks/discretize_speed.py``); results are identical.
        """
        if backend not in ("numba", "python"):
            raise ValueError(f"backend: expected 'numba' or 'python', got {backend!r}")
        kernel = _integrate_kernel if backend == "numba" else _integrate_kernel.py_func
        ends, hit = beam_endpoints(ranges, angles, sensor_pose, range_min, range_max, inf_free_range)
        sx = (float(sensor_pose[0]) - self.origin_xy[0]) / self.resolution
        sy = (float(sensor_pose[1]) - self.origin_xy[1]) / self.resolution
        gx = (ends[:, 0] - self.origin_xy[0]) / self.resolution
        gy = (ends[:, 1] - self.origin_xy[1]) / self.resolution
        self._stamp += 1
        p = self.params
        n = kernel(
            self.log_odds,
            self._hit_stamp,
            self._free_stamp,
            np.int64(self._stamp),
            sx,
            sy,
            gx,
            gy,
            hit,
            p.l_free,
            p.l_occ,
            p.l_min,
            p.l_max,
        )
        self.n_scans += 1
        return int(n)

    def probability(self) -> np.ndarray:
        """``(H, W)`` occupancy probability ``1 / (1 + exp(-l))``."""
        return 1.0 / (1.0 + np.exp(-self.log_odds))

    def observed_mask(self) -> np.ndarray:
        """``(H, W)`` bool: cells some beam has touched (log-odds not exactly 0)."""
        return self.log_odds != 0.0

    def to_map(self) -> OccupancyMap:
        """Trinary :class:`OccupancyMap`: occupied above ``occupied_thresh``, free below ``free_thresh``."""
        prob = self.probability()
        occ = np.full(self.shape, UNKNOWN, dtype=np.int8)
        occ[prob > self.params.occupied_thresh] = OCCUPIED
        occ[prob < self.params.free_thresh] = FREE
        occ[~self.observed_mask()] = UNKNOWN
        return OccupancyMap(occupancy=occ, resolution=self.resolution, origin=(*self.origin_xy, 0.0))



@dataclass(frozen=True)
class MapAccuracy:
    """A map compared with a ground-truth raster (fractions in [0, 1]).

    Attributes:
        wall_correct: of the truth-occupied pixels the map has observed (not
            unknown), the fraction mapped occupied; a pixel also counts as correct
            when a mapped-occupied pixel lies within ``tolerance_px`` of it (range
            noise and pixel quantisation smear a wall's surface by about a pixel).
        wall_coverage: of the truth wall-surface pixels (occupied pixels 8-adjacent
            to truth-free ones), the fraction with a mapped-occupied pixel within
            ``tolerance_px``: how much of the walls the map shows.
        free_correct: of the truth-free pixels of ``region`` farther than
            ``tolerance_px`` from any truth-occupied pixel, the fraction mapped free
            (unknown counts as wrong, so this also measures coverage).
        n_wall_observed, n_surface, n_free: the pixel counts behind the fractions.
        tolerance_px: the tolerance band, pixels (Chebyshev distance).
    """

    wall_correct: float
    wall_coverage: float
    free_correct: float
    n_wall_observed: int
    n_surface: int
    n_free: int
    tolerance_px: int


def map_accuracy(
    grid: OccupancyMap,
    truth_occupied: np.ndarray,
    region: np.ndarray | None = None,
    tolerance_px: int = 1,
) -> MapAccuracy:
    """Compare ``grid`` with ``truth_occupied`` ``(H, W)`` bool (same pixels, True = wall).

    ``region`` ``(H, W)`` bool restricts the free-space score (default: every
    truth-free pixel). See :class:`MapAccuracy` for the definitions.
    """
    from scipy import ndimage

    truth = np.asarray(truth_occupied, dtype=bool)
    if truth.shape != grid.shape:
        raise ValueError(f"truth_occupied: expected shape {grid.shape}, got {truth.shape}")
    truth_free = ~truth
    if region is not None:
        truth_free &= np.asarray(region, dtype=bool)
    k = 2 * int(tolerance_px) + 1
    box = np.ones((k, k), dtype=bool)
    mapped_occ = grid.occupancy >= OCCUPIED * 0.65
    near_mapped_occ = ndimage.binary_dilation(mapped_occ, box) if tolerance_px else mapped_occ
    observed = grid.occupancy != UNKNOWN
    wall_obs = truth & observed
    surface = truth & ndimage.binary_dilation(~truth, np.ones((3, 3), dtype=bool))
    near_truth_occ = ndimage.binary_dilation(truth, box) if tolerance_px else truth
    free_scored = truth_free & ~near_truth_occ

    def frac(mask_ok: np.ndarray, mask_all: np.ndarray) -> float:
        n = int(mask_all.sum())
        return float((mask_ok & mask_all).sum() / n) if n else float("nan")

    return MapAccuracy(
        wall_correct=frac(near_mapped_occ, wall_obs),
        wall_coverage=frac(near_mapped_occ, surface),
        free_correct=frac(grid.occupancy == FREE, free_scored),
        n_wall_observed=int(wall_obs.sum()),
        n_surface=int(surface.sum()),
        n_free=int(free_scored.sum()),
        tolerance_px=int(tolerance_px),
    )
