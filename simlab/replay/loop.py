"""One replay run in one world: the decision loop, its recorder and its outcome.

The loop (see :mod:`simlab.replay.replay` for what the robot does and why) is the
physics' :class:`~simlab.physics.driver.DecisionDriver` with the replay's callbacks:
:class:`Chooser` (greedy / random / epsilon choice, blocked retries, loop watchdog) and
:class:`Recorder` (one ``record(...)`` per decision; the columns become the arrays of a
:class:`ReplayLog` at the end). Goal switching, the return to the start pose, video
frames and the progress bar stay here.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from simlab.replay.policy import escape_action, greedy_action, recurs

__all__ = ["FRAME_PARTICLES", "Chooser", "Recorder", "ReplayLog", "RunOutcome", "RunSpec",
           "drive_to_pose", "run"]

#: Particles stored per video frame (a subsample of the filter's).
FRAME_PARTICLES = 150


@dataclass(frozen=True)
class ReplayLog:
    """One row per transition (arrays of length n).

    ``t`` robot time (s) when the primitive starts; ``duration`` its stepped time (s);
    ``s``, ``a``, ``s_next`` believed states and action; ``goal`` goal index during the
    transition; ``reward`` 1 if ``s_next`` lies in the goal; ``blocked``; ``truth_before``
    / ``truth_after`` and ``est_before`` / ``est_after`` ``(n, 3)`` true and pose-source
    poses; ``odom_after`` ``(n, 3)`` wheel odometry; ``s_true_next`` the state of the true
    pose after the transition. ``latency`` (s) idle time per decision.
    """

    t: NDArray[np.float64]
    duration: NDArray[np.float64]
    s: NDArray[np.int64]
    a: NDArray[np.int64]
    s_next: NDArray[np.int64]
    goal: NDArray[np.int64]
    reward: NDArray[np.int64]
    blocked: NDArray[np.bool_]
    truth_before: NDArray[np.float64]
    truth_after: NDArray[np.float64]
    est_before: NDArray[np.float64]
    est_after: NDArray[np.float64]
    odom_after: NDArray[np.float64]
    s_true_next: NDArray[np.int64]
    latency: float

    @property
    def n(self) -> int:
        return int(self.t.shape[0])

    @property
    def t_end(self) -> NDArray[np.float64]:
        """Robot time (s) at the end of each transition (after the decision latency)."""
        return self.t + self.duration + self.latency

    @property
    def reward_times(self) -> NDArray[np.float64]:
        """Robot times (s) at which rewards were earned (end of the rewarded transitions)."""
        return self.t_end[self.reward > 0]


@dataclass(frozen=True)
class RunOutcome:
    """One replay run in one world (the main run or the random baseline)."""

    log: ReplayLog
    robot_seconds: float
    stepped_seconds: float
    wall_seconds: float
    blocked_retries: int
    escapes: int
    returns_to_start: int
    mcl_log: Any = None
    frames: list[Any] = field(default_factory=list)


@dataclass(frozen=True)
class RunSpec:
    """Everything one run needs (built by :func:`simlab.replay.replay.replay`)."""

    arena: Any
    discretizer: Any
    goal_masks: NDArray[np.bool_]
    Q: NDArray[np.float64] | None
    policy: str
    pose_source: str
    budget: float
    params: Any
    mcl_field: Any
    mcl_params: Any
    return_to_start: bool
    retry_blocked: bool
    escape_radius: float
    epsilon: float
    frame_stride: int
    primitives: NDArray[np.int64] = field(default_factory=lambda: np.arange(16))
    """simlab primitive executed by each action of the action set, ``(A,)``."""
    valid: NDArray[np.bool_] | None = None
    """``(G, S, A)`` actions the greedy policy may choose (None: all)."""
    remote_mcl: bool = False
    """Run the ``mcl`` particle filter in a process of its own (``parallel``)."""
    physics_hz: float | None = None
    """The physics rate (Hz; None: the default)."""


# --------------------------------------------------------------------------------------
# Callbacks of the decision driver
# --------------------------------------------------------------------------------------


class Chooser:
    """The replay's decision rule and its memory: the current ``goal``, the actions
    refused at this pose (``excluded``), the decisions of this goal episode (``history``,
    for the loop watchdog), and the counts of blocked retries and escapes."""

    def __init__(self, spec: RunSpec, rng: np.random.Generator, goal: int) -> None:
        self.spec = spec
        self.rng = rng
        self.goal = goal
        self.n_actions = len(spec.primitives)
        self.excluded = np.zeros(self.n_actions, dtype=bool)
        self.history: list[tuple[float, float, int]] = []
        self.retries = 0
        self.escapes = 0

    def __call__(self, est: NDArray[np.float64], s: int | None) -> int:
        spec, rng = self.spec, self.rng
        if spec.policy == "random" or (spec.epsilon > 0 and rng.random() < spec.epsilon):
            a = int(rng.integers(0, self.n_actions))
        else:
            allowed = None if spec.valid is None else spec.valid[self.goal, s]
            a = greedy_action(spec.Q[self.goal, s], rng,  # type: ignore[index]
                              self.excluded if spec.retry_blocked else None, valid=allowed)
            self.retries += int(self.excluded.any())
            if spec.escape_radius > 0 and recurs(self.history, est, a, spec.escape_radius):
                a = escape_action(a, allowed, self.n_actions, rng)
                self.escapes += 1
        self.history.append((est[0], est[1], a))
        return a

    def after(self, action: int, blocked: bool) -> None:
        """A refused action stays excluded at this pose; any move clears the exclusions."""
        if blocked:
            self.excluded[action] = True
        else:
            self.excluded[:] = False


class Recorder:
    """The columns of the replay log: one :meth:`record` per decision, arrays at the end."""

    #: column -> (dtype, width of a pose column or None)
    COLUMNS: ClassVar[dict[str, tuple[Any, int | None]]] = {
        "t": (np.float64, None), "duration": (np.float64, None), "s": (np.int64, None),
        "a": (np.int64, None), "s_next": (np.int64, None), "goal": (np.int64, None),
        "reward": (np.int64, None), "blocked": (bool, None), "truth_before": (np.float64, 3),
        "truth_after": (np.float64, 3), "est_before": (np.float64, 3),
        "est_after": (np.float64, 3), "odom_after": (np.float64, 3),
        "s_true_next": (np.int64, None),
    }

    def __init__(self) -> None:
        self._rows: dict[str, list[Any]] = {k: [] for k in self.COLUMNS}

    def __len__(self) -> int:
        return len(self._rows["t"])

    def record(self, t: float, step: Any, goal: int, reward: int, s_true_next: int) -> None:
        """One decision: robot time ``t`` (s) at its start, the driver's
        :class:`~simlab.physics.driver.DecisionStep`, the goal, the reward, the true
        state reached."""
        res = step.result
        values = {"t": t, "duration": res.duration, "s": step.state_before, "a": step.action,
                  "s_next": step.state_after, "goal": goal, "reward": reward,
                  "blocked": bool(res.blocked), "truth_before": step.truth_before,
                  "truth_after": res.pose_after, "est_before": step.pose_before,
                  "est_after": step.pose_after, "odom_after": res.odom_after,
                  "s_true_next": s_true_next}
        for key, value in values.items():
            self._rows[key].append(value)

    def log(self, latency: float) -> ReplayLog:
        """The recorded columns as a :class:`ReplayLog` (``latency`` s per decision)."""
        arrays: dict[str, NDArray[Any]] = {}
        for name, (dtype, width) in self.COLUMNS.items():
            values = self._rows[name]
            if not values:
                arrays[name] = np.zeros((0, width) if width else 0, dtype=dtype)
            else:
                arrays[name] = np.asarray(values, dtype=dtype)
        return ReplayLog(**arrays, latency=latency)


# --------------------------------------------------------------------------------------
# Stepping outside primitives (the return to the start pose)
# --------------------------------------------------------------------------------------


def drive_to_pose(world: Any, target: NDArray[np.float64],
                  pose_fn: Callable[[], NDArray[np.float64]], rng: np.random.Generator,
                  on_scan: Callable[[Any, NDArray[np.float64]], None] | None = None, *,
                  scan_beams: NDArray[np.int64] | None = None, speed: float = 0.11,
                  position_tolerance: float = 0.03, heading_tolerance: float = 0.05,
                  timeout: float = 60.0) -> float:
    """Drive back to ``target`` (x, y, yaw) steering by ``pose_fn``: turn to face it, drive
    straight (proportional heading hold), turn to its yaw. No obstacle check (the table
    is convex). Returns the stepped seconds; gives up after ``timeout`` s."""
    from simlab.localization.motion import wrap
    from simlab.physics.motion import ScanStepper

    t0 = world.time
    stepper = ScanStepper(world, rng, on_scan, scan_beams)
    drive = world.drive
    w_max = world.robot_spec.w_max
    dt = 0.1
    target = np.asarray(target, dtype=np.float64)

    def turn_to(heading_of: Callable[[NDArray[np.float64]], float]) -> None:
        while world.time - t0 < timeout:
            p = pose_fn()
            err = float(wrap(heading_of(p) - p[2]))
            if abs(err) < heading_tolerance:
                break
            drive.command(0.0, float(np.clip(3.0 * err, -w_max, w_max)))
            stepper.advance(dt)
        drive.command(0.0, 0.0)
        stepper.advance(0.2)

    def bearing(p: NDArray[np.float64]) -> float:
        return math.atan2(target[1] - p[1], target[0] - p[0])

    p = pose_fn()
    if math.hypot(target[0] - p[0], target[1] - p[1]) > position_tolerance:
        turn_to(bearing)
        while world.time - t0 < timeout:
            p = pose_fn()
            dist = math.hypot(target[0] - p[0], target[1] - p[1])
            if dist < position_tolerance:
                break
            err = float(wrap(bearing(p) - p[2]))
            if abs(err) > math.pi / 2:  # overshot: turn again
                turn_to(bearing)
                continue
            drive.command(min(speed, 0.8 * dist + 0.02), float(np.clip(3.0 * err, -w_max, w_max)))
            stepper.advance(dt)
        drive.command(0.0, 0.0)
        stepper.advance(0.3)
    turn_to(lambda _p: float(target[2]))
    return world.time - t0


# --------------------------------------------------------------------------------------
# One run
# --------------------------------------------------------------------------------------


@dataclass
class _PoseSource:
    """The run's pose source: ``now(odom)`` the believed pose (3,) (``odom``: the
    odometry just measured, else read now), the filter (``mcl`` only) and its scan hook."""

    spec: RunSpec
    world: Any
    tracker: Any = None
    on_scan: Callable[..., None] | None = None
    scan_beams: NDArray[np.int64] | None = None

    @classmethod
    def open(cls, spec: RunSpec, world: Any, seq: np.random.SeedSequence) -> _PoseSource:
        """``seq`` seeds the filter (as a Generator here, as a seed for a remote one)."""
        src = cls(spec, world)
        if spec.pose_source == "mcl":
            start_pose = np.asarray(spec.arena.start, dtype=np.float64)
            if spec.remote_mcl:  # the filter beside the physics (bit-identical)
                from simlab.localization.remote import RemoteTracker

                src.tracker = RemoteTracker(spec.mcl_field, seq, spec.mcl_params,
                                            initial_pose=start_pose,
                                            odometry=world.odometry())
            else:
                from simlab.localization.tracker import MCLTracker

                src.tracker = MCLTracker(spec.mcl_field, np.random.default_rng(seq),
                                         spec.mcl_params, initial_pose=start_pose,
                                         odometry=world.odometry())
            src.on_scan = src.tracker.on_scan
            # cast only the beams the filter reads (40 of 360): half the replay's time
            src.scan_beams = src.tracker.filter.beam_subset(world.lidar_spec.n_beams)
        return src

    def now(self, odom: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        if self.spec.pose_source == "truth":
            return self.world.pose()
        odom = self.world.odometry() if odom is None else odom
        if self.spec.pose_source == "odometry":
            return np.asarray(odom, dtype=np.float64)
        return self.tracker.pose(odom)

    def after(self, result: Any) -> NDArray[np.float64]:
        """The driver's ``pose_of``: after a primitive result, or now for None."""
        return self.now(None if result is None else result.odom_after)


def _frame(source: _PoseSource, chooser: Chooser, robot_time: float, n: int, est: Any,
           s: int | None, rewards: int) -> Any:
    from simlab.replay.video import FrameState

    parts = None
    if source.tracker is not None:
        p = source.tracker.filter.particles
        parts = p[:: max(1, len(p) // FRAME_PARTICLES)].copy()
    return FrameState(t=robot_time, goal=chooser.goal, state=s, truth=source.world.pose(),
                      estimate=est.copy(), trail_end=n + 1, particles=parts, rewards=rewards)


def run(spec: RunSpec, seqs: list[np.random.SeedSequence], bar: Any = None) -> RunOutcome:
    """Drive one replay (see :mod:`simlab.replay.replay`); ``seqs`` = (policy, noise,
    localization, goals) seed sequences; ``bar`` a tqdm bar in robot hours (or None)."""
    from simlab.physics.driver import DecisionDriver
    from simlab.physics.world import World

    policy_rng, noise_rng, goal_rng = (np.random.default_rng(seqs[i]) for i in (0, 1, 3))
    latency = float(spec.params.decision_latency)
    G = spec.goal_masks.shape[0]
    disc = spec.discretizer

    def state_of(pose: NDArray[np.float64]) -> int:
        return int(disc.state_of(pose[:2]))

    # The "drive until the state changes" primitives watch the state of the true position.
    watch = (None if spec.params.mode != "until_state_change"
             else lambda xy: int(disc.state_of(np.asarray(xy, dtype=float)[None, :2])[0]))
    recorder, frames = Recorder(), []
    wall0 = time.perf_counter()
    with World(spec.arena, physics_hz=spec.physics_hz) as world:
        source = _PoseSource.open(spec, world, seqs[2])
        driver = DecisionDriver(world, spec.params, pose_of=source.after, state_of=state_of,
                                primitives=spec.primitives, on_scan=source.on_scan,
                                scan_beams=source.scan_beams, watch_state=watch)
        chooser = Chooser(spec, policy_rng, goal=int(goal_rng.integers(0, G)))
        start = np.asarray(spec.arena.start, dtype=np.float64)
        returns = rewards = 0
        idle = robot_time = 0.0
        while robot_time < spec.budget:
            step = driver.step(chooser, noise_rng)
            res = step.result
            reward = int(spec.goal_masks[chooser.goal, step.state_after])
            recorder.record(robot_time, step, chooser.goal, reward,
                            int(disc.state_of(res.pose_after[:2])))
            idle += latency
            chooser.after(step.action, bool(res.blocked))
            if reward:
                rewards += 1
                chooser.history.clear()
                if G > 1:
                    chooser.goal = int((chooser.goal + 1 + goal_rng.integers(0, G - 1)) % G)
                if spec.return_to_start:
                    drive_to_pose(world, start, source.now, noise_rng, source.on_scan,
                                  scan_beams=source.scan_beams)
                    returns += 1
                    driver.observe()
                    chooser.excluded[:] = False
            robot_time = world.time + idle
            n = len(recorder)
            if spec.frame_stride and (n - 1) % spec.frame_stride == 0:
                frames.append(_frame(source, chooser, robot_time, n, driver.pose,
                                     driver.state, rewards))
            if bar is not None:
                bar.update(min(robot_time, spec.budget) / 3600.0 - bar.n)
                if n % 20 == 0:
                    bar.set_postfix(rewards=rewards, refresh=False)
        stepped = world.time
    tracker = source.tracker
    return RunOutcome(log=recorder.log(latency), robot_seconds=stepped + idle,
                      stepped_seconds=stepped, wall_seconds=time.perf_counter() - wall0,
                      blocked_retries=chooser.retries, escapes=chooser.escapes,
                      returns_to_start=returns,
                      mcl_log=None if tracker is None else tracker.log(), frames=frames)
