"""The likelihood-field sensor model (Thrun, Burgard & Fox, *Probabilistic Robotics*, 6.4).

A beam's end point is scored by its distance ``d`` to the nearest occupied cell of the map,
not by ray casting: ``p(z | x, m) = z_hit * N(d; 0, sigma_hit) + z_rand / z_max``, where
``N`` is the Gaussian density (1/m) and ``z_rand / z_max`` the uniform density of random
returns over the sensor's range. Beams without a return (``inf``) are skipped, as in the
book's algorithm (max-range readings carry no end point). A scan's log-likelihood is the
sum over the beams used.

The distance to the nearest occupied cell is precomputed once per map (Euclidean distance
transform between pixel centres), and so is ``log p`` per pixel, so scoring a particle is
one table look-up per beam. An end point outside the map scores ``log(z_rand / z_max)``,
as if no obstacle could explain it. Unknown cells are not obstacles (only cells with
occupancy >= ``occupied_threshold`` percent are).

Two implementations give the same numbers: :func:`scan_log_likelihoods` (a numba kernel,
the one the filter uses) and :func:`scan_log_likelihoods_numpy` (plain vectorized numpy,
the reference of the tests and of ``benchmarks/replay_speed.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from discretize.gridmap import OccupancyMap
from simlab.base import validation
from simlab.base.errors import ConfigError


@dataclass(frozen=True)
class SensorModelParams:
    """Parameters of the likelihood field (metres).

    Attributes:
        sigma_hit: standard deviation (m) of the Gaussian around the nearest obstacle; it
            covers the range noise (LDS-01: 0.01 m), the map's cell size and small map
            errors.
        z_hit: weight of the Gaussian part.
        z_rand: weight of the uniform part (random returns, unmapped objects).
        z_max: range (m) the uniform part is spread over (the LIDAR's ``range_max``).
        max_distance: distances (m) are clipped here; beyond it every end point scores the
            same (keeps the table's values bounded).
        occupied_threshold: occupancy (percent) from which a map cell is an obstacle.
    """

    sigma_hit: float = 0.03
    z_hit: float = 0.95
    z_rand: float = 0.05
    z_max: float = 3.5
    max_distance: float = 0.5
    occupied_threshold: int = 65

    def __post_init__(self) -> None:
        for name in ("sigma_hit", "z_max", "max_distance"):
            validation.positive(getattr(self, name), f"SensorModelParams.{name}")
        for name in ("z_hit", "z_rand"):
            validation.probability(getattr(self, name), f"SensorModelParams.{name}")
        if self.z_rand <= 0:
            raise ConfigError("must be > 0 (else one stray return zeroes a particle)",
                              key="SensorModelParams.z_rand")
        if not 1 <= int(self.occupied_threshold) <= 100:
            raise ConfigError(f"must lie in 1..100, got {self.occupied_threshold!r}",
                              key="SensorModelParams.occupied_threshold")

    def log_density(self, d: NDArray[np.float64] | float) -> NDArray[np.float64]:
        """``log(z_hit * N(d; 0, sigma_hit) + z_rand / z_max)`` for distances ``d`` (m)."""
        d = np.minimum(np.asarray(d, dtype=np.float64), self.max_distance)
        gauss = np.exp(-0.5 * (d / self.sigma_hit) ** 2) / (math.sqrt(2 * math.pi) * self.sigma_hit)
        return np.log(self.z_hit * gauss + self.z_rand / self.z_max)

    @property
    def outside_log_density(self) -> float:
        """Score (log density, log 1/m) of an end point outside the map."""
        return math.log(self.z_rand / self.z_max)

    def nominal_beam_log_likelihood(self, noise_sigma: float) -> float:
        """Expected ``log p`` of one beam of a perfectly localized robot.

        The end point's distance to the obstacle is taken as ``|N(0, noise_sigma)|``
        (range noise and map quantization); the expectation is a 40-node Gauss-Hermite
        quadrature. The filter uses it as the prior of its long-term fit average.
        """
        nodes, weights = np.polynomial.hermite_e.hermegauss(40)
        values = self.log_density(np.abs(nodes * noise_sigma))
        return float(np.sum(weights * values) / math.sqrt(2 * math.pi))


class LikelihoodField:
    """The precomputed field of one map: ``log p`` per pixel, and the map's geometry.

    Attributes:
        map: the :class:`OccupancyMap`.
        params: the :class:`SensorModelParams`.
        distance: ``(H, W)`` float64 distance (m) from each pixel centre to the nearest
            occupied pixel centre (``inf`` if the map has none), not clipped.
        log_table: ``(H, W)`` float64 ``log p`` of an end point in each pixel.
        geometry: ``(6,)`` float64 map origin x, y (m), cos and sin of its yaw, 1 /
            resolution (1/m), and the log density of an end point outside the map.
    """

    def __init__(self, grid: OccupancyMap, params: SensorModelParams | None = None) -> None:
        self.map = grid
        self.params = params or SensorModelParams()
        occupied = grid.occupancy >= self.params.occupied_threshold
        if not occupied.any():
            raise ConfigError(
                "the map has no occupied cell: nothing to localize against",
                key="map", fix="use a map with walls (simlab map)",
            )
        self.distance = ndimage.distance_transform_edt(~occupied) * grid.resolution
        self.log_table = self.params.log_density(self.distance)
        self.log_table.setflags(write=False)
        ox, oy, yaw = grid.origin
        self.geometry = np.array([ox, oy, math.cos(yaw), math.sin(yaw), 1.0 / grid.resolution,
                                  self.params.outside_log_density], dtype=np.float64)

    @property
    def frame(self) -> tuple[float, float, float, float, float]:
        """The first five :attr:`geometry` values as Python floats (origin x, y, cos and sin
        of the yaw, 1 / resolution): the arguments of the per-call kernels."""
        ox, oy, cm, sm, inv_res = (float(v) for v in self.geometry[:5])
        return ox, oy, cm, sm, inv_res

    def log_likelihoods(self, particles: NDArray[np.float64], ranges: NDArray[np.float64],
                        angles: NDArray[np.float64],
                        sensor_offset: NDArray[np.float64]) -> NDArray[np.float64]:
        """Scan log-likelihood ``(N,)`` of each particle ``(N, 3)`` (x, y, yaw).

        ``ranges`` ``(K,)`` metres (``inf`` beams are skipped), ``angles`` ``(K,)`` beam
        directions in the base frame (rad), ``sensor_offset`` ``(2,)`` the sensor in the
        base frame (m).
        """
        return scan_log_likelihoods(self, particles, ranges, angles, sensor_offset)


def _finite_beams(ranges: NDArray[np.float64], angles: NDArray[np.float64]
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    r = np.asarray(ranges, dtype=np.float64)
    a = np.asarray(angles, dtype=np.float64)
    if r.shape != a.shape or r.ndim != 1:
        raise ValueError(f"ranges and angles: expected equal (K,) shapes, got {r.shape}, {a.shape}")
    ok = np.isfinite(r)
    return r[ok], a[ok]


@numba.njit(cache=True)
def yaw_trig(particles):  # pragma: no cover - compiled
    """``(cos, sin)`` ``(N,)`` of the particles' yaws (libm's, as ``math.cos``), computed
    once per update for the likelihood and the estimate (computed once, not twice)."""
    n = particles.shape[0]
    cos_yaw = np.empty(n)
    sin_yaw = np.empty(n)
    for i in range(n):
        cos_yaw[i] = math.cos(particles[i, 2])
        sin_yaw[i] = math.sin(particles[i, 2])
    return cos_yaw, sin_yaw


@numba.njit(cache=True, fastmath=False)
def _field_kernel(particles, ranges, cos_a, sin_a, off_x, off_y, table, ox, oy, cm, sm,
                  inv_res, outside, out):  # pragma: no cover - compiled
    cos_yaw, sin_yaw = yaw_trig(particles)
    return _field_kernel_trig(particles, cos_yaw, sin_yaw, ranges, cos_a, sin_a, off_x, off_y,
                              table, ox, oy, cm, sm, inv_res, outside, out)


@numba.njit(cache=True, fastmath=False)
def _field_kernel_trig(particles, cos_yaw, sin_yaw, ranges, cos_a, sin_a, off_x, off_y, table,
                       ox, oy, cm, sm, inv_res, outside, out):  # pragma: no cover - compiled
    """The likelihood field of each particle, in two passes per particle: the beams' end
    cells as floats (a loop the compiler vectorises: ~1.5x faster), then the
    table look-ups. A float cell index compares as its integer does (NaN and overflow
    fall outside either way), so the sums are the same bits."""
    n = particles.shape[0]
    k = ranges.shape[0]
    h = table.shape[0]
    w = table.shape[1]
    rows = np.empty(k)
    cols = np.empty(k)
    for i in range(n):
        x = particles[i, 0]
        y = particles[i, 1]
        c = cos_yaw[i]
        s = sin_yaw[i]
        sx = x + c * off_x - s * off_y
        sy = y + s * off_x + c * off_y
        for j in range(k):
            bc = c * cos_a[j] - s * sin_a[j]
            bs = s * cos_a[j] + c * sin_a[j]
            dx = sx + ranges[j] * bc - ox
            dy = sy + ranges[j] * bs - oy
            mx = cm * dx + sm * dy
            my = -sm * dx + cm * dy
            cols[j] = np.floor(mx * inv_res)
            rows[j] = np.floor(h - my * inv_res)
        acc = 0.0
        for j in range(k):
            row = rows[j]
            col = cols[j]
            if 0.0 <= row < h and 0.0 <= col < w:
                acc += table[int(row), int(col)]
            else:
                acc += outside
        out[i] = acc
    return out


@numba.njit(cache=True)
def beam_log_likelihoods(particles, cos_yaw, sin_yaw, ranges, angles, beams, offset, table,
                         geometry, out):  # pragma: no cover - compiled
    """:func:`scan_log_likelihoods` of the beams ``beams`` of a scan, with no numpy glue
    (one compiled call per scan): the beams with a return are picked, and their cos/sin taken, here, in the
    order the numpy path keeps them. ``cos_yaw``, ``sin_yaw``: :func:`yaw_trig` of the
    particles. ``geometry`` is :attr:`LikelihoodField.geometry`.
    Returns the number of beams with a return; ``out`` is left untouched when it is 0."""
    k = 0
    for j in range(beams.shape[0]):
        if math.isfinite(ranges[beams[j]]):
            k += 1
    if k == 0:
        return 0
    r = np.empty(k)
    cos_a = np.empty(k)
    sin_a = np.empty(k)
    m = 0
    for j in range(beams.shape[0]):
        b = beams[j]
        if math.isfinite(ranges[b]):
            r[m] = ranges[b]
            cos_a[m] = math.cos(angles[b])
            sin_a[m] = math.sin(angles[b])
            m += 1
    _field_kernel_trig(particles, cos_yaw, sin_yaw, r, cos_a, sin_a, offset[0], offset[1],
                       table, geometry[0], geometry[1], geometry[2], geometry[3], geometry[4],
                       geometry[5], out)
    return k


def scan_log_likelihoods(field: LikelihoodField, particles: NDArray[np.float64],
                         ranges: NDArray[np.float64], angles: NDArray[np.float64],
                         sensor_offset: NDArray[np.float64]) -> NDArray[np.float64]:
    """Numba implementation of :meth:`LikelihoodField.log_likelihoods`."""
    r, a = _finite_beams(ranges, angles)
    p = np.ascontiguousarray(particles, dtype=np.float64)
    out = np.empty(p.shape[0], dtype=np.float64)
    ox, oy, cm, sm, inv_res = field.frame
    return _field_kernel(p, r, np.cos(a), np.sin(a), float(sensor_offset[0]),
                         float(sensor_offset[1]), field.log_table, ox, oy, cm, sm, inv_res,
                         field.params.outside_log_density, out)


def scan_log_likelihoods_numpy(field: LikelihoodField, particles: NDArray[np.float64],
                               ranges: NDArray[np.float64], angles: NDArray[np.float64],
                               sensor_offset: NDArray[np.float64]) -> NDArray[np.float64]:
    """Plain numpy reference of :func:`scan_log_likelihoods` (same result, (N, K) arrays)."""
    r, a = _finite_beams(ranges, angles)
    p = np.asarray(particles, dtype=np.float64)
    c, s = np.cos(p[:, 2:3]), np.sin(p[:, 2:3])
    sx = p[:, 0:1] + c * sensor_offset[0] - s * sensor_offset[1]
    sy = p[:, 1:2] + s * sensor_offset[0] + c * sensor_offset[1]
    ca, sa = np.cos(a)[None, :], np.sin(a)[None, :]
    ex = sx + r[None, :] * (c * ca - s * sa)
    ey = sy + r[None, :] * (s * ca + c * sa)
    ox, oy, cm, sm, inv_res = field.frame
    dx, dy = ex - ox, ey - oy
    mx = cm * dx + sm * dy
    my = -sm * dx + cm * dy
    h, w = field.log_table.shape
    col = np.floor(mx * inv_res).astype(np.int64)
    row = np.floor(h - my * inv_res).astype(np.int64)
    inside = (row >= 0) & (row < h) & (col >= 0) & (col < w)
    values = np.full(row.shape, field.params.outside_log_density)
    values[inside] = field.log_table[row[inside], col[inside]]
    return values.sum(axis=1)
