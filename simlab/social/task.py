"""The social task on the table: a TurtleBot and a kinematic human (thesis, Future directions:
a social task for the TurtleBot with a human drawn on the interactive screen).

:class:`SocialTable` runs the grid's social module (thesis 2.1.2, paper Fig. 4)
with the robot in PyBullet and the human of :mod:`simlab.social.human`. One decision
step, in the grid's order (``simlab.visitlab.dynamics.social_step``, thesis variant),
re-stated here on continuous poses:

1. **Percepts** of the observed state (:func:`simlab.social.perception.percepts`, line of
   sight by a ray test): percept level 0-4, distance class, angle. Appropriate = class 1-3.
2. **Attention** (thesis 2.1.2): an engaged human (level >= 5) disengages when the
   distance is not appropriate, or with probability L_H (one draw per engaged step); the
   level falls back to the percept level.
3. **Social actions** (thesis 2.1.2, Table 2.2): HELLO at level 3 or 4 with an
   appropriate distance -> 5; at level 3 it fails with probability F_H (one draw), at
   level 4 it always succeeds. COME at 5 -> 7 with probability 1 - P_H, else 6 (one
   draw). POINTING at 6 -> 7. Any other use does nothing.
4. **The robot acts** (:mod:`simlab.social.actions`): a primitive (blocked by the
   human's disc in its corridor, ``human_blocks``); STAY or a signal
   (``signal_time`` s standing still); LOOK_H (turn to face the human); GO_TO_HUMAN only
   if the human is not engaged after 2: drives to ``gth_cells`` cells ahead of the human's
   gaze, then turns to face the human (decision: the grid leaves a random orientation,
   since its option does not choose one; a physical robot that walked up to someone
   faces them).
5. **The human reacts**: engaged -> it looks at the robot; at level 7, unless the robot
   signalled (HELLO/COME/POINTING), it walks toward where it saw the robot at the start of
   the step at a speed drawn from s_H, stopping ``follow_gap`` before the robot, then
   looks at it again (:func:`simlab.social.human.follow_step`). Not engaged: random
   move / turn (:func:`simlab.social.human.idle_step`).
6. **Reward** +1 if the level is 7 and the human moved (>= 1 mm) in the required
   direction of the observed state (the displacement's nearest direction).
7. With probability ``redraw_p`` (paper: 0.2) a new required direction (uniform of 8).

Randomness: ``reset(seed)`` spawns two streams from ``SeedSequence(seed)``: the task's
(placements, human, attention, required direction) and the physics noise (LIDAR noise of
the primitives' obstacle checks). Same seed and actions -> the same observations.

Time: every decision adds the primitive parameters' ``decision_latency`` to the
simulated time beside what was stepped (or ``signal_time`` for STAY and the signals).

**The robot's own pose estimate** (``SocialConfig.pose_source``, names of
:data:`simlab.localization.sources.POSE_SOURCES`): the robot's side of perception (its
bearing to the human -> ``angle``, the distance -> distance class, its orientation ->
"R looks at H") is computed from the pose the robot believes it has, the human's side
(does the human see / look at the robot) and the line of sight from the true poses
(:func:`simlab.social.perception.robot_percepts`). Decision: the human's map position is
known to the robot (as on the grid, where "the robot knows where the human is"), so the
estimate error moves the robot's percepts, not the human's; the required direction (the
human's position -> the goal, :mod:`simlab.social.closedloop`) does not involve the
robot's pose and is not affected. The *dynamics* (attention, HELLO's level and
distance conditions) follow the true percepts: a human answers to where the robot is,
not to where it believes it is; the observation is the robot's. LOOK_H turns by the
angle the robot believes separates its heading from the human's bearing. GO_TO_HUMAN's
drive and the primitives run on the true pose, as the navigation primitives do. With
``"truth"`` (default) nothing changes (bit for bit).

**Paper rules 4-6** (the code published with Chartouny et al. 2024; ``SocialConfig.rules = "paper"`` or one by one, as the
grid's paper variant, :mod:`simlab.visitlab.dynamics`):

* ``gaze_before_move`` (rule 4): in 5 an engaged human's orientation aims at the
  robot's position *before* the robot's move (where it walks to) and is not re-aimed
  after the human walks; thesis: it looks at the robot after the robot's move and again
  after walking.
* ``gth_before_attention`` (rule 5): GO_TO_HUMAN works only if the human was not engaged
  before this step's attention check (2); thesis: if not engaged after 2. The paper also
  lets the robot land on the human's cell: two bodies cannot share a place, so here the
  target is still kept clear of the human (``min_separation``).
* ``idle_turn_all`` (rule 6): a random turn of an idle human draws among all 8
  orientations, the current one included (one integer 0-7); thesis: among the 7 others.
  The rest of rule 6 (robot and human may share a cell, moves ignore the other) has no
  physics meaning: two bodies never overlap, so walking stops short of the robot as
  before.

**The human's body** (``SocialConfig.human_body``): ``"disc"`` (default) has no PyBullet
body; ``"turtlebot"`` loads a second TurtleBot (the robot's URDF, fixed base) and moves it
kinematically to the human's pose whenever that changes, so the robot's LIDAR, obstacle
detector and contacts see it; rays cast from the human's centre (line of sight, walking,
GO_TO_HUMAN's target) ignore its own body.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from simlab.base import validation
from simlab.base.actions import HEADINGS
from simlab.base.errors import ConfigError
from simlab.localization.sources import POSE_SOURCES, make_pose_source
from simlab.physics.driver import DecisionDriver
from simlab.physics.motion import N_ACTIONS, PrimitiveParams, ScanStepper
from simlab.physics.robot import wrap_angle
from simlab.physics.world import World
from simlab.social.actions import (
    N_SOCIAL_ACTIONS,
    SIGNALS,
    SocialAction,
    execute_social_primitive,
    go_to_point,
    turn_to,
)
from simlab.social.human import HumanBody, follow_step, idle_step, is_free, look_at, random_pose
from simlab.social.perception import (
    Percepts,
    SocialPerception,
    bearing,
    line_of_sight,
    percepts,
    robot_percepts,
    social_obs_index,
)
from simlab.visitlab.humans import Human
from simlab.visitlab.humans import human as human_preset

Pose = NDArray[np.float64]

#: Rule sets of the physics social task (module docstring, paper rules 4-6).
RULES = ("thesis", "paper")
#: Bodies of the human.
HUMAN_BODIES = ("disc", "turtlebot")
_PAPER_RULES = ("gaze_before_move", "gth_before_attention", "idle_turn_all")


@dataclass(frozen=True)
class SocialConfig:
    """Settings of the physics social task.

    Attributes:
        arena: built-in arena name or TOML path.
        human: a preset name of :mod:`simlab.visitlab.humans` or a :class:`Human`.
        body: geometry of the projected human (cell size, radius, gaps; m).
        perception: fields (deg) and distance bounds (m).
        primitives: parameters of the motion primitives (and the decision latency).
        signal_time: decision time (s) of STAY, HELLO, COME and POINTING.
        redraw_p: per-step probability of redrawing the required direction (paper 0.2).
        gth_cells: GO_TO_HUMAN's target distance ahead of the human's gaze, in cells.
        gth_tolerance: distance (m) at which GO_TO_HUMAN's drive counts as arrived.
        gth_max_primitives: most primitives one GO_TO_HUMAN may drive.
        gth_offsets_deg: angles (deg) off the human's gaze at which GO_TO_HUMAN tries its
            target, in order, until one leaves room (default ``(0,)``: straight ahead
            only, as on the grid). E.g. ``(0, 30, -30)`` lets a robot walk up to a human
            who faces a wall from the side (it may end in the visual field, level 3,
            when the wall keeps it from the target).
        human_blocks: the human's disc blocks a primitive whose detector corridor it meets
            (the robot turns, does not drive), and GO_TO_HUMAN detours around it; the
            human has no PyBullet body, so the LIDAR itself never sees it.
        pose_source: the robot's pose estimate for its side of perception (module
            docstring): ``"truth"`` (default), ``"odometry"`` or ``"mcl"``.
        pose_source_options: keyword arguments of the ``mcl`` source
            (:func:`simlab.localization.sources.make_pose_source`); empty otherwise.
        rules: ``"thesis"`` (default) or ``"paper"``: the default of the three rule
            switches below (module docstring, paper rules 4-6).
        gaze_before_move, gth_before_attention, idle_turn_all: paper rules 4, 5 and 6
            one by one (None: as ``rules`` says).
        human_body: ``"disc"`` (default: no PyBullet body) or ``"turtlebot"`` (a second
            TurtleBot moved kinematically; module docstring). Choose a ``body`` whose
            ``min_separation``/``follow_gap`` keep two TurtleBots apart (their swept
            radii are 0.12 m each): the defaults (0.16/0.25 m) let them touch.
    """

    arena: str = "table"
    human: str | Human = "easy"
    body: HumanBody = field(default_factory=HumanBody)
    perception: SocialPerception = field(default_factory=SocialPerception)
    primitives: PrimitiveParams = field(default_factory=PrimitiveParams)
    signal_time: float = 1.0
    redraw_p: float = 0.2
    gth_cells: float = 2.0
    gth_tolerance: float = 0.05
    gth_max_primitives: int = 30
    gth_offsets_deg: tuple[float, ...] = (0.0,)
    human_blocks: bool = True
    pose_source: str = "truth"
    pose_source_options: Mapping[str, Any] = field(default_factory=dict)
    rules: str = "thesis"
    gaze_before_move: bool | None = None
    gth_before_attention: bool | None = None
    idle_turn_all: bool | None = None
    human_body: str = "disc"

    def __post_init__(self) -> None:
        object.__setattr__(self, "human", human_preset(self.human))
        validation.choice(self.pose_source, POSE_SOURCES, "SocialConfig.pose_source")
        object.__setattr__(self, "pose_source_options", dict(self.pose_source_options))
        validation.choice(self.rules, RULES, "SocialConfig.rules")
        validation.choice(self.human_body, HUMAN_BODIES, "SocialConfig.human_body")
        for key in _PAPER_RULES:
            value = getattr(self, key)
            if value is None:
                object.__setattr__(self, key, self.rules == "paper")
            else:
                validation.boolean(value, f"SocialConfig.{key}")
        validation.positive(self.signal_time, "SocialConfig.signal_time", allow_zero=True)
        validation.probability(self.redraw_p, "SocialConfig.redraw_p")
        validation.positive(self.gth_cells, "SocialConfig.gth_cells")
        validation.positive(self.gth_tolerance, "SocialConfig.gth_tolerance")
        validation.boolean(self.human_blocks, "SocialConfig.human_blocks")
        validation.whole(self.gth_max_primitives, "SocialConfig.gth_max_primitives", minimum=1)
        offsets = tuple(validation.number(v, "SocialConfig.gth_offsets_deg", low=-180.0,
                                          high=180.0) for v in self.gth_offsets_deg)
        if not offsets:
            raise ConfigError("expected at least one angle", key="SocialConfig.gth_offsets_deg",
                              fix="e.g. (0.0,)")
        object.__setattr__(self, "gth_offsets_deg", offsets)
        for key, kind in (("body", HumanBody), ("perception", SocialPerception),
                          ("primitives", PrimitiveParams)):
            if not isinstance(getattr(self, key), kind):
                raise ConfigError(f"expected a {kind.__name__}, got {getattr(self, key)!r}",
                                  key=f"SocialConfig.{key}")


@dataclass(frozen=True)
class SocialStepInfo:
    """What one step did: ``level`` the interaction level after it (0-7),
    ``percepts`` after it, ``moved`` the human's direction (-1: stayed), ``duration``
    simulated seconds (stepped + latency or signal time), ``blocked`` a primitive was
    blocked, ``robot_pose`` and ``human_pose`` (3,) after it, ``time`` the total (s)."""

    level: int
    percepts: Percepts
    moved: int
    duration: float
    blocked: bool
    robot_pose: Pose
    human_pose: Pose
    time: float


class PoseEstimate(Protocol):
    """What the robot believes its pose is: :meth:`now` (3,) (x, y, yaw; m, m, rad) at any
    time. ``on_scan``/``scan_beams``: the LIDAR hook of a filter (None: no scans needed).
    :meth:`reset` is called after every world reset with the estimate's own Generator."""

    on_scan: Any
    scan_beams: NDArray[np.int64] | None

    def reset(self, world: Any, rng: np.random.Generator) -> None: ...

    def now(self) -> Pose: ...


class SourceEstimate:
    """A pose source of :mod:`simlab.localization.sources` read at any time, not only after
    a primitive: ``truth`` the true pose, ``odometry`` the wheel odometry now, ``mcl`` the
    filter's last estimate carried forward by the odometry now (as the replay reads it)."""

    def __init__(self, name: str, world: Any, options: Mapping[str, Any] | None = None
                 ) -> None:
        self.name = validation.choice(name, POSE_SOURCES, "pose_source")
        self.world = world
        self.source = (make_pose_source(name, world, dict(options or {}))
                       if name == "mcl" else None)
        self.on_scan: Any = None
        self.scan_beams: NDArray[np.int64] | None = None

    def reset(self, world: Any, rng: np.random.Generator) -> None:
        self.world = world
        if self.source is not None:
            self.source.reset(world, rng)
            self.on_scan = self.source.on_scan
            self.scan_beams = self.source.scan_beams

    def now(self) -> Pose:
        if self.name == "truth":
            return self.world.pose()
        odom = self.world.odometry()
        if self.name == "odometry":
            return np.asarray(odom, dtype=float)
        return np.asarray(self.source.tracker.pose(odom), dtype=float)  # type: ignore[union-attr]


class SocialTable:
    """The robot and a human on the table (module docstring). Call :meth:`reset` first.

    ``world``: an existing :class:`~simlab.physics.world.World` (not closed by this
    object), else one is built from ``config.arena``, stepping at ``physics_hz``
    (:func:`simlab.physics.rate.resolve_rate`), and closed by :meth:`close`.
    ``pose_estimate``: the robot's pose estimate (a :class:`PoseEstimate`, e.g. a test
    stub); default the config's ``pose_source`` (none for ``"truth"``: the true pose).
    """

    n_actions = N_SOCIAL_ACTIONS

    def __init__(self, config: SocialConfig | None = None, world: World | None = None, *,
                 pose_estimate: PoseEstimate | None = None,
                 physics_hz: float | None = None) -> None:
        from simlab.physics.rate import resolve_rate

        self.config = config or SocialConfig()
        self._own_world = world is None
        if world is not None and physics_hz is not None:
            raise ConfigError("give the world or its rate, not both", key="physics_hz",
                              fix="build the World with physics_hz=")
        self.world = world if world is not None else World(
            self.config.arena, physics_hz=resolve_rate(physics_hz))
        if pose_estimate is None and self.config.pose_source != "truth":
            pose_estimate = SourceEstimate(self.config.pose_source, self.world,
                                           self.config.pose_source_options)
        self._estimate = pose_estimate
        #: PyBullet body id of the human's TurtleBot (``human_body="turtlebot"``), else None
        self.human_body_id: int | None = None
        self._human_inertial = np.zeros(3)
        self.human_pose: Pose = np.zeros(3)
        self.engaged = 0
        self.required_direction = 0
        self.time = 0.0
        self._rng: np.random.Generator | None = None
        self._noise: np.random.Generator | None = None

    # ------------------------------------------------------------------ lifecycle
    def close(self) -> None:
        if self._own_world:
            self.world.close()

    def __enter__(self) -> SocialTable:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def reset(self, seed: int, robot_pose: Pose | None = None,
              human_pose: Pose | None = None) -> int:
        """New episode; returns the social observation (0-2559).

        Random (when not given): the robot's position uniform on the free table (kept its
        swept radius from walls and obstacles) with one of the 8 headings, the human's
        (:func:`~simlab.social.human.random_pose`), the required direction. Human not
        engaged. A pose estimate restarts at the true pose with a third stream of
        ``SeedSequence(seed)`` (the first two are unchanged by it).
        """
        task_seq, noise_seq, estimate_seq = np.random.SeedSequence(seed).spawn(3)
        self._rng = rng = np.random.default_rng(task_seq)
        self._noise = np.random.default_rng(noise_seq)
        w = self.world
        if robot_pose is None:
            robot_pose = self._random_robot_pose(rng)
        w.reset(np.asarray(robot_pose, dtype=float))
        if self._estimate is None:
            self.driver = DecisionDriver(w, self.config.primitives)
        else:
            self._estimate.reset(w, np.random.default_rng(estimate_seq))
            self.driver = DecisionDriver(w, self.config.primitives,
                                         on_scan=self._estimate.on_scan,
                                         scan_beams=self._estimate.scan_beams)
        if human_pose is None:
            human_pose = random_pose(w, rng, self.config.body, avoid_xy=w.pose()[:2])
        self.human_pose = np.array(human_pose, dtype=float)
        if self.human_pose.shape != (3,) or not np.all(np.isfinite(self.human_pose)):
            raise ValueError(f"human_pose must be 3 finite numbers (x, y, theta), got "
                             f"{human_pose!r}")
        self.human_body_id = None
        if self.config.human_body == "turtlebot":
            self._load_human_body()
        self.required_direction = int(rng.integers(0, 8))
        self.engaged = 0
        self.time = 0.0
        return self.observation()

    def _random_robot_pose(self, rng: np.random.Generator) -> Pose:
        a = self.world.arena
        clearance = self.world.robot_spec.swept_radius + 0.02
        for _ in range(1000):
            x = a.center[0] + rng.uniform(-a.size[0] / 2, a.size[0] / 2)
            y = a.center[1] + rng.uniform(-a.size[1] / 2, a.size[1] / 2)
            if is_free(a, (x, y), clearance):
                return np.array([x, y, float(HEADINGS[int(rng.integers(0, 8))])])
        raise ConfigError("no free robot position found", key="arena")

    def _load_human_body(self) -> None:
        """The human's TurtleBot: the robot's URDF with a fixed base (moved kinematically)."""
        from simlab.physics.urdf_merge import merged_urdf_path

        c = self.world.client
        self.human_body_id = int(c.loadURDF(
            str(merged_urdf_path(self.world.robot_spec.urdf_path)),
            basePosition=[float(self.human_pose[0]), float(self.human_pose[1]), 0.0],
            useFixedBase=True))
        self._human_inertial = np.asarray(c.getDynamicsInfo(self.human_body_id, -1)[3],
                                          dtype=float)
        self.sync_human_body()

    def sync_human_body(self) -> None:
        """Move the human's TurtleBot (if any) to :attr:`human_pose` (its base frame, the
        floor under the axle, at the human's position and orientation) and refresh the
        collision world so ray tests and scans see it at once."""
        if self.human_body_id is None:
            return
        c = self.world.client
        x, y, th = (float(v) for v in self.human_pose)
        orn = c.getQuaternionFromEuler([0.0, 0.0, th])
        rot = np.asarray(c.getMatrixFromQuaternion(orn), dtype=float).reshape(3, 3)
        com = np.array([x, y, 0.0]) + rot @ self._human_inertial
        c.resetBasePositionAndOrientation(self.human_body_id, com.tolist(), orn)
        c.performCollisionDetection()

    # ------------------------------------------------------------------ perception
    def true_percepts(self) -> Percepts:
        """Percepts from the true poses (ray-tested line of sight); the dynamics use these."""
        robot = self.world.pose()
        visible = line_of_sight(self.world, self.human_pose[:2], robot[:2],
                                ignore=self.human_body_id)
        return percepts(robot, self.human_pose, visible, self.config.perception)

    def robot_pose_estimate(self) -> Pose:
        """The pose (3,) the robot believes it has (the true pose with ``"truth"``)."""
        if self._estimate is None:
            return self.world.pose()
        return np.asarray(self._estimate.now(), dtype=float)

    def percepts(self) -> Percepts:
        """The robot's percepts of the current state: its side from its pose estimate,
        the human's side from the truth (module docstring); all truth with ``"truth"``."""
        truth = self.true_percepts()
        if self._estimate is None:
            return truth
        return robot_percepts(self.robot_pose_estimate(), self.human_pose, truth,
                              self.config.perception)

    def level(self, perc: Percepts | None = None) -> int:
        """Interaction level 0-7: the engagement (5-7) if engaged, else the percept level."""
        return self.engaged if self.engaged >= 5 else (perc or self.percepts()).level

    def observation(self, perc: Percepts | None = None) -> int:
        """Social observation 0-2559 (the grid's index)."""
        perc = perc or self.percepts()
        return social_obs_index(self.level(perc), perc.distance_class,
                                self.required_direction, perc.angle)

    # ------------------------------------------------------------------ step
    def step(self, action: int) -> tuple[int, float, SocialStepInfo]:
        """One decision (module docstring); returns (observation, reward, info)."""
        if self._rng is None:
            raise RuntimeError("call reset(seed) before step()")
        a = int(action)
        if not 0 <= a < N_SOCIAL_ACTIONS:
            raise ValueError(f"action must be in 0..{N_SOCIAL_ACTIONS - 1}, got {action}")
        rng, hp, cfg = self._rng, self.config.human, self.config
        engaged_before = self.engaged
        e = self._attention(self.true_percepts(), a, rng, hp)
        robot_before = self.world.pose()
        duration, blocked = self._robot_acts(a, e, engaged_before)
        robot_after = self.world.pose()
        moved = -1
        if e >= 5:
            look_at(self.human_pose, (robot_before if cfg.gaze_before_move else robot_after)[:2])
            if e == 7 and a not in SIGNALS:
                self.human_pose, moved = follow_step(
                    self.world, self.human_pose, robot_before[:2], robot_after[:2], hp,
                    cfg.body, rng, look=not cfg.gaze_before_move, ignore=self.human_body_id)
        else:
            self.human_pose, moved = idle_step(self.world, self.human_pose, hp, cfg.body,
                                               robot_after[:2], rng, turn_all=cfg.idle_turn_all,
                                               ignore=self.human_body_id)
        self.sync_human_body()
        self.engaged = e
        reward = 1.0 if (e == 7 and moved == self.required_direction) else 0.0
        if rng.random() < self.config.redraw_p:
            self.required_direction = int(rng.integers(0, 8))
        self.time += duration
        after = self.percepts()
        info = SocialStepInfo(level=self.level(after), percepts=after, moved=moved,
                              duration=duration, blocked=blocked, robot_pose=robot_after,
                              human_pose=self.human_pose.copy(), time=self.time)
        return self.observation(after), reward, info

    def _attention(self, perc: Percepts, a: int, rng: np.random.Generator, hp: Human) -> int:
        """Steps 2 and 3: the engagement after attention loss and the social action."""
        e = self.engaged
        if e >= 5 and (rng.random() < hp.lose_attention or not perc.appropriate):
            e = 0
        level = e if e >= 5 else perc.level
        if a == SocialAction.HELLO:
            if level in (3, 4) and perc.appropriate:
                u = rng.random()
                if level == 4 or u >= hp.fail_hello:
                    e = 5
        elif a == SocialAction.COME:
            if e == 5:
                e = 7 if rng.random() >= hp.pointing_need else 6
        elif a == SocialAction.POINTING and e == 6:
            e = 7
        return e

    def _stepper(self) -> ScanStepper:
        """A stepper for motion outside the primitives (feeds a filter's scans)."""
        return ScanStepper(self.world, self._noise, self.driver.on_scan, self.driver.scan_beams)

    def _look_target(self) -> float:
        """LOOK_H's map-frame heading (rad): the bearing to the human; with a pose estimate
        the true heading turned by the angle the robot believes is left."""
        w = self.world
        if self._estimate is None:
            return bearing(w.pose(), self.human_pose)
        est = self.robot_pose_estimate()
        return w.yaw() + float(wrap_angle(bearing(est, self.human_pose) - est[2]))

    def _robot_acts(self, a: int, e: int, engaged_before: int = 0) -> tuple[float, bool]:
        """Step 4; returns (simulated seconds, blocked). ``engaged_before``: the
        engagement before the attention check (paper rule 5)."""
        cfg, w = self.config, self.world
        latency = cfg.primitives.decision_latency
        if a < N_ACTIONS:
            t, blocked = execute_social_primitive(
                self.driver, a, self._noise, self.human_pose[:2] if cfg.human_blocks else None,
                cfg.body.radius)
            return t + latency, blocked
        if a == SocialAction.LOOK_H:
            t = turn_to(w, self._look_target(), cfg.primitives, self._stepper())
            self.driver.observe()
            return t + latency, False
        if a == SocialAction.GO_TO_HUMAN:
            if (engaged_before if cfg.gth_before_attention else e) >= 5:
                return cfg.signal_time + latency, False
            return self._go_to_human(), False
        return cfg.signal_time + latency, False

    def _go_to_human(self) -> float:
        """GO_TO_HUMAN's drive and turn; returns the simulated seconds. The target lies
        ``gth_cells`` cells along the human's gaze (turned by the first of
        ``gth_offsets_deg`` that leaves room), brought back by walls or obstacles on
        that line (one LIDAR-plane ray) to keep the robot's swept radius clear of them; if
        less than ``min_separation + gth_tolerance`` is left on every line (the human
        faces a wall) nothing happens, as
        on the grid when the landing cell is the human's own."""
        cfg, w = self.config, self.world
        target = None
        for offset in cfg.gth_offsets_deg:
            target = self._gth_target(float(self.human_pose[2]) + math.radians(offset))
            if target is not None:
                break
        if target is None:
            return cfg.signal_time + cfg.primitives.decision_latency
        res = go_to_point(self.driver, target, self._noise, cfg.gth_tolerance,
                          cfg.gth_max_primitives,
                          self.human_pose[:2] if cfg.human_blocks else None, cfg.body.radius)
        t = turn_to(w, bearing(w.pose(), self.human_pose), cfg.primitives, self._stepper())
        self.driver.observe()
        return res.duration + t + cfg.primitives.decision_latency

    def _gth_target(self, theta: float) -> Pose | None:
        """GO_TO_HUMAN's target along the line from the human at angle ``theta`` (rad), or
        None if it leaves too little room."""
        cfg, w = self.config, self.world
        u = np.array([math.cos(theta), math.sin(theta)])
        dist = cfg.gth_cells * cfg.body.cell_size
        clear = w.robot_spec.swept_radius + 0.02
        z = float(w.robot_spec.lidar_offset[2])
        start = self.human_pose[:2]
        end = start + (dist + clear) * u
        hit = w.client.rayTest([start[0], start[1], z], [end[0], end[1], z])[0]
        if hit[0] >= 0 and hit[0] not in (w.body, self.human_body_id):
            dist = min(dist, hit[2] * (dist + clear) - clear)
        if dist < cfg.body.min_separation + cfg.gth_tolerance:
            return None
        return start + dist * u
