"""Online learning in physics: the meta-controlled agent drives the robot decision by decision.

The decision step is the physics' :class:`~simlab.physics.driver.DecisionDriver` (the
replay's and the dataset walkers' step); the agent calls are those of the fused MDP loop
(:mod:`simlab.online.loop`), in the same order::

    a, e, ... = meta.decide(agent, s, agent_rng)     # criterion, planning, action
    step      = driver.execute(a, noise_rng)         # primitive (obstacle detector), pose
    s'        = the discretizer's state of the believed pose after it
    r         = 1 if s' is in the current goal else 0
    meta.learn(agent, s, a, r, s')

Decisions (the protocol of Dromnelle et al. 2022, sec. 4.1, on simlab's arena):

* after a reward the robot is put back at the centre of a start state drawn with
  ``env_rng`` (keeping its heading): the published robot restarted from a start state;
  simlab does not spend simulated time driving it there.
* pose source ``truth`` (default): the believed pose is the simulator's; the state noise of
  a real robot's localisation is left to the MDP half (its estimated ``T``). Pose source
  ``mcl``: a particle filter (:class:`~simlab.localization.tracker.MCLPoseSource`) on the
  arena's map, fed by the LIDAR scans of the primitives; after the teleport of a restart
  it restarts around the new pose (the robot is put down at a known start, as AMCL is
  given its initial pose), so the teleport never corrupts it.
* changes at a decision: ``goal`` (the goal states move) or ``box`` (a box is added to
  the running world with :func:`simlab.physics.obstacles.add_box`: the LIDAR sees it from
  the next scan, the obstacle detector blocks moves into it; the agent is not told).
  With ``mcl`` the map the filter localizes against is then either ``updated`` with the
  box (someone edited the lab's map) or left ``stale`` (the map of the empty lab: the
  box's returns do not match it, as for a real robot whose map predates the obstacle).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from simlab.base.errors import ConfigError
from simlab.online import meta
from simlab.online.loop import OnlineLog

__all__ = ["MCL_MAPS", "POSE_SOURCES", "PhysicsChange", "PhysicsRun", "PhysicsTask",
           "RunStreams", "children", "run_physics_online"]

#: Pose sources of the physics runs, and what the MCL's map does when a box is added.
POSE_SOURCES = ("truth", "mcl")
MCL_MAPS = ("updated", "stale")


@dataclass(frozen=True)
class PhysicsChange:
    """A change at decision ``at`` (0-based): ``kind`` ``goal`` (new ``goal`` states) or
    ``box`` (``box`` = ``(x, y, size_x, size_y)`` metres, added as a 0.25 m tall box)."""

    at: int
    kind: str
    goal: tuple[int, ...] = ()
    box: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if self.kind not in ("goal", "box"):
            raise ConfigError(f"unknown change {self.kind!r}", key="change",
                              fix="choose goal or box")
        if self.kind == "goal" and not self.goal:
            raise ConfigError("a goal change needs the new goal state(s)", key="new_goal")


@dataclass(frozen=True)
class PhysicsTask:
    """What a physics run does: ``goal`` and ``start_states`` (states of the discretizer),
    ``decisions``, the ``changes``, the ``pose_source`` (:data:`POSE_SOURCES`) and, for
    ``mcl``, whether its map is ``updated`` with an added box or left ``stale``
    (:data:`MCL_MAPS`)."""

    goal: tuple[int, ...]
    start_states: tuple[int, ...]
    decisions: int
    changes: tuple[PhysicsChange, ...] = ()
    pose_source: str = "truth"
    mcl_map: str = "updated"

    def __post_init__(self) -> None:
        if self.pose_source not in POSE_SOURCES:
            raise ConfigError(f"unknown pose source {self.pose_source!r}", key="pose_source",
                              fix=f"choose one of {', '.join(POSE_SOURCES)}")
        if self.mcl_map not in MCL_MAPS:
            raise ConfigError(f"unknown MCL map setting {self.mcl_map!r}", key="mcl_map",
                              fix=f"choose one of {', '.join(MCL_MAPS)}")
        object.__setattr__(self, "changes", tuple(sorted(self.changes, key=lambda c: c.at)))

    def check_states(self, n_states: int) -> None:
        """:class:`ConfigError` naming the field when a state is not in ``0..n_states-1``."""
        for key, states in (("goal", self.goal), ("start_states", self.start_states)):
            bad = [s for s in states if not 0 <= int(s) < n_states]
            if bad or not states:
                raise ConfigError(f"expected states in 0..{n_states - 1}, got {list(states)}",
                                  key=key)


@dataclass(frozen=True)
class RunStreams:
    """The random streams of one run: ``env`` (start states), ``agent`` (the agent's
    draws), ``noise`` (the primitives' noise), ``mcl`` (the particle filter)."""

    env: np.random.Generator
    agent: np.random.Generator
    noise: np.random.Generator
    mcl: np.random.Generator

    @classmethod
    def from_seed(cls, seed: np.random.SeedSequence) -> RunStreams:
        """The four streams of the children 0-3 of ``seed`` (:func:`children`)."""
        return cls(*(np.random.default_rng(s) for s in children(seed, 4)))


def children(seed: np.random.SeedSequence, n: int) -> list[np.random.SeedSequence]:
    """The first ``n`` children of ``seed``, as a fresh ``seed.spawn(n)`` gives them, without
    spawning: ``SeedSequence.spawn`` counts the children it has made, so one seed shared by
    the runs of several arms in one process would hand each arm other streams (and the
    results would depend on the executor). This is the same for every call."""
    return [np.random.SeedSequence(seed.entropy, spawn_key=(*seed.spawn_key, k),
                                   pool_size=seed.pool_size) for k in range(n)]


@dataclass
class PhysicsRun:
    """What :func:`run_physics_online` did: the decision ``log`` (the columns of
    :class:`~simlab.online.loop.OnlineLog`), ``blocked`` (n,) bool, ``robot_seconds``
    simulated, ``wall_seconds``, ``boxes`` the body ids added, ``mcl_field`` the
    :class:`~simlab.localization.likelihood.LikelihoodField` the filter used last (None
    for ``truth``)."""

    log: OnlineLog
    blocked: np.ndarray
    robot_seconds: float
    wall_seconds: float
    boxes: list[int] = field(default_factory=list)
    mcl_field: Any = None


class _Pose:
    """The run's pose source: the truth, or an MCL filter restarted at each restart."""

    def __init__(self, world: Any, task: PhysicsTask, rng: np.random.Generator) -> None:
        self.world, self.task, self.rng = world, task, rng
        self.mcl = None
        self.arena = world.arena
        if task.pose_source == "mcl":
            from simlab.localization.tracker import MCLPoseSource

            self.mcl = MCLPoseSource(world)
            self.mcl.reset(world, rng)

    def of(self, result: Any) -> np.ndarray:
        """The driver's ``pose_of``: after a primitive ``result``, or now for None."""
        if self.mcl is None:
            return self.world.pose()
        return self.mcl.tracker.pose(None if result is None else result.odom_after)

    def restarted(self) -> None:
        if self.mcl is not None:
            self.mcl.reset(self.world, self.rng)

    def box_added(self, box: tuple[float, float, float, float]) -> None:
        """A box joined the world: the filter's map follows it when ``updated``."""
        if self.mcl is None or self.task.mcl_map == "stale":
            return
        from simlab.localization.likelihood import LikelihoodField
        from simlab.localization.maps import arena_map
        from simlab.physics.obstacles import arena_with_box

        x, y, sx, sy = box
        self.arena = arena_with_box(self.arena, x, y, (sx, sy))
        self.mcl.field = LikelihoodField(arena_map(self.arena), self.mcl.params.sensor)
        self.mcl.tracker.filter.set_field(self.mcl.field)


def run_physics_online(agent: meta.MetaAgent, world: Any, discretizer: Any, task: PhysicsTask,
                       streams: RunStreams, *, params: Any = None) -> PhysicsRun:
    """Let ``agent`` (states of ``discretizer``, 16 primitive actions) learn online for
    ``task.decisions`` decisions in ``world`` (module docstring); ``params`` the
    :class:`~simlab.physics.motion.PrimitiveParams` (default: simlab's)."""
    from simlab.physics.driver import DecisionDriver
    from simlab.physics.motion import PrimitiveParams
    from simlab.physics.obstacles import add_box

    S = int(discretizer.n_states)
    if agent.mf.Q.shape != (S, 16):
        raise ConfigError(f"the agent has {agent.mf.Q.shape} Q-tables; expected ({S}, 16): "
                          "one row per state of the discretizer, one column per primitive",
                          key="agent")
    task.check_states(S)
    centres = np.asarray(discretizer.centres, dtype=float)

    def state_of(pose: np.ndarray) -> int:
        return int(discretizer.state_of(np.asarray(pose[:2], dtype=float)[None])[0])

    source = _Pose(world, task, streams.mcl)
    mcl = source.mcl
    driver = DecisionDriver(world, PrimitiveParams() if params is None else params,
                            pose_of=source.of, state_of=state_of,
                            on_scan=None if mcl is None else mcl.on_scan,
                            scan_beams=None if mcl is None else mcl.scan_beams)
    goal_mask = np.isin(np.arange(S), task.goal)
    pending = list(task.changes)
    n = int(task.decisions)
    log = OnlineLog.empty(n)
    blocked = np.zeros(n, dtype=bool)
    boxes: list[int] = []
    starts = np.asarray(task.start_states, dtype=np.int64)

    def restart() -> None:
        s0 = int(starts[streams.env.integers(0, starts.size)])
        world.set_pose((centres[s0, 0], centres[s0, 1], world.pose()[2]))
        source.restarted()
        driver.observe()

    restart()
    t_robot0, t_wall0 = world.time, time.perf_counter()
    phase = 0
    for t in range(n):
        while pending and pending[0].at <= t:
            c = pending.pop(0)
            phase += 1
            if c.kind == "goal":
                goal_mask = np.isin(np.arange(S), c.goal)
            else:
                boxes.append(add_box(world, c.box[0], c.box[1], (c.box[2], c.box[3])))
                source.box_added(c.box)
        s = int(driver.state)
        a, e, h_mf, h_mb, c_mf, c_mb, backups, seconds = meta.decide(agent, s, streams.agent)
        step = driver.execute(int(a), streams.noise)
        s_next = int(step.state_after)
        r = 1.0 if goal_mask[s_next] else 0.0
        meta.learn(agent, s, int(a), r, s_next)
        for col, val in (("s", s), ("a", a), ("s_next", s_next), ("expert", e), ("h_mf", h_mf),
                         ("h_mb", h_mb), ("c_mf", c_mf), ("c_mb", c_mb), ("backups", backups),
                         ("seconds", seconds), ("reward", r), ("phase", phase)):
            getattr(log, col)[t] = val
        blocked[t] = bool(step.result.blocked)
        if r > 0:
            restart()
    return PhysicsRun(log=log, blocked=blocked, robot_seconds=world.time - t_robot0,
                      wall_seconds=time.perf_counter() - t_wall0, boxes=boxes,
                      mcl_field=None if mcl is None else mcl.field)

