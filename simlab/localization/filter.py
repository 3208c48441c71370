"""Monte Carlo localization: a particle filter on an occupancy map (augmented MCL).

One cycle (Thrun, Burgard & Fox, *Probabilistic Robotics*, Table 8.3):

1. :meth:`ParticleFilter.predict` moves every particle by the odometry motion between two
   odometry poses, with sampled noise (:mod:`simlab.localization.motion`);
2. :meth:`ParticleFilter.update` weights the particles by the likelihood field of a scan
   (:mod:`simlab.localization.likelihood`, ``n_beams`` beams evenly spread over the scan)
   and stores the pose estimate;
3. low-variance resampling when the effective sample size drops below
   ``resample_threshold * n_particles``, or when particles are to be injected.

Recovery (augmented MCL): ``w_slow`` and ``w_fast`` are long- and short-term averages of
the measurement likelihood; at each resampling a fraction ``max(0, 1 - w_fast / w_slow)``
of the particles is replaced by poses drawn uniformly in free space. Two choices where
the book leaves room:

* the likelihood averaged is the *per-beam* geometric mean of the predictive likelihood,
  ``exp(log(sum_i w_i p(z | x_i)) / K)`` with ``K`` the beams with a return, so that the
  ratio does not depend on how many beams are used (the raw product of 40 densities spans
  dozens of orders of magnitude);
* both averages start at the *nominal* fit, the expected per-beam likelihood of a
  perfectly localized robot (:meth:`SensorModelParams.nominal_beam_log_likelihood` with
  the range noise and the map's cell size). A filter started at a wrong pose therefore
  sees its short-term fit fall below the long-term one at once and injects particles;
  with averages initialised from the first (already wrong) measurement it would not.

Estimate: the weighted mean of the particles near the best one (a few mean-shift steps
from the highest-weight particle, radius ``estimate_radius`` and ``estimate_angle``), so
that a multi-modal cloud (global initialisation, injected particles) gives the pose of
its strongest mode rather than the average of all modes. It is computed at each update,
before resampling, and carried forward by the odometry between updates.

Limitation: in a symmetric arena (the bare square table) the scans of a pose and of its
images under the arena's symmetries (rotations by 90 degrees about the centre) are the
same, so global localization and kidnapped-robot recovery can settle on an image of the
truth; only the initial pose (tracking) or asymmetric obstacles disambiguate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numba
import numpy as np
from numpy.typing import NDArray

from discretize.gridmap import OccupancyMap
from simlab.base import validation
from simlab.base.errors import ConfigError
from simlab.localization.likelihood import (
    LikelihoodField,
    SensorModelParams,
    beam_log_likelihoods,
    yaw_trig,
)
from simlab.localization.motion import (
    OdometryMotionParams,
    compose,
    relative,
    sample_odometry_motion,
    wrap,
)


class ScanLike(Protocol):
    """What :meth:`ParticleFilter.update` reads from a scan (e.g. a ``LidarScan``, whose
    fields are read-only: so are these)."""

    @property
    def ranges(self) -> NDArray[np.float64]: ...

    @property
    def angles(self) -> NDArray[np.float64]: ...

    @property
    def sensor_offset(self) -> NDArray[np.float64]: ...


@dataclass(frozen=True)
class MCLParams:
    """Parameters of the particle filter (SI units: m, rad).

    Attributes:
        n_particles: number of particles N.
        n_beams: beams K used per update, evenly spread over the scan (AMCL ``max_beams``).
        sensor: likelihood-field parameters.
        motion: odometry motion-model noise.
        resample_threshold: resample when N_eff < this fraction of N.
        alpha_slow, alpha_fast: smoothing of the long- and short-term likelihood averages
            (per update; AMCL's recovery_alpha_slow / _fast). 0 disables injection.
        range_noise: range noise (m) assumed for the nominal fit (LDS-01: 0.01).
        inject_clearance: injected and globally initialised particles keep this distance
            (m) from occupied cells (about the robot's half-width: the robot's centre can
            be no nearer to a wall).
        update_min_distance, update_min_angle: a tracker updates the filter only after the
            odometry moved this far (m) or turned this much (rad) since the last update.
        estimate_radius, estimate_angle: neighbourhood of the estimate's mean-shift (m, rad).
    """

    n_particles: int = 500
    n_beams: int = 40
    sensor: SensorModelParams = field(default_factory=SensorModelParams)
    motion: OdometryMotionParams = field(default_factory=OdometryMotionParams)
    resample_threshold: float = 0.5
    alpha_slow: float = 0.001
    alpha_fast: float = 0.1
    range_noise: float = 0.01
    inject_clearance: float = 0.07
    update_min_distance: float = 0.02
    update_min_angle: float = 0.1
    estimate_radius: float = 0.1
    estimate_angle: float = 0.5

    def __post_init__(self) -> None:
        for name in ("n_particles", "n_beams"):
            validation.whole(getattr(self, name), f"MCLParams.{name}", minimum=1)
        for name in ("resample_threshold", "alpha_slow", "alpha_fast"):
            validation.probability(getattr(self, name), f"MCLParams.{name}")
        if self.alpha_fast < self.alpha_slow:
            raise ConfigError(
                f"alpha_fast ({self.alpha_fast}) must be >= alpha_slow ({self.alpha_slow})",
                key="MCLParams.alpha_fast",
            )
        for name in ("range_noise", "inject_clearance", "update_min_distance",
                     "update_min_angle"):
            validation.positive(getattr(self, name), f"MCLParams.{name}", allow_zero=True)
        for name in ("estimate_radius", "estimate_angle"):
            validation.positive(getattr(self, name), f"MCLParams.{name}")


def low_variance_resample(weights: NDArray[np.float64], n: int,
                          rng: np.random.Generator) -> NDArray[np.int64]:
    """Indices ``(n,)`` drawn by low-variance (systematic) resampling (Thrun Table 4.4).

    One uniform draw; particle ``i`` is picked ``floor(n w_i)`` or ``ceil(n w_i)`` times.
    ``weights`` must sum to 1.
    """
    return _low_variance_indices(weights, n, rng.random())


def _low_variance_indices(weights: NDArray[np.float64], n: int, u: float) -> NDArray[np.int64]:
    """:func:`low_variance_resample` with its uniform draw ``u`` given."""
    cdf = np.cumsum(np.asarray(weights, dtype=np.float64))
    cdf[-1] = 1.0  # guard against round-off: every pointer below 1 finds a particle
    pointers = (u + np.arange(n)) / n
    return np.searchsorted(cdf, pointers, side="right").astype(np.int64)


@numba.njit(cache=True)
def _resample_into(weights, u, particles, out):  # pragma: no cover - compiled
    """``out[:] = particles[_low_variance_indices(weights, len(out), u)]`` in one pass
    (no index array). The cumulative sum is numpy's (sequential); walking the sorted pointers
    along it finds what the binary search finds, because "cdf <= pointer" holds on a
    prefix only (the last entry is 1 > every pointer). A NaN or negative weight breaks
    that order, and the last pointer can round up to 1: then returns False (``out``
    unspecified) and the caller takes numpy's search, whatever it gives then."""
    n = out.shape[0]
    if (u + (n - 1)) / n >= 1.0:  # the last pointer rounded up to 1 (u within 2^-44 of 1)
        return False
    m = weights.shape[0]
    cdf = np.empty(m)
    acc = 0.0
    for i in range(m):
        if not weights[i] >= 0.0:  # NaN or negative
            return False
        acc += weights[i]
        cdf[i] = acc
    cdf[m - 1] = 1.0
    j = 0
    for k in range(n):
        pointer = (u + k) / n
        while cdf[j] <= pointer:
            j += 1
        out[k, 0] = particles[j, 0]
        out[k, 1] = particles[j, 1]
        out[k, 2] = particles[j, 2]
    return True


def effective_sample_size(weights: NDArray[np.float64]) -> float:
    """``1 / sum w_i^2`` of normalized weights (N for uniform, 1 for a single particle)."""
    w = np.asarray(weights, dtype=np.float64)
    return float(1.0 / np.sum(w * w))


def weighted_pose_mean(particles: NDArray[np.float64],
                       weights: NDArray[np.float64]) -> NDArray[np.float64]:
    """Weighted mean ``(3,)`` of poses: arithmetic in x, y; circular in yaw."""
    w = np.asarray(weights, dtype=np.float64)
    w = w / w.sum()
    x = float(w @ particles[:, 0])
    y = float(w @ particles[:, 1])
    yaw = math.atan2(float(w @ np.sin(particles[:, 2])), float(w @ np.cos(particles[:, 2])))
    return np.array([x, y, yaw])


@numba.njit(cache=True)
def _mean_shift(p, w, r2, max_angle, steps):  # pragma: no cover - compiled
    """Weighted mean of the particles within (sqrt(r2), max_angle) of a centre that starts
    at the highest-weight particle, iterated ``steps`` times (see ``estimate``)."""
    cos_yaw, sin_yaw = yaw_trig(p)
    return _mean_shift_trig(p, cos_yaw, sin_yaw, w, r2, max_angle, steps)


@numba.njit(cache=True)
def _mean_shift_trig(p, cos_yaw, sin_yaw, w, r2, max_angle, steps):  # pragma: no cover
    """:func:`_mean_shift` with the yaws' cos and sin given (taken once per update, not
    once per particle and step)."""
    centre = p[np.argmax(w)].copy()
    two_pi = 2.0 * math.pi
    for _ in range(steps):
        sw = sx = sy = ss = sc = 0.0
        for i in range(p.shape[0]):
            dx = p[i, 0] - centre[0]
            dy = p[i, 1] - centre[1]
            da = (p[i, 2] - centre[2] + math.pi) % two_pi - math.pi
            if dx * dx + dy * dy <= r2 and abs(da) <= max_angle:
                sw += w[i]
                sx += w[i] * p[i, 0]
                sy += w[i] * p[i, 1]
                ss += w[i] * sin_yaw[i]
                sc += w[i] * cos_yaw[i]
        if sw <= 0.0:
            break
        centre[0] = sx / sw
        centre[1] = sy / sw
        centre[2] = math.atan2(ss, sc)
    return centre


@numba.njit(cache=True)
def _reweight(weights, loglik, out):  # pragma: no cover - compiled
    """One pass each over ``(N,)``: ``out = normalised weights * exp(loglik)``; returns
    (log of the normaliser, effective sample size of ``out``). Zero weights stay zero."""
    n = weights.shape[0]
    top = -math.inf
    for i in range(n):
        lw = math.log(weights[i]) + loglik[i] if weights[i] > 0.0 else -math.inf
        out[i] = lw
        if lw > top:
            top = lw
    acc = 0.0
    for i in range(n):
        acc += math.exp(out[i] - top)
    total = top + math.log(acc)
    sq = 0.0
    for i in range(n):
        v = math.exp(out[i] - total)
        out[i] = v
        sq += v * v
    return total, 1.0 / sq


@numba.njit(cache=True)
def _spread(p, weights):  # pragma: no cover - compiled
    """(position std (m), heading std (rad)) of particles ``p`` ``(N, 3)``: the traces of
    :meth:`ParticleFilter.covariance` in two passes, no temporaries."""
    n = p.shape[0]
    wsum = 0.0
    for i in range(n):
        wsum += weights[i]
    mx = my = ms = mc = 0.0
    for i in range(n):
        w = weights[i] / wsum
        mx += w * p[i, 0]
        my += w * p[i, 1]
        ms += w * math.sin(p[i, 2])
        mc += w * math.cos(p[i, 2])
    myaw = math.atan2(ms, mc)
    two_pi = 2.0 * math.pi
    cxx = cyy = caa = 0.0
    for i in range(n):
        w = weights[i] / wsum
        dx = p[i, 0] - mx
        dy = p[i, 1] - my
        da = (p[i, 2] - myaw + math.pi) % two_pi - math.pi
        cxx += w * dx * dx
        cyy += w * dy * dy
        caa += w * da * da
    return math.sqrt(max(0.0, cxx + cyy)), math.sqrt(max(0.0, caa))


@numba.njit(cache=True)
def _weigh(particles, weights, ranges, angles, beams, offset, table, geometry, r2, max_angle,
           steps, out):  # pragma: no cover - compiled
    """The compiled part of :meth:`ParticleFilter.update` in one call (one
    dispatch instead of three, no glue between): scan log-likelihoods, reweighting into
    ``out``, mean-shift estimate. Returns (beams with a return, log normaliser, effective
    sample size, estimate); with no beam ``out`` is untouched and the rest is zeros."""
    loglik = np.empty(particles.shape[0])
    cos_yaw, sin_yaw = yaw_trig(particles)
    k = beam_log_likelihoods(particles, cos_yaw, sin_yaw, ranges, angles, beams, offset,
                             table, geometry, loglik)
    if k == 0:
        return 0, 0.0, 0.0, np.zeros(3)
    total, ess = _reweight(weights, loglik, out)
    return k, total, ess, _mean_shift_trig(particles, cos_yaw, sin_yaw, out, r2, max_angle,
                                           steps)


def mean_shift_numpy(p: NDArray[np.float64], w: NDArray[np.float64], r2: float,
                     max_angle: float, steps: int) -> NDArray[np.float64]:
    """Plain-numpy reference of the compiled mean shift of :meth:`ParticleFilter.estimate`."""
    centre = p[int(np.argmax(w))].copy()
    for _ in range(steps):
        near = ((p[:, 0] - centre[0]) ** 2 + (p[:, 1] - centre[1]) ** 2 <= r2) & (
            np.abs(wrap(p[:, 2] - centre[2])) <= max_angle)
        if not near.any() or w[near].sum() <= 0:
            break
        centre = weighted_pose_mean(p[near], w[near])
    return centre


class ParticleFilter:
    """A particle filter on an :class:`OccupancyMap` (see the module docstring).

    Parameters
    ----------
    grid:
        The occupancy map (or a prebuilt :class:`LikelihoodField` of it).
    params:
        :class:`MCLParams`.
    rng:
        Draws the motion noise, resampling and injected particles.

    Attributes: ``particles`` ``(N, 3)`` (x, y, yaw), ``weights`` ``(N,)`` normalized,
    ``w_slow``, ``w_fast`` (per-beam likelihood averages, 1/m), ``n_updates``,
    ``n_resamples``, ``n_injected`` (total particles injected), ``last_fit`` (per-beam
    likelihood of the last update).
    """

    #: mean-shift iterations of the estimate
    _MODE_STEPS = 3

    def __init__(self, grid: OccupancyMap | LikelihoodField, params: MCLParams | None = None,
                 rng: np.random.Generator | None = None) -> None:
        if rng is None:
            raise ConfigError("a numpy Generator is needed (np.random.default_rng(seed))",
                              key="rng")
        self.params = params or MCLParams()
        if isinstance(grid, LikelihoodField):
            self.field = grid
        else:
            self.field = LikelihoodField(grid, self.params.sensor)
        self.map = self.field.map
        self.rng = rng
        res = self.map.resolution
        nominal = self.params.sensor.nominal_beam_log_likelihood(
            math.hypot(self.params.range_noise, res))
        self.nominal_fit = math.exp(nominal)
        free = (self.map.occupancy == 0) & (self.field.distance >= self.params.inject_clearance)
        if not free.any():
            raise ConfigError(
                f"the map has no free cell {self.params.inject_clearance} m away from obstacles",
                key="map", fix="check the map (free cells must be white)",
            )
        self._free_rc = np.argwhere(free)
        n = int(self.params.n_particles)
        self.particles = np.zeros((n, 3))
        self.weights = np.full(n, 1.0 / n)
        self._estimate = np.zeros(3)
        self.w_slow = self.nominal_fit
        self.w_fast = self.nominal_fit
        self.last_fit = float("nan")
        self.n_updates = 0
        self.n_resamples = 0
        self.n_injected = 0
        self.initialised = False
        self._beam_subsets: dict[int, NDArray[np.int64]] = {}

    def set_field(self, field: LikelihoodField) -> None:
        """Localize against ``field`` from now on, keeping the particles (a map updated
        while the robot runs, e.g. an obstacle added to the lab); same frame expected."""
        self.field, self.map = field, field.map
        free = (self.map.occupancy == 0) & (field.distance >= self.params.inject_clearance)
        self._free_rc = np.argwhere(free)

    # ------------------------------------------------------------------ initialisation
    def _reset_stats(self) -> None:
        self.w_slow = self.nominal_fit
        self.w_fast = self.nominal_fit
        self.weights = np.full(self.params.n_particles, 1.0 / self.params.n_particles)
        self.initialised = True

    def init_gaussian(self, pose: NDArray[np.float64],
                      cov: NDArray[np.float64] | None = None) -> None:
        """Particles drawn from ``N(pose, cov)``; ``cov`` ``(3, 3)`` (m^2, rad^2), default
        ``diag(0.05^2, 0.05^2, 0.1^2)``."""
        pose = np.asarray(pose, dtype=np.float64)
        if pose.shape != (3,) or not np.all(np.isfinite(pose)):
            raise ValueError(f"pose: expected 3 finite numbers, got {pose}")
        cov = np.diag([0.05**2, 0.05**2, 0.1**2]) if cov is None else np.asarray(cov, float)
        if cov.shape != (3, 3):
            raise ValueError(f"cov: expected a (3, 3) matrix, got shape {cov.shape}")
        p = self.rng.multivariate_normal(pose, cov, size=self.params.n_particles,
                                         method="cholesky")
        p[:, 2] = wrap(p[:, 2])
        self.particles = p
        self._reset_stats()
        self._estimate = np.array([pose[0], pose[1], float(wrap(pose[2]))])

    def sample_free(self, n: int) -> NDArray[np.float64]:
        """``n`` poses uniform over the free cells (clearance ``inject_clearance``), uniform yaw."""
        rc = self._free_rc[self.rng.integers(0, len(self._free_rc), size=n)]
        jitter = self.rng.random((n, 2))
        xy = self.map.pixel_to_world(rc + jitter - 0.5)
        yaw = self.rng.uniform(-math.pi, math.pi, size=n)
        return np.column_stack([xy, yaw])

    def init_global(self) -> None:
        """Global localization: particles uniform over the free space, headings uniform."""
        self.particles = self.sample_free(self.params.n_particles)
        self._reset_stats()
        self._estimate = weighted_pose_mean(self.particles, self.weights)

    def _check_init(self) -> None:
        if not self.initialised:
            raise RuntimeError("initialise the filter first (init_gaussian or init_global)")

    # ------------------------------------------------------------------ the cycle
    def predict(self, odom_prev: NDArray[np.float64], odom_now: NDArray[np.float64],
                delta: NDArray[np.float64] | tuple[float, float, float] | None = None) -> None:
        """Move the particles by the odometry motion ``odom_prev -> odom_now`` (with noise).

        ``delta``: ``relative(odom_prev, odom_now)`` (3 numbers: an array or a tuple of
        floats) when the caller has computed it already (the tracker has, to decide whether
        to update; ~35 us saved per update).
        """
        self._check_init()
        self.particles = sample_odometry_motion(self.particles, odom_prev, odom_now,
                                                self.params.motion, self.rng)
        if delta is None:
            delta = relative(odom_prev, odom_now)
        self._estimate = compose(self._estimate, delta)

    def beam_subset(self, n_total: int) -> NDArray[np.int64]:
        """Indices of the ``n_beams`` beams used out of a scan of ``n_total`` (read-only;
        computed once per scan size, as every update asks for them)."""
        n_total = int(n_total)
        idx = self._beam_subsets.get(n_total)
        if idx is None:
            k = min(self.params.n_beams, n_total)
            idx = np.floor(np.arange(k) * (n_total / k)).astype(np.int64)
            idx.setflags(write=False)
            self._beam_subsets[n_total] = idx
        return idx

    def update(self, scan: ScanLike) -> bool:
        """Weight the particles by ``scan``, store the estimate and resample if needed.

        Returns False (and changes nothing) when none of the beams used has a return.
        """
        self._check_init()
        ranges = np.asarray(scan.ranges, dtype=np.float64)
        weights = np.empty_like(self.weights)
        p = self.params
        k_used, total, ess, estimate = _weigh(
            self.particles, self.weights, ranges, np.asarray(scan.angles, dtype=np.float64),
            self.beam_subset(len(ranges)), np.asarray(scan.sensor_offset, dtype=np.float64),
            self.field.log_table, self.field.geometry, p.estimate_radius ** 2,
            p.estimate_angle, self._MODE_STEPS, weights)
        if k_used == 0:
            return False
        self.weights = weights
        # Per-beam geometric mean of the predictive likelihood sum_i w_i p(z | x_i).
        fit = math.exp(total / k_used)
        self.last_fit = fit
        self.w_slow += p.alpha_slow * (fit - self.w_slow)
        self.w_fast += p.alpha_fast * (fit - self.w_fast)
        self.n_updates += 1
        self._estimate = estimate
        inject = self.injection_probability
        if inject > 0 or ess < p.resample_threshold * p.n_particles:
            self._resample(inject)
        return True

    @property
    def injection_probability(self) -> float:
        """Fraction of particles the next resampling replaces: ``max(0, 1 - w_fast/w_slow)``."""
        if self.params.alpha_slow == 0 or self.w_slow <= 0:
            return 0.0
        return max(0.0, 1.0 - self.w_fast / self.w_slow)

    def _resample(self, inject: float) -> None:
        n = self.params.n_particles
        u = self.rng.random()  # the draw of low_variance_resample
        new = np.empty((n, 3))
        if not _resample_into(self.weights, u, self.particles, new):
            new = self.particles[_low_variance_indices(self.weights, n, u)]
        if inject > 0:
            mask = self.rng.random(n) < inject
            m = int(mask.sum())
            if m:
                new[mask] = self.sample_free(m)
                self.n_injected += m
        self.particles = new
        self.weights = np.full(n, 1.0 / n)
        self.n_resamples += 1

    # ------------------------------------------------------------------ estimates
    def estimate(self) -> NDArray[np.float64]:
        """Pose estimate ``(3,)`` (x, y, yaw): the strongest mode at the last update, moved
        by the odometry since (see the module docstring)."""
        self._check_init()
        return self._estimate.copy()

    def covariance(self) -> NDArray[np.float64]:
        """Weighted covariance ``(3, 3)`` of all particles (m^2, rad^2; yaw about its mean)."""
        self._check_init()
        mean = weighted_pose_mean(self.particles, self.weights)
        d = self.particles - mean
        d[:, 2] = wrap(d[:, 2])
        w = self.weights / self.weights.sum()
        return (d * w[:, None]).T @ d

    def spread(self) -> tuple[float, float]:
        """``(position std (m), heading std (rad))`` of the particle cloud: the traces of
        :meth:`covariance` by one compiled kernel (equal within float rounding)."""
        self._check_init()
        pos, yaw = _spread(self.particles, self.weights)
        return float(pos), float(yaw)
