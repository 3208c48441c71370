"""What runs inside a collection worker: one part of one epsilon = 1 random walk.

A *part* is the unit of work, of storage and of resumption. Part ``p`` of worker
``w`` is a pure function of its :class:`PartJob`:

* the simulator is rebuilt from scratch at the part's start pose
  (``world.reset(pose=...)``: a full deterministic rebuild, robot at rest) — the truth
  pose after the last transition of part ``p - 1``, or the arena's start pose for
  ``p = 0``;
* its random streams come from ``np.random.SeedSequence(seed, spawn_key=(w, p))``
  spawned into (actions, motion noise, pose source);
* the worker clock continues from the previous part's end time ``t0``.

So an uninterrupted run and a run resumed after a crash compute every part from the
same inputs and produce the same rows, bit for bit, whichever process (or Ray node)
runs it. The price: the robot is re-placed at rest at each part boundary, and an
odometry pose source restarts from the truth pose there (its drift is bounded by a
part's length — see ``part_size`` in :func:`simlab.data.collect.collect`).

Two simulators implement the :class:`Walker` protocol:

* ``physics`` — :class:`PhysicsWalker`: the PyBullet world and the 16 motion
  primitives of :mod:`simlab.physics.motion` (the real thing);
* ``kinematic`` — :class:`KinematicWalker`: a physics-free point robot with noisy
  straight moves inside the arena's free area, thousands of times faster; for dry runs
  of the pipeline and for tests of the dataset machinery. Not a model of the robot.

The states ``s``/``s_next`` are not computed here: the driver discretizes the poses of
a whole part at once (the walk itself is random, so it never needs the state).
"""

from __future__ import annotations

import math
import resource
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from simlab.base.actions import HEADINGS, SIMLAB16
from simlab.base.errors import ConfigError
from simlab.localization.sources import (  # noqa: F401 (the names stay importable here)
    POSE_SOURCES,
    SCANLESS_POSE_SOURCES,
    OdometryPose,
    PoseSource,
    TruthPose,
    check_pose_source_name,
    make_pose_source,
)

#: Number of motion primitives (= :data:`simlab.data.schema.N_ACTIONS`), taken from the action
#: set so that a worker process does not import the schema's PyArrow (0.1 s).
N_ACTIONS = SIMLAB16.n_actions

SIMULATORS = ("physics", "kinematic")


# Pose sources (what the dataset records as x, y, yaw; and so what s and s' are) are
# defined in :mod:`simlab.localization.sources`; the names stay importable from here.


def check_pose_source(name: str, simulator: str) -> None:
    """Raise ConfigError early (in the driver) for an unusable pose source."""
    check_pose_source_name(name)
    if simulator == "kinematic" and name not in SCANLESS_POSE_SOURCES:
        raise ConfigError(
            f"the kinematic simulator has no LIDAR, so no {name!r} pose source",
            key="pose_source", fix="use truth or odometry, or --simulator physics",
        )


# --------------------------------------------------------------------------------------
# Walkers
# --------------------------------------------------------------------------------------


#: Label grids of this process by the partition's content hash (see :func:`point_state_of`).
_LABEL_GRIDS: dict[str, Any] = {}


def point_state_of(discretizer: Any) -> Callable[[float, float], int]:
    """``state(x, y) -> int``: the state of one position (m) under ``discretizer``.

    A :class:`~discretize.voronoi.Discretizer` answers through a
    :class:`~discretize.label_grid.LabelGrid` (a dictionary lookup for most points, its own
    nearest-centre search near a boundary: the same states, ~10x cheaper at the 10 Hz
    control ticks of an ``until_state_change`` drive). Any other object with ``state_of(xy
    (N, 2)) -> (N,)`` is asked directly, one point at a time.
    """
    from discretize.label_grid import LabelGrid
    from discretize.voronoi import Discretizer

    if isinstance(discretizer, Discretizer):
        # Kept per partition: a calibration walks many candidates over the same states,
        # each with a walker of its own, and the cells labelled by one serve the next.
        key = discretizer.content_hash()
        grid = _LABEL_GRIDS.get(key)
        if grid is None:
            if len(_LABEL_GRIDS) >= 4:
                _LABEL_GRIDS.clear()
            grid = _LABEL_GRIDS[key] = LabelGrid.of(discretizer)
        return grid.state
    state_of = discretizer.state_of

    def state(x: float, y: float) -> int:
        return int(np.asarray(state_of(np.array([[x, y]])))[0])

    return state


@dataclass(frozen=True)
class StepOutcome:
    """One primitive: blocked flag, stepped duration (s), truth and recorded poses (3,)."""

    blocked: bool
    duration: float
    truth_before: NDArray[np.float64]
    truth_after: NDArray[np.float64]
    pose_before: NDArray[np.float64]
    pose_after: NDArray[np.float64]


class Walker(Protocol):
    """A simulator able to run motion primitives from a deterministic start."""

    decision_latency: float

    def reset(self, pose: NDArray[np.float64] | None, source_rng: np.random.Generator) -> None:
        """Rebuild at ``pose`` (truth, (3,)) or at the arena start, robot at rest."""

    def step(self, action: int, rng: np.random.Generator) -> StepOutcome:
        """Run primitive ``action`` (0-15) with motion noise from ``rng``."""

    def close(self) -> None: ...


class PhysicsWalker:
    """The PyBullet world running :func:`simlab.physics.motion.execute_primitive`."""

    def __init__(self, arena: Any, params: Any, pose_source: str,
                 pose_source_options: dict[str, Any], discretizer: Any = None,
                 physics_hz: float | None = None) -> None:
        from simlab.physics.driver import DecisionDriver
        from simlab.physics.motion import noisy_pose
        from simlab.physics.world import World

        self._noisy_pose = noisy_pose
        self.params = params
        self._state_of: Callable[[Any], int] | None = None
        self._point_state: Callable[[float, float], int] | None = None
        if discretizer is not None:
            point_state = self._point_state = point_state_of(discretizer)
            self._state_of = lambda xy: point_state(float(xy[0]), float(xy[1]))
        self._pose_noise = bool(params.pose_noise_xy or params.pose_noise_yaw)
        self._localized = (self._pose_noise and self._state_of is not None
                           and pose_source == "truth"
                           and getattr(params, "mode", "fixed") == "until_state_change")
        self._noise_rng: np.random.Generator | None = None
        self._last_pose: NDArray[np.float64] | None = None
        self._error = np.zeros(3)
        self.decision_latency = float(params.decision_latency)
        self.world = World(arena, gui=False, physics_hz=physics_hz)
        try:
            self.source = make_pose_source(pose_source, self.world, pose_source_options)
        except BaseException:
            self.world.close()
            raise
        self._on_scan: Callable[..., None] | None = (
            self.source.on_scan if self.source.needs_scans else None
        )
        # the action is the primitive (0-15); the recorded poses come from the pose source
        self.driver = DecisionDriver(self.world, params, on_scan=self._on_scan,
                                     watch_state=self._state_of)

    def reset(self, pose: NDArray[np.float64] | None, source_rng: np.random.Generator) -> None:
        self.world.reset(pose=None if pose is None else np.asarray(pose, dtype=np.float64))
        self.source.reset(self.world, source_rng)
        self.driver.scan_beams = getattr(self.source, "scan_beams", None)
        self._noise_rng = source_rng
        self._last_pose = None

    def place(self, pose: NDArray[np.float64], source_rng: np.random.Generator) -> None:
        """Carry the robot to ``pose`` (truth, (3,)) in the running world and put it down
        at rest, keeping every body added since the last :meth:`reset` (an episode's
        restart: the robot is set down at a start and its localization restarts there, as
        AMCL is given the pose it was put down at). Unlike :meth:`reset` no time or
        contact state is rebuilt; the next reading, and a persistent localization error
        (``pose_noise_persistence``), are drawn afresh."""
        self.world.set_pose(np.asarray(pose, dtype=np.float64))
        self.source.reset(self.world, source_rng)
        self.driver.scan_beams = getattr(self.source, "scan_beams", None)
        self._noise_rng = source_rng
        self._last_pose = None

    def hold(self) -> tuple[Any, ...]:
        """What a move changes of the robot, for :meth:`undo`: its true pose, the reading
        the next move starts from and its localization error (the truth pose source's whole
        state: odometry and a particle filter's particles are not held)."""
        last = None if self._last_pose is None else self._last_pose.copy()
        return np.asarray(self.world.pose(), dtype=np.float64).copy(), last, self._error.copy()

    def undo(self, held: tuple[Any, ...]) -> None:
        """Take a move back: the robot set down at rest where :meth:`hold` found it, its
        reading and localization error as they were (the noise streams go on)."""
        pose, last, error = held
        self.world.set_pose(pose)
        self._last_pose = None if last is None else last.copy()
        self._error = error.copy()

    def believed_pose(self) -> NDArray[np.float64]:
        """The pose (3,) the robot believes it is at now, between two primitives: the
        reading the next transition starts from (drawn now if none is held, from the
        pose-source Generator, in the order :meth:`step` would draw it), else the pose
        source's estimate."""
        if self._pose_noise:
            assert self._noise_rng is not None, "reset() first"
            if self._last_pose is None:
                base = (self.world.pose() if self._localized
                        else self._source_now())
                self._last_pose = self._first_reading(np.asarray(base, dtype=np.float64))
            return self._last_pose
        return self._source_now()

    def _source_now(self) -> NDArray[np.float64]:
        tracker = getattr(self.source, "tracker", None)
        if tracker is not None:  # the particle filter's estimate
            return np.asarray(tracker.pose(None), dtype=np.float64)
        if isinstance(self.source, OdometryPose):
            return np.asarray(self.world.odometry(), dtype=np.float64)
        return np.asarray(self.world.pose(), dtype=np.float64)

    def step(self, action: int, rng: np.random.Generator) -> StepOutcome:
        if self._localized:
            return self._localized_step(action, rng)
        res = self.driver.execute(action, rng).result
        before, after = self.source.poses(res)
        if self._pose_noise:
            # One noisy reading per pose: a transition starts where the previous one's
            # reading ended (as on the real robot); drawn from the pose-source Generator.
            # A part starts with a fresh reading (parts are computed on their own).
            assert self._noise_rng is not None
            if self._last_pose is None:
                self._last_pose = self._first_reading(np.asarray(before, dtype=np.float64))
            before = self._last_pose
            after = np.asarray(after, dtype=np.float64)
            if self.params.pose_noise_persistence:
                after = after + self._next_error()
                after[2] = float(np.arctan2(np.sin(after[2]), np.cos(after[2])))
            else:
                after = self._noisy_pose(after, self.params, self._noise_rng)
            self._last_pose = after
        return self._outcome(res, before, after)

    def _first_reading(self, pose: NDArray[np.float64]) -> NDArray[np.float64]:
        """A part's first reading of ``pose`` (3,): the error drawn from its stationary
        spread (parts are computed on their own)."""
        assert self._noise_rng is not None
        reading = self._noisy_pose(pose, self.params, self._noise_rng)
        if self.params.pose_noise_persistence:
            self._error = reading - pose
            self._error[2] = float(np.arctan2(np.sin(self._error[2]), np.cos(self._error[2])))
        return reading

    def _next_error(self) -> NDArray[np.float64]:
        """The localization error (3,) of the next decision: drawn afresh, or with
        ``pose_noise_persistence`` rho the AR(1) step ``rho e + sqrt(1 - rho^2) sigma z``
        from the last one (one draw of three normals either way, so the streams agree)."""
        assert self._noise_rng is not None
        fresh = self._noisy_pose(np.zeros(3), self.params, self._noise_rng)
        rho = float(self.params.pose_noise_persistence)
        if rho:
            fresh = rho * self._error + math.sqrt(1.0 - rho * rho) * fresh
            self._error = fresh
        return fresh

    def _localized_step(self, action: int, rng: np.random.Generator) -> StepOutcome:
        """A robot whose states come from its localization drives until its *localized*
        state changes (truth pose source with pose noise, drive-until-state-change mode).

        Decision: the localization error of each decision (:meth:`_next_error`: drawn anew,
        or drifting from the last one with ``pose_noise_persistence``) is held during the
        move; the move ends when the state of (true position + that error) leaves its
        value at the start, and that reading is the recorded end pose. The recorded start
        pose stays the previous move's end reading (a transition starts where the last
        one's reading ended), so a jump of the estimate between two decisions shows as
        noise of the recorded ``s``, as in a real robot's log. The readings are drawn in
        the same order as the other walks' (a part's first reading, then each end reading).
        """
        assert self._noise_rng is not None and self._point_state is not None
        if self._last_pose is None:
            self._last_pose = self._first_reading(self.world.pose())
        before = self._last_pose
        offset = self._next_error()
        point_state, ox, oy = self._point_state, float(offset[0]), float(offset[1])
        self.driver.watch_state = lambda xy: point_state(float(xy[0]) + ox, float(xy[1]) + oy)
        res = self.driver.execute(action, rng).result
        after = np.asarray(res.pose_after, dtype=np.float64) + offset
        after[2] = float(np.arctan2(np.sin(after[2]), np.cos(after[2])))
        self._last_pose = after
        return self._outcome(res, before, after)

    def _outcome(self, res: Any, before: Any, after: Any) -> StepOutcome:
        return StepOutcome(
            blocked=bool(res.blocked),
            duration=float(res.duration),
            truth_before=np.asarray(res.pose_before, dtype=np.float64),
            truth_after=np.asarray(res.pose_after, dtype=np.float64),
            pose_before=np.asarray(before, dtype=np.float64),
            pose_after=np.asarray(after, dtype=np.float64),
        )

    def close(self) -> None:
        self.world.close()


@dataclass(frozen=True)
class KinematicParams:
    """Parameters of the physics-free point robot (:class:`KinematicWalker`).

    Speeds and drive time follow the physics primitives' defaults (0.10 / 0.22 m/s for
    0.5 s); the noise is invented (the kinematic walker is a stand-in, not a model).

    Attributes:
        slow_speed: m/s of actions 0-7.
        fast_speed: m/s of actions 8-15.
        drive_time: s of straight driving per primitive.
        turn_rate: rad/s of the in-place rotation to the heading.
        distance_noise: relative standard deviation of the distance driven.
        heading_noise: standard deviation (rad) of the heading actually driven.
        clearance: m; the "detector" blocks a move whose intended end point lies closer
            than this to a wall or obstacle.
        radius: m; the robot's centre never comes closer than this to the area's edge.
        decision_latency: s of idle time between primitives (added to the clock).
    """

    slow_speed: float = 0.10
    fast_speed: float = 0.22
    drive_time: float = 0.5
    turn_rate: float = 2.0
    distance_noise: float = 0.15
    heading_noise: float = 0.08
    clearance: float = 0.12
    radius: float = 0.09
    decision_latency: float = 3.0

    def __post_init__(self) -> None:
        from simlab.base import validation

        for name in ("slow_speed", "fast_speed", "drive_time", "turn_rate"):
            validation.positive(getattr(self, name), f"params.{name}")
        for name in ("distance_noise", "heading_noise", "clearance", "radius",
                     "decision_latency"):
            validation.positive(getattr(self, name), f"params.{name}", allow_zero=True)


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


class KinematicWalker:
    """A point robot in the arena's free area; no physics, no LIDAR.

    A primitive turns in place to the action's heading (``turn_rate``), then, unless
    the end point would lie within ``clearance`` of a wall or obstacle ("blocked"),
    drives ``speed * drive_time`` metres with relative noise ``distance_noise`` along
    the heading perturbed by ``heading_noise``; the robot stops at ``radius`` from the
    arena edge. Odometry integrates the commanded motion (exact heading and distance),
    so it drifts from the truth.
    """

    def __init__(self, arena: Any, params: KinematicParams, pose_source: str = "truth") -> None:
        if pose_source not in SCANLESS_POSE_SOURCES:
            raise ConfigError(
                f"the kinematic simulator has no LIDAR, so no {pose_source!r} pose source",
                key="pose_source", fix="use truth or odometry, or --simulator physics",
            )
        self.arena = arena
        self.params = params
        self.pose_source = pose_source
        self.decision_latency = float(params.decision_latency)
        self._truth = np.asarray(arena.start, dtype=np.float64).copy()
        self._odom = self._truth.copy()

    def reset(self, pose: NDArray[np.float64] | None, source_rng: np.random.Generator) -> None:
        del source_rng
        start = self.arena.start if pose is None else pose
        self._truth = np.asarray(start, dtype=np.float64).copy()
        self._odom = self._truth.copy()

    def step(self, action: int, rng: np.random.Generator) -> StepOutcome:
        p = self.params
        heading = float(HEADINGS[action % 8])
        speed = p.fast_speed if action >= 8 else p.slow_speed
        distance = speed * p.drive_time
        # Both noise draws happen on every step so the stream does not depend on blocking.
        heading_true = _wrap(heading + p.heading_noise * rng.standard_normal())
        distance_true = max(0.0, distance * (1.0 + p.distance_noise * rng.standard_normal()))
        truth_before, odom_before = self._truth.copy(), self._odom.copy()
        turn_time = abs(_wrap(heading - float(truth_before[2]))) / p.turn_rate
        probe = truth_before[:2] + (distance + p.clearance) * np.array(
            [math.cos(heading), math.sin(heading)]
        )
        blocked = bool(self.arena.occupied(probe))
        truth_after, odom_after = truth_before.copy(), odom_before.copy()
        truth_after[2], odom_after[2] = heading_true, heading
        if blocked:
            duration = turn_time
        else:
            duration = turn_time + p.drive_time
            x0, y0, x1, y1 = self.arena.bounds
            xy = truth_before[:2] + distance_true * np.array(
                [math.cos(heading_true), math.sin(heading_true)]
            )
            truth_after[0] = min(max(xy[0], x0 + p.radius), x1 - p.radius)
            truth_after[1] = min(max(xy[1], y0 + p.radius), y1 - p.radius)
            odom_after[:2] += distance * np.array([math.cos(heading), math.sin(heading)])
        self._truth, self._odom = truth_after, odom_after
        if self.pose_source == "truth":
            return StepOutcome(blocked, duration, truth_before, truth_after,
                               truth_before, truth_after)
        return StepOutcome(blocked, duration, truth_before, truth_after,
                           odom_before, odom_after)

    def close(self) -> None:
        pass


# --------------------------------------------------------------------------------------
# The part job
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class WalkSpec:
    """Everything a worker needs to rebuild its simulator (picklable, hashable ``key``).

    Attributes:
        key: identifies the simulator configuration (cache key in a worker process).
        simulator: ``"physics"`` or ``"kinematic"``.
        arena: the :class:`~simlab.physics.arena.ArenaConfig`.
        params: ``PrimitiveParams`` (physics) or :class:`KinematicParams`.
        pose_source: ``truth``, ``odometry`` or ``mcl``.
        pose_source_options: keyword arguments of the pose-source factory.
        discretizer: the states' discretizer, given to the primitives when they need
            ``state_of`` (``mode = "until_state_change"``); None otherwise.
        primitives: the primitives the walk draws from, uniformly; the recorded action
            ``a`` is the index into this tuple (default: all 16, so ``a`` is the
            primitive). A real robot's 8 actions walk with their 8 primitives
            (:meth:`simlab.base.actions.ActionSet.primitives`).
        physics_hz: the physics world's rate (Hz; None: the default rate).
    """

    key: str
    simulator: str
    arena: Any
    params: Any
    pose_source: str = "truth"
    pose_source_options: dict[str, Any] = field(default_factory=dict, hash=False)
    discretizer: Any = field(default=None, compare=False, hash=False)
    primitives: tuple[int, ...] = tuple(range(N_ACTIONS))
    physics_hz: float | None = None


def build_walker(spec: WalkSpec) -> Walker:
    """Instantiate the walker of ``spec`` (a PyBullet world for ``physics``)."""
    if spec.simulator == "physics":
        return PhysicsWalker(spec.arena, spec.params, spec.pose_source, spec.pose_source_options,
                             spec.discretizer, spec.physics_hz)
    if spec.simulator == "kinematic":
        return KinematicWalker(spec.arena, spec.params, spec.pose_source)
    raise ConfigError(f"unknown simulator {spec.simulator!r}", key="simulator",
                      fix=f"choose one of {', '.join(SIMULATORS)}")


class WalkerCache:
    """Walkers kept alive between parts in one process (one world per configuration).

    At most ``size`` walkers are kept: the one used longest ago is closed to make room
    (a calibration's worker process sees a new configuration with every candidate, each
    world a few tens of MB). A part's rows do not depend on whether its walker was kept
    or built anew: every part resets the world (:meth:`PhysicsWalker.reset`)."""

    def __init__(self, size: int = 8) -> None:
        self._walkers: dict[str, Walker] = {}
        self.size = max(1, int(size))

    def get(self, spec: WalkSpec) -> Walker:
        walker = self._walkers.pop(spec.key, None)
        if walker is None:
            while len(self._walkers) >= self.size:
                oldest = next(iter(self._walkers))
                self._walkers.pop(oldest).close()
            walker = build_walker(spec)
        self._walkers[spec.key] = walker  # the most recently used last
        return walker

    def close(self) -> None:
        for walker in self._walkers.values():
            walker.close()
        self._walkers.clear()

    def __enter__(self) -> WalkerCache:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


#: The cache of a worker process (process pool or Ray worker); lives until it exits.
_PROCESS_CACHE = WalkerCache()


@dataclass(frozen=True)
class PartJob:
    """One part of one worker's walk.

    Attributes:
        spec: the simulator to use.
        seed: the collection's root seed.
        worker: worker index w.
        part: part index p within the worker.
        t0: simulated seconds on the worker clock when the part starts.
        pose0: truth pose (3,) to start from, or None for the arena start pose.
        part_size: maximum number of transitions in a part.
        remaining: transitions the worker still owes (``--transitions`` budget), or None.
        t_budget: the worker's simulated-seconds budget (``--hours``), or None. A
            primitive is started only while the clock is below it.
    """

    spec: WalkSpec
    seed: int
    worker: int
    part: int
    t0: float
    pose0: tuple[float, float, float] | None
    part_size: int
    remaining: int | None = None
    t_budget: float | None = None


@dataclass(frozen=True)
class PartResult:
    """What a worker sends back: the part's columns (without ``s``, ``s_next``) and its end.

    ``columns`` maps column names of :func:`simlab.data.schema.transition_schema` to
    numpy arrays of equal length; the truth-pose columns (``x_true`` ...) are always
    included (the driver keeps them only when the pose source is not ``truth``).
    ``t_end`` and ``pose_end`` (truth) seed the next part; ``final`` says the worker's
    budget is spent. ``peak_rss_mb`` is the worker process's peak resident memory,
    ``cpu_seconds`` the CPU time the part took (user + system of this process).
    """

    worker: int
    part: int
    columns: dict[str, NDArray[Any]]
    t_end: float
    pose_end: tuple[float, float, float]
    final: bool
    wall_seconds: float
    peak_rss_mb: float
    cpu_seconds: float = 0.0

    @property
    def rows(self) -> int:
        return int(self.columns["a"].shape[0])


def part_generators(seed: int, worker: int, part: int) -> tuple[np.random.Generator, ...]:
    """(actions, motion, pose source) Generators of part ``part`` of worker ``worker``."""
    children = np.random.SeedSequence(seed, spawn_key=(worker, part)).spawn(3)
    return tuple(np.random.default_rng(c) for c in children)


def peak_rss_mb() -> float:
    """Peak resident set size of this process in MiB (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run_part(job: PartJob, cache: WalkerCache | None = None) -> PartResult:
    """Run one part of an epsilon = 1 random walk (uniform actions over the walk's
    primitives, ``job.spec.primitives``; all 16 by default).

    Deterministic given ``job``: see the module docstring. ``cache`` keeps simulators
    alive between calls (default: this process's cache).
    """
    start_wall = time.perf_counter()
    start_cpu = time.process_time()
    walker = (cache if cache is not None else _PROCESS_CACHE).get(job.spec)
    actions_rng, motion_rng, source_rng = part_generators(job.seed, job.worker, job.part)
    walker.reset(None if job.pose0 is None else np.asarray(job.pose0, dtype=np.float64),
                 source_rng)
    n_max = job.part_size if job.remaining is None else min(job.part_size, job.remaining)
    primitives = job.spec.primitives
    actions = actions_rng.integers(0, len(primitives), size=n_max)
    t_start = np.empty(n_max)
    duration = np.empty(n_max)
    blocked = np.empty(n_max, dtype=bool)
    pose = np.empty((n_max, 6))
    truth = np.empty((n_max, 6))
    t = float(job.t0)
    truth_end = None if job.pose0 is None else np.asarray(job.pose0, dtype=np.float64)
    n = 0
    for i in range(n_max):
        if job.t_budget is not None and t >= job.t_budget:
            break
        out = walker.step(primitives[int(actions[i])], motion_rng)
        t_start[i] = t
        duration[i] = out.duration
        blocked[i] = out.blocked
        pose[i, :3], pose[i, 3:] = out.pose_before, out.pose_after
        truth[i, :3], truth[i, 3:] = out.truth_before, out.truth_after
        t = t + out.duration + walker.decision_latency
        truth_end = out.truth_after
        n = i + 1
    if truth_end is None:  # the driver never schedules a part with no transition left
        raise ValueError(f"part {job.part} of worker {job.worker} has nothing to do")
    final = (job.remaining is not None and n >= job.remaining) or (
        job.t_budget is not None and t >= job.t_budget
    )
    columns: dict[str, NDArray[Any]] = {
        "t": t_start[:n].copy(),
        "duration": duration[:n].copy(),
        "a": actions[:n].astype(np.int32),
        "x": pose[:n, 0].copy(), "y": pose[:n, 1].copy(), "yaw": pose[:n, 2].copy(),
        "x_next": pose[:n, 3].copy(), "y_next": pose[:n, 4].copy(),
        "yaw_next": pose[:n, 5].copy(),
        "blocked": blocked[:n].copy(),
        "x_true": truth[:n, 0].copy(), "y_true": truth[:n, 1].copy(),
        "yaw_true": truth[:n, 2].copy(), "x_next_true": truth[:n, 3].copy(),
        "y_next_true": truth[:n, 4].copy(), "yaw_next_true": truth[:n, 5].copy(),
    }
    return PartResult(
        worker=job.worker,
        part=job.part,
        columns=columns,
        t_end=t,
        pose_end=(float(truth_end[0]), float(truth_end[1]), float(truth_end[2])),
        final=bool(final),
        wall_seconds=time.perf_counter() - start_wall,
        peak_rss_mb=peak_rss_mb(),
        cpu_seconds=time.process_time() - start_cpu,
    )
