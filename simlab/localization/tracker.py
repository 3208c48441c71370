"""Plugging the particle filter into the physics: the tracker and the ``mcl`` pose source.

:class:`MCLTracker` is the scan callback of
:func:`simlab.physics.motion.execute_primitive` (``on_scan=tracker.on_scan``, 5 Hz of
simulated time). Like ROS AMCL it integrates the odometry at every scan but updates the
filter only once the odometry moved ``update_min_distance`` or turned
``update_min_angle`` since the last update (a robot at rest adds no information, and
repeating the same scan would make the filter overconfident); the first scan after the
initialisation always updates. Between updates the pose
is the last estimate carried forward by the odometry (AMCL's map -> odom correction).

Every update is logged with the scan's true pose, so the localization error against the
truth is available (:meth:`MCLTracker.log`, :meth:`MCLTracker.error_stats`).

:class:`MCLPoseSource` adapts the tracker to the pose-source protocol of the dataset
walkers (:mod:`simlab.data.walkers`), so ``simlab collect --pose-source mcl`` records
MCL poses; the factory is :func:`simlab.localization.sources.make_pose_source`.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from discretize.gridmap import OccupancyMap
from simlab.base.errors import ConfigError
from simlab.localization.filter import MCLParams, ParticleFilter, ScanLike
from simlab.localization.likelihood import LikelihoodField
from simlab.localization.motion import compose, relative, relative3, wrap


@dataclass(frozen=True)
class LocalizationLog:
    """One row per filter update: ``t`` (N,) s, ``truth`` and ``estimate`` (N, 3)
    (x, y, yaw), ``spread`` (N, 2) (position std m, heading std rad), ``fit`` (N,)
    per-beam likelihood, ``injected`` (N,) particles injected at that update."""

    t: NDArray[np.float64]
    truth: NDArray[np.float64]
    estimate: NDArray[np.float64]
    spread: NDArray[np.float64]
    fit: NDArray[np.float64]
    injected: NDArray[np.int64]

    @property
    def position_error(self) -> NDArray[np.float64]:
        """Distance (m) between estimate and truth at each update."""
        return np.hypot(*(self.estimate[:, :2] - self.truth[:, :2]).T)

    @property
    def heading_error(self) -> NDArray[np.float64]:
        """Absolute heading error (rad) at each update."""
        return np.abs(wrap(self.estimate[:, 2] - self.truth[:, 2]))


def error_summary(position_error: NDArray[np.float64], heading_error: NDArray[np.float64],
                  ) -> dict[str, float | int | None]:
    """Mean, median, 95th percentile and max of position (m) and heading (rad) errors."""
    pe = np.asarray(position_error, dtype=np.float64)
    he = np.asarray(heading_error, dtype=np.float64)
    if pe.size == 0:
        return {"n": 0}

    def q(v: NDArray[np.float64], p: float) -> float:
        return float(np.percentile(v, p))

    return {
        "n": int(pe.size),
        "position_mean_m": float(pe.mean()),
        "position_median_m": q(pe, 50),
        "position_p95_m": q(pe, 95),
        "position_max_m": float(pe.max()),
        "heading_mean_rad": float(he.mean()),
        "heading_median_rad": q(he, 50),
        "heading_p95_rad": q(he, 95),
        "heading_max_rad": float(he.max()),
    }


class MCLTracker:
    """A particle filter fed by the scans and odometry of a moving robot.

    Parameters
    ----------
    grid:
        The map (or a prebuilt :class:`LikelihoodField`).
    rng:
        The filter's Generator.
    params:
        :class:`MCLParams`.
    initial_pose:
        ``(3,)`` pose to track from (particles ``N(initial_pose, initial_cov)``); None for
        global localization.
    initial_cov:
        ``(3, 3)`` covariance of the initial cloud (default: that of
        :meth:`ParticleFilter.init_gaussian`).
    odometry:
        The odometry pose ``(3,)`` at the time of ``initial_pose`` (default: taken from
        the first scan callback).
    """

    def __init__(self, grid: OccupancyMap | LikelihoodField, rng: np.random.Generator,
                 params: MCLParams | None = None, *,
                 initial_pose: NDArray[np.float64] | None = None,
                 initial_cov: NDArray[np.float64] | None = None,
                 odometry: NDArray[np.float64] | None = None) -> None:
        self.filter = ParticleFilter(grid, params, rng)
        self.params = self.filter.params
        if initial_pose is None:
            self.filter.init_global()
        else:
            self.filter.init_gaussian(np.asarray(initial_pose, dtype=np.float64), initial_cov)
        self._odom_ref = None if odometry is None else np.asarray(odometry, dtype=np.float64)
        self._odom_last = self._odom_ref
        self._fresh = True  # the first scan always updates (as AMCL after initialisation)
        self._rows: list[tuple[Any, ...]] = []
        self.n_scans = 0

    # ------------------------------------------------------------------ feeding
    def on_scan(self, scan: ScanLike, odom: NDArray[np.float64]) -> None:
        """The ``on_scan(scan, odometry_pose)`` callback of ``execute_primitive``."""
        odom = np.asarray(odom, dtype=np.float64)
        self.n_scans += 1
        self._odom_last = odom
        if self._odom_ref is None:
            self._odom_ref = odom
        d = relative3(self._odom_ref.tolist(), odom.tolist())  # floats: ~10x cheaper
        p = self.params
        moved = math.hypot(d[0], d[1]) >= p.update_min_distance or abs(d[2]) >= p.update_min_angle
        if not (moved or self._fresh):
            return
        self.filter.predict(self._odom_ref, odom, d)
        self._odom_ref = odom
        self._fresh = False
        self._update(scan)

    def _update(self, scan: ScanLike) -> None:
        injected_before = self.filter.n_injected
        if not self.filter.update(scan):
            return
        truth = getattr(scan, "pose", None)
        truth = np.full(3, np.nan) if truth is None else np.asarray(truth, dtype=np.float64)
        self._rows.append((float(getattr(scan, "stamp", np.nan)), truth,
                           self.filter.estimate(), self.filter.spread(),
                           self.filter.last_fit, self.filter.n_injected - injected_before))

    # ------------------------------------------------------------------ reading
    def pose(self, odometry: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """Current pose estimate ``(3,)``: the filter's estimate moved by the odometry
        from the last update to ``odometry`` (default: the last odometry seen)."""
        est = self.filter.estimate()
        odom = self._odom_last if odometry is None else np.asarray(odometry, dtype=np.float64)
        if self._odom_ref is None or odom is None:
            return est
        return compose(est, relative(self._odom_ref, odom))

    def particles(self) -> NDArray[np.float64]:
        """Copy of the particles ``(N, 3)``."""
        return self.filter.particles.copy()

    def log(self) -> LocalizationLog:
        """Every update so far (see :class:`LocalizationLog`)."""
        n = len(self._rows)
        if n == 0:
            empty = np.zeros((0, 3))
            return LocalizationLog(np.zeros(0), empty, empty.copy(), np.zeros((0, 2)),
                                   np.zeros(0), np.zeros(0, dtype=np.int64))
        t, truth, est, spread, fit, inj = zip(*self._rows, strict=True)
        return LocalizationLog(np.array(t), np.array(truth), np.array(est), np.array(spread),
                               np.array(fit), np.array(inj, dtype=np.int64))

    def error_stats(self, after: float = 0.0) -> dict[str, float | int | None]:
        """Error summary (:func:`error_summary`) over the updates at ``t >= after`` (s)."""
        log = self.log()
        keep = log.t >= after
        return error_summary(log.position_error[keep], log.heading_error[keep])


# --------------------------------------------------------------------------------------
# The ``mcl`` pose source of the dataset walkers
# --------------------------------------------------------------------------------------


def _params_from_options(options: dict[str, Any]) -> MCLParams:
    known = {f.name for f in fields(MCLParams)} - {"sensor", "motion"}
    unknown = set(options) - known
    if unknown:
        raise ConfigError(
            f"unknown MCL option(s) {sorted(unknown)}", key="pose_source_options",
            fix=f"allowed: map, initial_std, {', '.join(sorted(known))}",
        )
    return replace(MCLParams(), **options)


class MCLPoseSource:
    """The ``mcl`` pose source for :mod:`simlab.data.walkers` (dataset collection).

    At every world reset (the start of a dataset part) the filter restarts around the
    world's true pose with standard deviation ``initial_std`` (m, m, rad): the robot
    starts each part from a known pose, as the thesis robot started AMCL from its known
    initial pose. Scans then drive it; the recorded poses are its estimates.
    """

    needs_scans = True

    def __init__(self, world: Any, map: str | os.PathLike[str] | None = None,
                 initial_std: tuple[float, float, float] = (0.02, 0.02, 0.05),
                 **options: Any) -> None:
        from simlab.localization.maps import load_map_for_arena

        self.params = _params_from_options(options)
        grid, _ = load_map_for_arena(map, world.arena)
        self.field = LikelihoodField(grid, self.params.sensor)
        self.initial_cov = np.diag(np.square(np.asarray(initial_std, dtype=np.float64)))
        self.tracker: MCLTracker | None = None
        self._before: NDArray[np.float64] | None = None
        #: beam indices the filter reads; the walker casts only these (None before reset)
        self.scan_beams: NDArray[np.int64] | None = None

    def reset(self, world: Any, rng: np.random.Generator) -> None:
        self.tracker = MCLTracker(self.field, rng, self.params, initial_pose=world.pose(),
                                  initial_cov=self.initial_cov, odometry=world.odometry())
        self.scan_beams = self.tracker.filter.beam_subset(world.lidar_spec.n_beams)
        self._before = self.tracker.pose()

    def on_scan(self, scan: Any, odom: NDArray[np.float64]) -> None:
        assert self.tracker is not None, "reset() first"
        self.tracker.on_scan(scan, odom)

    def poses(self, result: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        assert self.tracker is not None and self._before is not None, "reset() first"
        after = self.tracker.pose(result.odom_after)
        before, self._before = self._before, after
        return before, after

