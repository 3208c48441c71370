"""``simlab replay``: the learned policy driven in closed loop in physics (SPEC A9, thesis 4.5).

The question of the physics half: does a policy planned on the empirical matrix work
when the robot drives it? The replay does what the thesis's TurtleBot did for three
hours (Fig. 4.10):

1. the robot starts at the arena's start pose; the first goal is drawn uniformly among
   the arena's goals;
2. at each decision it reads its pose from the **pose source** (``truth``: the
   simulator; ``odometry``: the wheel encoders, which drift; ``mcl``: the LIDAR particle
   filter of :mod:`simlab.localization` on the occupancy map, started at the known start
   pose), turns it into a Markov state with the discretizer, and picks
   ``argmax_a Q_goal(s, a)`` over the **valid** actions (ties broken at random;
   ``policy="random"`` picks uniformly among all the robot's actions);
3. it executes the motion primitive of that action, ``action_set.to_primitive(a)`` (the
   Q-tables' :class:`~simlab.actions.ActionSet`: 16 simlab primitives, or e.g. a real
   robot's 8 actions numbered counter-clockwise from East), in physics; the obstacle
   detector is part of the primitive (a blocked primitive rotates but does not translate);
4. the robot clock advances by the primitive's stepped duration plus the decision latency
   (idle, not stepped);
5. if the state reached (from the pose source, as the real robot only knows its
   estimate) lies in the current goal (goal masks of the arena and discretizer, the
   estimator's rule), the reward is +1 and the goal switches to one of the other goals
   drawn uniformly; with ``return_to_start`` the robot first drives back to the start
   pose (the thesis's ``go_back_initial_pose`` node: turn, straight line, turn; no
   obstacle check; its time counts, it earns nothing).

Decisions where the thesis is silent:

* **blocked retries** (``retry_blocked``, default on): the simulated robot is
  deterministic, so a greedy action the detector refused would be refused again from the
  same pose forever. After a blocked primitive the refused action is excluded at that
  pose; the robot takes the best remaining one; the exclusions clear once the robot has
  moved. (The empirical MDP models a blocked action as a chance of staying; the physics
  makes it a certainty at a given pose. This is part of the sim-to-model gap.)
* **loop watchdog** (``escape_radius``, default 0.03 m): the simulator has no motion
  noise, so a greedy policy can fall into an exact limit cycle (UP fast into a cell whose
  greedy action is DOWN fast, back to the same pose, and so on for hours) that the
  empirical MDP, estimated over all positions within the cells, sees as a rare transient.
  The real robot's wheel slip and localization noise break such loops. Here, when the
  greedy choice is an action already taken in the current goal episode from a pose
  (of the pose source) within ``escape_radius``, the physics would repeat itself, so the
  robot takes a uniformly random other action instead (counted as ``escapes``). Repeats
  from other positions (a robot crossing a large cell in several moves) are not
  touched. ``epsilon`` > 0 gives an epsilon-greedy policy instead or in addition
  (modelled exactly by the prediction, unlike the watchdog).
* **heading control**: the primitives steer by the true heading (the stand-in for the
  localized heading, see :class:`~simlab.physics.motion.PrimitiveParams`), except with the
  ``odometry`` pose source, where the robot has nothing but its encoders and steers by
  the odometry heading.
* **random baseline**: for ``policy="greedy"`` a random-policy replay of
  ``baseline_hours`` (default: the same duration) runs in a second world with its own
  seed stream and the truth pose source (a random policy ignores the pose; only the
  bookkeeping of rewards uses it).
* **masked actions** (issue 12): the Q-tables' saved ``valid`` mask (or, for Q-tables
  without one and not trained with the ``self-loop`` rule, the MDP's) is never violated by
  the greedy choice, the blocked-retry fallback or the loop watchdog; only ``epsilon``
  exploration and the random baseline draw among all actions (as the prediction models).
  Q-tables whose action set differs from the MDP's are refused.
* **primitive parameters**: the robot must drive the primitives the model was estimated
  from, so by default the replay uses those recorded in the MDP's dataset manifest
  (found through ``mdp.json``); explicit ``params`` that differ raise ConfigError.
* **predicted rate**: :mod:`simlab.replay.prediction`, at the dataset's pace (its robot
  seconds per transition) and at the replay's own measured pace.
* **scheduling** (issue 17; ``parallel=True``, when cores are idle, :func:`schedule`): the
  random baseline runs in a ``spawn`` process while this one drives the learned policy,
  and the ``mcl`` filter runs in a third process fed scan by scan
  (:class:`~simlab.localization.remote.RemoteTracker`; the robot waits for it only at
  decisions and video frames). The worlds and seed streams are independent, so the
  results are bit-identical to ``parallel=False``; the replay's wall time becomes that
  of its longest part instead of the sum.

Outputs in ``out``: ``replay.json`` (summary; the headline numbers also flat at its top
level: ``reward_rate_per_hour``, ``random_rate_per_hour``, ``predicted_rate_per_hour``,
``position_error_mean_m`` of a non-truth pose source), ``cumulative_reward.png`` (Fig. 4.10:
learned policy, random policy, MDP-predicted rates), ``transitions.parquet`` (one row per
transition), ``localization.parquet`` (one row per filter update, ``mcl`` only),
``replay.gif`` (and ``replay.mp4`` if imageio-ffmpeg is installed) with ``video=True``.
Every output path is checked before the robot moves; each file is written atomically.

Seeding: ``SeedSequence(seed).spawn(5)`` -> (policy ties / random actions, LIDAR noise,
localization, goal draws, random baseline); same seed, same replay.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.errors import ConfigError
from simlab.io import atomic_write, atomic_write_json, ensure_new, output_transaction

POSE_SOURCES = ("truth", "odometry", "mcl")
POLICIES = ("greedy", "random")
#: Particles stored per video frame (a subsample of the filter's).
FRAME_PARTICLES = 150


# --------------------------------------------------------------------------------------
# Result objects
# --------------------------------------------------------------------------------------


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
class ReplayResult:
    """What :func:`replay` did: the summary written to ``replay.json``, the runs and the
    files."""

    summary: dict[str, Any]
    run: RunOutcome
    baseline: RunOutcome | None
    files: dict[str, Path]

    @property
    def rate_per_hour(self) -> float:
        return float(self.summary["result"]["rate_per_hour"])


# --------------------------------------------------------------------------------------
# Action choice
# --------------------------------------------------------------------------------------


def greedy_action(q: NDArray[np.float64], rng: np.random.Generator,
                  excluded: NDArray[np.bool_] | None = None, tie_tolerance: float = 1e-9, *,
                  valid: NDArray[np.bool_] | None = None) -> int:
    """``argmax_a q[a]`` over the ``valid`` actions (None: all; a state with none valid keeps
    all) not ``excluded`` (ignored when it would exclude every valid action), ties (within
    ``tie_tolerance * max(1, |max|)``, the rule of
    :func:`simlab.replay.prediction.greedy_ties`) broken uniformly with ``rng``."""
    q = np.asarray(q, dtype=np.float64)
    if valid is not None and valid.any() and not valid.all():
        q = np.where(valid, q, -np.inf)
        if excluded is not None:
            excluded = excluded & valid
            if excluded.sum() == valid.sum():
                excluded = None
    if excluded is not None and excluded.any() and not excluded.all():
        q = np.where(excluded, -np.inf, q)
    best = float(q.max())
    ties = np.flatnonzero(q >= best - tie_tolerance * max(1.0, abs(best)))
    if ties.size == 1:
        return int(ties[0])
    return int(ties[rng.integers(0, ties.size)])


def _escape_action(a: int, valid: NDArray[np.bool_] | None, n_actions: int,
                   rng: np.random.Generator) -> int:
    """A uniformly random action other than ``a`` (among the valid ones when there are
    others; without a mask the same draw as before the mask existed)."""
    if valid is None or valid.all():
        return int((a + 1 + rng.integers(0, n_actions - 1)) % n_actions)
    others = np.flatnonzero(valid & (np.arange(n_actions) != a))
    if others.size == 0:
        return a
    return int(others[rng.integers(0, others.size)])


def _recurs(history: list[tuple[float, float, int]], pose: NDArray[np.float64], action: int,
            radius: float) -> bool:
    """Whether ``action`` was already taken from within ``radius`` (m) of ``pose``."""
    r2 = radius * radius
    x, y = float(pose[0]), float(pose[1])
    return any(a == action and (hx - x) ** 2 + (hy - y) ** 2 <= r2 for hx, hy, a in history)


# --------------------------------------------------------------------------------------
# Stepping outside primitives (the return to the start pose)
# --------------------------------------------------------------------------------------


def drive_to_pose(world: Any, target: NDArray[np.float64],
                  pose_fn: Callable[[], NDArray[np.float64]], rng: np.random.Generator,
                  on_scan: Callable[[Any, NDArray[np.float64]], None] | None = None, *,
                  scan_beams: NDArray[np.int64] | None = None, speed: float = 0.11, position_tolerance: float = 0.03,
                  heading_tolerance: float = 0.05, timeout: float = 60.0) -> float:
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


@dataclass(frozen=True)
class _RunSpec:
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


def _run(spec: _RunSpec, seqs: list[np.random.SeedSequence], bar: Any = None) -> RunOutcome:
    """Drive one replay (see the module docstring); ``seqs`` = (policy, noise, localization,
    goals) seed sequences."""
    from simlab.localization.tracker import MCLTracker
    from simlab.physics.motion import execute_primitive
    from simlab.physics.world import World

    n_actions = len(spec.primitives)

    policy_rng, noise_rng, loc_rng, goal_rng = (np.random.default_rng(s) for s in seqs)
    params = spec.params
    latency = float(params.decision_latency)
    G = spec.goal_masks.shape[0]
    disc = spec.discretizer
    # The "drive until the state changes" primitives watch the state of the true position.
    state_of = (None if params.mode != "until_state_change"
                else lambda xy: int(disc.state_of(np.asarray(xy, dtype=float)[None, :2])[0]))
    rows: dict[str, list[Any]] = {k: [] for k in (
        "t", "duration", "s", "a", "s_next", "goal", "reward", "blocked", "truth_before",
        "truth_after", "est_before", "est_after", "odom_after", "s_true_next")}
    frames: list[Any] = []
    wall0 = time.perf_counter()
    with World(spec.arena) as world:
        tracker = None
        on_scan = None
        scan_beams = None
        if spec.pose_source == "mcl":
            start_pose = np.asarray(spec.arena.start, dtype=np.float64)
            if spec.remote_mcl:  # the filter beside the physics (bit-identical)
                from simlab.localization.remote import RemoteTracker

                tracker = RemoteTracker(spec.mcl_field, seqs[2], spec.mcl_params,
                                        initial_pose=start_pose, odometry=world.odometry())
            else:
                tracker = MCLTracker(spec.mcl_field, loc_rng, spec.mcl_params,
                                     initial_pose=start_pose, odometry=world.odometry())
            on_scan = tracker.on_scan
            # cast only the beams the filter reads (40 of 360): half the replay's time
            scan_beams = tracker.filter.beam_subset(world.lidar_spec.n_beams)

        def pose_now(odom: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
            if spec.pose_source == "truth":
                return world.pose()
            odom = world.odometry() if odom is None else odom
            if spec.pose_source == "odometry":
                return np.asarray(odom, dtype=np.float64)
            return tracker.pose(odom)  # type: ignore[union-attr]

        start = np.asarray(spec.arena.start, dtype=np.float64)
        goal = int(goal_rng.integers(0, G))
        est = pose_now()
        s = int(disc.state_of(est[:2]))
        excluded = np.zeros(n_actions, dtype=bool)
        history: list[tuple[float, float, int]] = []  # decisions of the goal episode
        retries = returns = rewards = escapes = 0
        idle = 0.0
        robot_time = 0.0
        while robot_time < spec.budget:
            if spec.policy == "random" or (spec.epsilon > 0 and
                                           policy_rng.random() < spec.epsilon):
                a = int(policy_rng.integers(0, n_actions))
            else:
                allowed = None if spec.valid is None else spec.valid[goal, s]
                a = greedy_action(spec.Q[goal, s], policy_rng,  # type: ignore[index]
                                  excluded if spec.retry_blocked else None, valid=allowed)
                retries += int(excluded.any())
                if spec.escape_radius > 0 and _recurs(history, est, a, spec.escape_radius):
                    a = _escape_action(a, allowed, n_actions, policy_rng)
                    escapes += 1
            history.append((est[0], est[1], a))
            truth_before = world.pose()
            res = execute_primitive(world, int(spec.primitives[a]), noise_rng, params,
                                    on_scan=on_scan, scan_beams=scan_beams,
                                    state_of=state_of)
            est_after = pose_now(res.odom_after)
            s_next = int(disc.state_of(est_after[:2]))
            reward = int(spec.goal_masks[goal, s_next])
            rows["t"].append(robot_time)
            rows["duration"].append(res.duration)
            rows["s"].append(s)
            rows["a"].append(a)
            rows["s_next"].append(s_next)
            rows["goal"].append(goal)
            rows["reward"].append(reward)
            rows["blocked"].append(bool(res.blocked))
            rows["truth_before"].append(truth_before)
            rows["truth_after"].append(res.pose_after)
            rows["est_before"].append(est)
            rows["est_after"].append(est_after)
            rows["odom_after"].append(res.odom_after)
            rows["s_true_next"].append(int(disc.state_of(res.pose_after[:2])))
            idle += latency
            if res.blocked:
                excluded[a] = True
            else:
                excluded[:] = False
            est, s = est_after, s_next
            if reward:
                rewards += 1
                history.clear()
                if G > 1:
                    goal = int((goal + 1 + goal_rng.integers(0, G - 1)) % G)
                if spec.return_to_start:
                    drive_to_pose(world, start, pose_now, noise_rng, on_scan,
                                  scan_beams=scan_beams)
                    returns += 1
                    est = pose_now()
                    s = int(disc.state_of(est[:2]))
                    excluded[:] = False
            robot_time = world.time + idle
            n = len(rows["t"])
            if spec.frame_stride and (n - 1) % spec.frame_stride == 0:
                from simlab.replay.video import FrameState

                parts = None
                if tracker is not None:
                    p = tracker.filter.particles
                    parts = p[:: max(1, len(p) // FRAME_PARTICLES)].copy()
                frames.append(FrameState(t=robot_time, goal=goal, state=s, truth=world.pose(),
                                         estimate=est.copy(), trail_end=n + 1,
                                         particles=parts, rewards=rewards))
            if bar is not None:
                bar.update(min(robot_time, spec.budget) / 3600.0 - bar.n)
                if n % 20 == 0:
                    bar.set_postfix(rewards=rewards, refresh=False)
        stepped = world.time
    wall = time.perf_counter() - wall0

    def arr(name: str, dtype: Any, width: int | None = None) -> NDArray[Any]:
        values = rows[name]
        if not values:
            return np.zeros((0, width) if width else 0, dtype=dtype)
        return np.asarray(values, dtype=dtype)

    log = ReplayLog(
        t=arr("t", np.float64), duration=arr("duration", np.float64), s=arr("s", np.int64),
        a=arr("a", np.int64), s_next=arr("s_next", np.int64), goal=arr("goal", np.int64),
        reward=arr("reward", np.int64), blocked=arr("blocked", bool),
        truth_before=arr("truth_before", np.float64, 3),
        truth_after=arr("truth_after", np.float64, 3),
        est_before=arr("est_before", np.float64, 3), est_after=arr("est_after", np.float64, 3),
        odom_after=arr("odom_after", np.float64, 3),
        s_true_next=arr("s_true_next", np.int64), latency=latency,
    )
    return RunOutcome(log=log, robot_seconds=stepped + idle, stepped_seconds=stepped,
                      wall_seconds=wall, blocked_retries=retries, escapes=escapes,
                      returns_to_start=returns,
                      mcl_log=None if tracker is None else tracker.log(), frames=frames)


def _bar(total: float, desc: str, progress: bool) -> Any:
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=desc, unit="robot-h", disable=not progress,
                dynamic_ncols=True, bar_format="{l_bar}{bar}| {n:.2f}/{total:.2f} robot-h "
                                               "[{elapsed}<{remaining}{postfix}]")


def _run_quiet(spec: _RunSpec, seqs: list[np.random.SeedSequence]) -> RunOutcome:
    """:func:`_run` without a progress bar (the entry point of the baseline's process)."""
    return _run(spec, seqs)


def usable_cores() -> int:
    """CPUs this process may run on (its affinity mask; ``os.cpu_count()`` elsewhere)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def idle_cores(window: float = 0.25) -> float:
    """CPUs idle right now, as seen by this process: ``usable_cores()`` times the idle
    share of ``/proc/stat`` over ``window`` seconds (this process sleeps meanwhile, so
    a quiet 2-core machine reads ~2). Without ``/proc/stat``: ``usable_cores()``."""

    def sample() -> tuple[int, int]:
        with open("/proc/stat") as fh:
            values = [int(v) for v in fh.readline().split()[1:]]
        return values[3] + values[4], sum(values)  # idle + iowait, total

    try:
        idle0, total0 = sample()
        time.sleep(window)
        idle1, total1 = sample()
    except (OSError, ValueError, IndexError):  # pragma: no cover - not Linux
        return float(usable_cores())
    if total1 <= total0:
        return float(usable_cores())
    return usable_cores() * (idle1 - idle0) / (total1 - total0)


def schedule(parallel: bool, baseline: bool, mcl: bool) -> tuple[bool, bool]:
    """``(baseline in a process, mcl filter in a process)`` for a replay.

    Extra processes pay only with idle cores to run on: on a machine already busy they
    add their start-up (~1.5 s each) and contention (measured: a 1 h + 1 h replay at load
    4 on 2 cores took 18 s in three processes, 14 s in one). So with ``parallel`` the
    baseline gets a process when at least 1.5 cores are idle, and the filter one when
    another 1 is idle beyond the baseline's (with no baseline: 1.5). Results do not
    depend on the choice (bit-identical, tested).
    """
    if not parallel or usable_cores() < 2 or not (baseline or mcl):
        return False, False
    free = idle_cores()
    split_baseline = baseline and free >= 1.5
    split_mcl = mcl and free >= (2.5 if split_baseline else 1.5)
    return split_baseline, split_mcl


def _run_both(spec: _RunSpec, seqs: list[np.random.SeedSequence], bspec: _RunSpec | None,
              bseqs: list[np.random.SeedSequence], hours: float, baseline_hours: float,
              policy: str, pose_source: str, progress: bool, parallel: bool
              ) -> tuple[RunOutcome, RunOutcome | None]:
    """The main run (in this process) and the random baseline (``bspec``, None: none).

    With ``parallel`` (see :func:`schedule`) the baseline runs in a ``spawn``
    process (no PyBullet client or lock of this process is inherited) while this one
    drives the main run: the two worlds share nothing and each draws from its own
    seed streams, so the outcome is the sequential one, bit for bit (tested); the
    replay's wall time becomes that of the longer run instead of their sum.
    """
    if bspec is None or not parallel:
        with _bar(hours, f"replay {policy} ({pose_source})", progress) as bar:
            run = _run(spec, seqs, bar)
        if bspec is None:
            return run, None
        with _bar(baseline_hours, "replay random baseline", progress) as bar:
            return run, _run(bspec, bseqs, bar)
    import concurrent.futures as cf
    import multiprocessing

    with cf.ProcessPoolExecutor(max_workers=1,
                                mp_context=multiprocessing.get_context("spawn")) as pool:
        future = pool.submit(_run_quiet, bspec, bseqs)
        with _bar(hours, f"replay {policy} ({pose_source}; random baseline in parallel)",
                  progress) as bar:
            run = _run(spec, seqs, bar)
        return run, future.result()


# --------------------------------------------------------------------------------------
# Summaries
# --------------------------------------------------------------------------------------


def _pose_errors(est: NDArray[np.float64], truth: NDArray[np.float64]
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    from simlab.localization.motion import wrap

    pos = np.hypot(*(est[:, :2] - truth[:, :2]).T) if len(est) else np.zeros(0)
    head = np.abs(wrap(est[:, 2] - truth[:, 2])) if len(est) else np.zeros(0)
    return pos, head


def _run_summary(run: RunOutcome, goal_names: tuple[str, ...]) -> dict[str, Any]:
    log = run.log
    hours = run.robot_seconds / 3600.0
    rewards = int(log.reward.sum())
    per_goal = {g: int(log.reward[log.goal == i].sum()) for i, g in enumerate(goal_names)}
    true_hits = int(((log.reward > 0) & (log.s_true_next == log.s_next)).sum())
    return {
        "transitions": log.n,
        "robot_seconds": run.robot_seconds,
        "stepped_seconds": run.stepped_seconds,
        "rewards": rewards,
        "rate_per_hour": rewards / hours if hours > 0 else 0.0,
        "reward_per_transition": rewards / log.n if log.n else 0.0,
        "goals_reached": per_goal,
        "rewards_true_state_agrees": true_hits,
        "seconds_per_transition": run.robot_seconds / log.n if log.n else None,
        "mean_primitive_seconds": float(log.duration.mean()) if log.n else None,
        "transitions_per_goal": log.n / rewards if rewards else None,
        "blocked": int(log.blocked.sum()),
        "blocked_retries": run.blocked_retries,
        "escapes": run.escapes,
        "returns_to_start": run.returns_to_start,
        "state_agrees_with_truth": float((log.s_true_next == log.s_next).mean())
        if log.n else None,
        "wall_seconds": run.wall_seconds,
        "real_time_factor_robot": run.robot_seconds / run.wall_seconds
        if run.wall_seconds > 0 else None,
        "real_time_factor_stepped": run.stepped_seconds / run.wall_seconds
        if run.wall_seconds > 0 else None,
    }


def _localization_summary(run: RunOutcome) -> dict[str, Any]:
    from simlab.localization.tracker import error_summary

    log = run.log
    out: dict[str, Any] = {}
    pe, he = _pose_errors(log.odom_after, log.truth_after)
    out["odometry"] = {"at_decisions": error_summary(pe, he),
                       "final_position_error_m": float(pe[-1]) if pe.size else None}
    if run.mcl_log is not None:
        ml = run.mcl_log
        pe2, he2 = _pose_errors(log.est_after, log.truth_after)
        late = ml.t >= 60.0
        out["mcl"] = {
            "at_decisions": error_summary(pe2, he2),
            "updates": error_summary(ml.position_error, ml.heading_error),
            "updates_after_first_minute": error_summary(ml.position_error[late],
                                                        ml.heading_error[late]),
            "particles_injected": int(ml.injected.sum()),
        }
    return out


def _check_choice(value: Any, allowed: tuple[str, ...], key: str) -> str:
    if value not in allowed:
        raise ConfigError(f"expected one of {', '.join(allowed)}, got {value!r}", key=key)
    return str(value)


def _check_hours(value: Any, key: str, allow_zero: bool = False) -> float:
    ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or value < 0 or (value == 0 and not allow_zero):
        raise ConfigError(f"expected a number of hours {'>= 0' if allow_zero else '> 0'}, "
                          f"got {value!r}", key=key)
    return float(value)


# --------------------------------------------------------------------------------------
# The command
# --------------------------------------------------------------------------------------


def replay(
    arena: Any = "table",
    states: Any = None,
    qtables: str | os.PathLike[str] | Mapping[str, Any] | None = None,
    hours: float = 3.0,
    pose_source: str = "truth",
    seed: int = 0,
    out: str | os.PathLike[str] = "runs/replay",
    policy: str = "greedy",
    map: str | os.PathLike[str] | None = None,
    return_to_start: bool = False,
    video: bool = False,
    progress: bool = True,
    overwrite: bool = False,
    *,
    mdp: Any = None,
    baseline_hours: float | None = None,
    retry_blocked: bool = True,
    escape_radius: float = 0.03,
    epsilon: float = 0.0,
    params: Any = None,
    mcl_params: Any = None,
    max_frames: int = 150,
    action_set: Any = None,
    goals: str | Sequence[str] | None = None,
    parallel: bool = True,
) -> ReplayResult:
    """Replay the Q-tables in physics for ``hours`` of robot time (see the module doc).

    Args:
        arena: built-in arena name, ``.toml`` path or ``ArenaConfig``.
        states: states file of ``simlab discretize`` (JSON) or a discretizer.
        qtables: the ``simlab train`` output directory (``q_<goal>.npz`` per goal) or a
            mapping ``goal -> Q (S, A)`` (A = 16, or ``action_set``'s); may be None for
            ``policy="random"``.
        hours: robot time (driving + idle latency) to replay.
        goals: the goals to switch between: None / ``"all"`` for every arena goal, or
            names — arena goals, or state-id goals ``s18`` / ``s18+19`` as
            ``simlab train --goal-states`` names them (:func:`simlab.data.goals.select_goals`).
        pose_source: ``"truth"``, ``"odometry"`` or ``"mcl"``.
        seed: root seed (see the module docstring).
        out: output directory.
        policy: ``"greedy"`` (the Q-tables) or ``"random"`` (uniform actions).
        map: map_server ``map.yaml`` to localize on and to draw (checked against the
            arena); default: the arena's own geometry rasterised at 1 cm.
        return_to_start: drive back to the start pose after each goal (thesis 3.2.4).
        video: also write ``replay.gif`` (and ``replay.mp4`` with imageio-ffmpeg).
        progress: show a progress bar (robot hours).
        overwrite: replace existing outputs.
        mdp: ``mdp.npz`` for the predicted rate (default: the one the Q-tables record).
        baseline_hours: duration of the random-policy baseline replay (default
            ``hours``; 0: none, the random rate then comes from the MDP only).
        retry_blocked: exclude a refused action at the same pose (module docstring).
        escape_radius: the loop watchdog (m): a greedy choice repeating the action taken
            earlier in the goal episode from within this distance is replaced by a random
            other action (module docstring); 0 disables it.
        epsilon: probability of a uniformly random action at each decision (epsilon-greedy;
            the prediction models it exactly). Default 0: greedy.
        params: :class:`~simlab.physics.motion.PrimitiveParams` (default: those of the
            MDP's dataset when known, else the default values).
        mcl_params: :class:`~simlab.localization.filter.MCLParams` (default values).
        max_frames: at most this many video frames (evenly spread over the replay).
        action_set: :class:`~simlab.actions.ActionSet` of in-memory Q-tables (files record
            theirs; given, it must agree).
        parallel: run the random baseline in a second process while this one drives the
            learned policy, and the ``mcl`` particle filter in a third, beside the physics
            (:mod:`simlab.localization.remote`), when the machine has idle cores for them
            (:func:`schedule`); the results are bit-identical to ``parallel=False``
            (tested).

    Returns:
        :class:`ReplayResult`. Raises :class:`ConfigError` for bad input (naming the file):
        Q-tables of the wrong shape, a goal without a Q-table, an MDP or map of another
        arena or discretizer, missing files, outputs that exist.
    """
    from simlab.data.goals import goal_state_masks, select_goals
    from simlab.data.inputs import load_arena_config, load_discretizer
    from simlab.localization.filter import MCLParams
    from simlab.localization.likelihood import LikelihoodField
    from simlab.localization.maps import load_map_for_arena
    from simlab.replay.inputs import (
        discover_mdp,
        load_model,
        load_qtables,
        primitive_params_for,
    )
    from simlab.replay.prediction import (
        greedy_policy_matrix,
        predict_reward_rate,
        uniform_policy_matrix,
    )

    hours = _check_hours(hours, "hours")
    pose_source = _check_choice(pose_source, POSE_SOURCES, "pose_source")
    policy = _check_choice(policy, POLICIES, "policy")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ConfigError(f"expected a whole number >= 0, got {seed!r}", key="seed")
    baseline_hours = hours if baseline_hours is None else _check_hours(
        baseline_hours, "baseline_hours", allow_zero=True)
    if policy == "random":
        baseline_hours = 0.0
    if not (isinstance(escape_radius, int | float) and math.isfinite(escape_radius)
            and escape_radius >= 0):
        raise ConfigError(f"expected a distance >= 0 m, got {escape_radius!r}",
                          key="escape_radius")
    if not (isinstance(epsilon, int | float) and 0.0 <= epsilon <= 1.0):
        raise ConfigError(f"expected a probability in [0, 1], got {epsilon!r}", key="epsilon")
    if isinstance(max_frames, bool) or not isinstance(max_frames, int) or max_frames < 1:
        raise ConfigError(f"expected a whole number >= 1, got {max_frames!r}", key="max_frames")

    # ---- inputs, all checked before anything runs
    arena_cfg = load_arena_config(arena)
    disc = load_discretizer(states)
    states_src = str(states) if isinstance(states, str | os.PathLike) else None
    from simlab.statecheck import check_centres_in_arena, check_states_hash, npz_states_hash

    check_centres_in_arena(disc.centres, arena_cfg, source=states_src)
    goal_names, goal_masks = select_goals(goal_state_masks(arena_cfg, disc.centres), goals,
                                          disc.n_states)
    goal_names = tuple(str(g) for g in goal_names)
    if qtables is None and policy == "greedy":
        raise ConfigError("a greedy replay needs Q-tables", key="qtables",
                          fix="pass --qtables DIR (the output of `simlab train`) or --random")
    qt = None if qtables is None else load_qtables(qtables, goal_names, disc.n_states, states_src,
                                                   action_set=action_set)
    states_hash = disc.content_hash()
    for i, meta in enumerate(() if qt is None else qt.metadata):
        check_states_hash(meta.get("states_hash"), states_hash, what="the Q-table",
                          path=qt.files[i] or qt.source, against=states_src or "the states")
    mdp_source = mdp if mdp is not None else (None if qt is None else discover_mdp(qt))
    model = None if mdp_source is None else load_model(
        mdp_source, disc, goal_names, goal_masks,
        action_set=None if qt is None else qt.action_set)
    if isinstance(mdp_source, str | os.PathLike):
        check_states_hash(npz_states_hash(mdp_source), states_hash, what="the MDP",
                          path=mdp_source, against=states_src or "the states")
    action_set, valid = _actions_and_mask(qt, model)
    grid, map_check = load_map_for_arena(map, arena_cfg)
    params, params_source = primitive_params_for(model, params)
    if pose_source == "odometry" and params.heading_source != "odometry":
        params = replace(params, heading_source="odometry")
    mcl_params = mcl_params if mcl_params is not None else MCLParams()
    field_ = LikelihoodField(grid, mcl_params.sensor) if pose_source == "mcl" else None

    out = Path(out)
    files = {"summary": out / "replay.json", "plot": out / "cumulative_reward.png",
             "transitions": out / "transitions.parquet"}
    if pose_source == "mcl":
        files["localization"] = out / "localization.parquet"
    if video:
        from simlab.replay.video import mp4_available

        files["gif"] = out / "replay.gif"
        if mp4_available():
            files["mp4"] = out / "replay.mp4"
    if out.exists() and not out.is_dir():
        raise ConfigError("output exists and is not a directory", path=out,
                          fix="choose another --out")
    for p in files.values():
        ensure_new(p, overwrite=overwrite, what="replay output")

    # ---- runs
    seqs = np.random.SeedSequence(int(seed)).spawn(5)
    budget = hours * 3600.0
    expected_transitions = budget / (params.decision_latency + 1.5)
    stride = max(1, math.ceil(expected_transitions / max_frames)) if video else 0
    split_baseline, split_mcl = schedule(parallel, baseline_hours > 0, pose_source == "mcl")
    spec = _RunSpec(arena=arena_cfg, discretizer=disc, goal_masks=goal_masks,
                    Q=None if qt is None else qt.Q, policy=policy, pose_source=pose_source,
                    budget=budget, params=params, mcl_field=field_, mcl_params=mcl_params,
                    return_to_start=return_to_start, retry_blocked=retry_blocked,
                    escape_radius=escape_radius, epsilon=epsilon,
                    frame_stride=stride, primitives=action_set.primitives(), valid=valid,
                    remote_mcl=split_mcl)
    bspec = None
    if baseline_hours > 0:
        bspec = replace(spec, policy="random", pose_source="truth", mcl_field=None,
                        budget=baseline_hours * 3600.0, return_to_start=False, frame_stride=0,
                        params=params if pose_source != "odometry"
                        else replace(params, heading_source="truth"))
    run, baseline = _run_both(spec, seqs[:4], bspec, seqs[4].spawn(4), hours,
                              baseline_hours, policy, pose_source, progress, split_baseline)

    # ---- summary
    result = _run_summary(run, goal_names)
    summary: dict[str, Any] = {
        "arena": arena_cfg.name,
        "arena_sha256": getattr(arena_cfg, "source_sha256", None),
        "states": {"file": states_src, "n_states": int(disc.n_states),
                   "hash": disc.content_hash()},
        "qtables": None if qt is None else {"source": qt.source,
                                            "files": [f for f in qt.files if f]},
        "mdp": None if model is None else model.source,
        "dataset": None if model is None else model.dataset,
        "map": {"file": None if map is None else str(map),
                "kind": "arena geometry (1 cm raster)" if map is None else "map file",
                "check": None if map_check is None else map_check.as_dict()},
        "goal_names": list(goal_names),
        "goal_states": {g: [int(s) for s in np.flatnonzero(m)]
                        for g, m in zip(goal_names, goal_masks, strict=True)},
        "action_set": action_set.to_json(),
        "masked_pairs": None if valid is None else int((~valid).sum()),
        "policy": policy,
        "pose_source": pose_source,
        "seed": int(seed),
        "hours": hours,
        "return_to_start": bool(return_to_start),
        "retry_blocked": bool(retry_blocked),
        "escape_radius": float(escape_radius),
        "epsilon": float(epsilon),
        "primitive_params": asdict(params),
        "primitive_params_source": params_source,
        "mcl_params": asdict(mcl_params) if pose_source == "mcl" else None,
        "schedule": {"baseline_process": split_baseline, "mcl_process": split_mcl},
        "result": result,
        "localization": _localization_summary(run),
    }
    if baseline is not None:
        b = _run_summary(baseline, goal_names)
        summary["random_baseline"] = {"source": "physics replay, random policy, truth poses",
                                      "hours": baseline_hours, **b}
    prediction: dict[str, Any] | None = None
    if model is not None:
        start_state = int(disc.state_of(np.asarray(arena_cfg.start[:2])))
        G, S = goal_masks.shape
        measured_pace = result["seconds_per_transition"]
        pace = model.dataset_seconds_per_transition or measured_pace
        prediction = {"mdp": model.source, "start_state": start_state,
                      "pace_source": "dataset" if model.dataset_seconds_per_transition
                      else "replay (the dataset's pace is unknown)"}
        A = action_set.n_actions
        pols = {"random": np.repeat(uniform_policy_matrix(S, A)[None], G, axis=0)}
        if qt is not None:
            from simlab.training.heatmap import masked_q

            greedy = np.stack([greedy_policy_matrix(masked_q(q, None if valid is None
                                                               else valid[i]))
                               for i, q in enumerate(qt.Q)])
            pols["greedy"] = (1.0 - epsilon) * greedy + epsilon * pols["random"]
        for name, pol in pols.items():
            if pace is None:
                continue
            horizon = result["transitions"] if name == policy else None
            pred = predict_reward_rate(model.T, goal_masks, pol, start_state, pace,
                                       horizon=horizon).as_dict()
            if measured_pace:
                pred["rate_per_hour_at_replay_pace"] = (
                    3600.0 * pred["reward_per_transition"] / measured_pace)
            prediction[name] = pred
        summary["prediction"] = prediction
    summary["comparison"] = _comparison(summary, policy)
    # Flat headline numbers (what reports such as ``simlab pipeline``'s read).
    comp = summary["comparison"]
    summary["reward_rate_per_hour"] = result["rate_per_hour"]
    for key in ("random_rate_per_hour", "predicted_rate_per_hour"):
        if comp.get(key) is not None:
            summary[key] = comp[key]
    if pose_source != "truth":
        loc = summary["localization"][pose_source]["at_decisions"]
        summary["position_error_mean_m"] = loc.get("position_mean_m")
    summary["files"] = {k: str(v) for k, v in files.items()}

    # ---- outputs
    with output_transaction(out, files.values(), overwrite=overwrite,
                            what="replay output") as txn:  # every file, or none
        staged = {k: txn.path(v) for k, v in files.items()}
        _write_transitions(staged["transitions"], run.log, goal_names)
        if "localization" in staged:
            _write_localization(staged["localization"], run.mcl_log)
        _plot(staged["plot"], run, baseline, summary, policy, pose_source)
        if video:
            _write_video(staged, run, arena_cfg, disc, qt, goal_names, grid, max_frames)
        atomic_write_json(staged["summary"], summary)
    return ReplayResult(summary=summary, run=run, baseline=baseline, files=files)


def _qt_valid(qt: Any) -> NDArray[np.bool_] | None:
    return qt.valid if not _trained_self_loop(qt) else None


def _trained_self_loop(qt: Any) -> bool:
    return any(m.get("unvisited") == "self-loop" for m in qt.metadata)


def _actions_and_mask(qt: Any, model: Any) -> tuple[Any, NDArray[np.bool_] | None]:
    """The action set of the replay and the ``(G, S, A)`` mask of its greedy choices.

    The Q-tables' set (else the MDP's, else simlab's 16). The mask: the Q-tables' saved
    ``valid``; for Q-tables without one (older files) the MDP's ``valid`` repeated per
    goal; none for Q-tables trained under the ``self-loop`` rule.
    """
    from simlab.actions import SIMLAB16

    if qt is not None:
        action_set = qt.action_set
    else:
        action_set = SIMLAB16 if model is None else model.action_set
    if qt is None or _trained_self_loop(qt):
        return action_set, None
    if qt.valid is not None:
        return action_set, qt.valid
    if model is not None and model.valid is not None:
        return action_set, np.repeat(model.valid[None], qt.Q.shape[0], axis=0)
    return action_set, None


def _comparison(summary: dict[str, Any], policy: str) -> dict[str, Any]:
    rate = summary["result"]["rate_per_hour"]
    out: dict[str, Any] = {"rate_per_hour": rate}
    base = summary.get("random_baseline")
    if base is not None:
        out["random_rate_per_hour"] = base["rate_per_hour"]
        out["ratio_to_random"] = rate / base["rate_per_hour"] if base["rate_per_hour"] else None
    pred = (summary.get("prediction") or {}).get(policy)
    if pred is not None:
        p = pred["rate_per_hour"]
        out["predicted_rate_per_hour"] = p
        out["measured_over_predicted"] = rate / p if p else None
        out["within_25_percent"] = bool(p) and abs(rate / p - 1.0) <= 0.25
        per_tr = summary["result"]["reward_per_transition"]
        q = pred["reward_per_transition"]
        out["reward_per_transition_measured_over_predicted"] = per_tr / q if q else None
        e = pred.get("expected_rewards_over_horizon")
        if e is not None:
            out["rewards_measured_over_expected_over_horizon"] = (
                summary["result"]["rewards"] / e if e > 0 else None)
        if pred["n_closed_classes"] > 1:
            out["warning"] = (f"the MDP's chain has {pred['n_closed_classes']} closed classes "
                              "reachable from the start: its long-run rate depends on which "
                              "one the robot falls into (often states whose actions the "
                              "dataset never tried); collect more data")
    return out


def _write_transitions(path: Path, log: ReplayLog, goal_names: tuple[str, ...]) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    cols: dict[str, Any] = {
        "t": log.t, "duration": log.duration, "s": log.s, "a": log.a, "s_next": log.s_next,
        "goal": np.asarray(goal_names, dtype=object)[log.goal] if log.n else np.array([], str),
        "reward": log.reward, "blocked": log.blocked, "s_true_next": log.s_true_next,
    }
    for prefix, arr in (("true", log.truth_before), ("true_next", log.truth_after),
                        ("est", log.est_before), ("est_next", log.est_after),
                        ("odom_next", log.odom_after)):
        for i, axis in enumerate(("x", "y", "yaw")):
            cols[f"{axis}_{prefix}"] = arr[:, i]
    table = pa.table({k: pa.array(v) for k, v in cols.items()})
    with atomic_write(path, "wb") as fh:
        pq.write_table(table, fh)


def _write_localization(path: Path, mcl_log: Any) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    cols = {"t": mcl_log.t}
    for prefix, arr in (("true", mcl_log.truth), ("est", mcl_log.estimate)):
        for i, axis in enumerate(("x", "y", "yaw")):
            cols[f"{axis}_{prefix}"] = arr[:, i]
    cols["position_error"] = mcl_log.position_error
    cols["heading_error"] = mcl_log.heading_error
    cols["position_std"] = mcl_log.spread[:, 0]
    cols["heading_std"] = mcl_log.spread[:, 1]
    cols["fit"] = mcl_log.fit
    cols["injected"] = mcl_log.injected
    table = pa.table({k: pa.array(np.asarray(v)) for k, v in cols.items()})
    with atomic_write(path, "wb") as fh:
        pq.write_table(table, fh)


def _plot(path: Path, run: RunOutcome, baseline: RunOutcome | None, summary: dict[str, Any],
          policy: str, pose_source: str) -> None:
    from simlab.replay.plots import RewardCurve, plot_cumulative_reward

    curves = [RewardCurve(f"{policy} policy ({pose_source}): "
                          f"{summary['result']['rate_per_hour']:.1f} /h",
                          run.log.reward_times, run.robot_seconds)]
    if baseline is not None:
        curves.append(RewardCurve(f"random policy (physics): "
                                  f"{summary['random_baseline']['rate_per_hour']:.1f} /h",
                                  baseline.log.reward_times, baseline.robot_seconds))
    predicted = []
    pred = summary.get("prediction") or {}
    for name in (policy, "random") if policy == "greedy" else (policy,):
        if name in pred:
            predicted.append((f"MDP-predicted, {name}: {pred[name]['rate_per_hour']:.1f} /h",
                              pred[name]["rate_per_hour"]))
    plot_cumulative_reward(path, curves, predicted, hours=summary["hours"],
                           title=f"{summary['arena']}: cumulative reward over "
                                 f"{summary['hours']:g} h of robot time")


def _write_video(files: dict[str, Path], run: RunOutcome, arena: Any, disc: Any, qt: Any,
                 goal_names: tuple[str, ...], grid: Any, max_frames: int) -> None:
    from simlab.physics.robot import load_robot_spec
    from simlab.replay.video import ReplayCanvas, write_video

    canvas = ReplayCanvas(arena, load_robot_spec(), disc.centres, None if qt is None else qt.Q,
                          goal_names, grid, action_set=None if qt is None else qt.action_set,
                          valid=None if qt is None else _qt_valid(qt))
    trail = np.vstack([run.log.truth_before[:1], run.log.truth_after]) if run.log.n else \
        np.asarray(arena.start, dtype=np.float64)[None]
    records = run.frames
    if len(records) > max_frames:  # the stride was set from an estimate: thin evenly
        keep = np.unique(np.linspace(0, len(records) - 1, max_frames).round().astype(int))
        records = [records[i] for i in keep]
    frames = [canvas.render(f, trail) for f in records]
    if not frames:
        return
    write_video(files["gif"], frames)
    if "mp4" in files:
        write_video(files["mp4"], frames)
