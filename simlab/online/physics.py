"""Online learning in physics: the meta-controlled agent drives the robot decision by decision.

The robot is the dataset walk's (:class:`~simlab.data.walkers.PhysicsWalker`): the same
primitives (simlab's 16, or a real robot's 8 through its action set), the same obstacle
detector and the same pose model (truth, the particle filter, or the calibrated twin's
localization error), so a twin calibrated by ``simlab calibrate`` learns online exactly
as it walks for its dataset. The agent calls are those of the fused MDP loop
(:mod:`simlab.online.loop`), in the same order::

    a, e, ... = meta.decide(agent, s, agent_rng)     # criterion, planning, action
    out       = walker.step(primitive[a], noise_rng) # rotate, detect, drive, pose
    s'        = the discretizer's state of the believed pose after it
    r         = 1 if s' is in the current goal else 0
    meta.learn(agent, s, a, r, s')

Decisions (the protocol of Dromnelle et al. 2022, sec. 4.1, on simlab's arena):

* after a reward the robot is put back at the centre of a start state drawn with
  ``env_rng`` (keeping its heading; :meth:`~simlab.data.walkers.PhysicsWalker.place`): the
  published robot restarted from a start state; simlab does not spend simulated time
  driving it there. Its localization restarts at the pose it is put down at. A centre
  where the robot does not fit at that heading (in or against an obstacle, or a box added
  mid-run) puts it down at the nearest place of the state where it fits
  (:func:`simlab.base.statecheck.start_in_state`, the rule of ``collect``'s walks).
* the believed pose is the walker's pose source: ``truth`` (with the primitives' own
  localization error when they have one, as a calibrated twin does) or ``mcl``, a particle
  filter on the arena's map fed by the primitives' LIDAR scans.
* changes at a decision: ``goal`` (the goal states move), ``box`` (a box is added to the
  running world with :func:`simlab.physics.obstacles.add_box`: the LIDAR sees it from the
  next scan, the obstacle detector blocks moves into it; the agent is not told) or
  ``passages`` (a box on the doorway of each passage ``u <-> v``,
  :func:`simlab.online.doorway.doorway`). With ``mcl`` the map the filter localizes
  against is then either ``updated`` with the box (someone edited the lab's map) or left
  ``stale`` (the map of the empty lab: the box's returns do not match it, as for a real
  robot whose map predates the obstacle).
* a passage is closed by a box (``closing = "box"``, the lab closed physically) or, with
  ``closing = "remove"``, as the published experiment closed it: its transitions removed
  from the model and the rows renormalised over what is left (Dromnelle et al. 2022,
  sec. 4.1; :func:`simlab.online.task.close_passages`). In physics a move that ends across
  a removed passage (``u -> v`` or ``v -> u`` between believed states) is taken back (the
  robot set down where it started, its localization as it was) and drawn again with fresh
  noise, so the move's outcomes are the twin's own, renormalised; after
  :data:`REDRAWS` redraws that all cross, the robot stays (the self-loop
  ``close_passages`` makes of a row with nothing left). The world is not otherwise
  changed (no box for the LIDAR or the detector), as in the edited model. Truth pose only.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from simlab.base.errors import ConfigError
from simlab.online import meta
from simlab.online.loop import OnlineLog

__all__ = ["MCL_MAPS", "POSE_SOURCES", "PhysicsChange", "PhysicsLab", "PhysicsRun",
           "PhysicsTask", "RunStreams", "children", "run_physics_online"]

#: Pose sources of the physics runs, and what the MCL's map does when a box is added.
POSE_SOURCES = ("truth", "mcl")
MCL_MAPS = ("updated", "stale")
CHANGE_KINDS = ("goal", "box", "passages")
#: How a passage closes (module docstring).
CLOSINGS = ("box", "remove")
#: Redraws of a move across a removed passage before the robot stays (module docstring).
REDRAWS = 10
#: Height (m) of a box added mid-run: above the LIDAR plane, as the arena's walls.
BOX_HEIGHT = 0.25


@dataclass(frozen=True)
class PhysicsChange:
    """A change at decision ``at`` (0-based): ``kind`` ``goal`` (new ``goal`` states),
    ``box`` (``box`` = ``(x, y, size_x, size_y)`` m, or with a fifth value its yaw in rad,
    added as a 0.25 m tall box) or ``passages`` (each passage ``(u, v)`` of ``passages``
    closed by ``closing``: a box on its doorway, or its transitions removed; module
    docstring)."""

    at: int
    kind: str
    goal: tuple[int, ...] = ()
    box: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)
    passages: tuple[tuple[int, int], ...] = ()
    use_states: tuple[int, ...] = ()
    closing: str = "box"

    def __post_init__(self) -> None:
        if self.closing not in CLOSINGS:
            raise ConfigError(f"unknown passage closing {self.closing!r}", key="closing",
                              fix=f"choose one of {', '.join(CLOSINGS)}")
        if self.kind not in CHANGE_KINDS:
            raise ConfigError(f"unknown change {self.kind!r}", key="change",
                              fix=f"choose one of {', '.join(CHANGE_KINDS)}")
        if self.kind == "goal" and not self.goal:
            raise ConfigError("a goal change needs the new goal state(s)", key="new_goal")
        if self.kind == "box" and len(self.box) not in (4, 5):
            raise ConfigError(f"expected (x, y, size_x, size_y[, yaw]), got {self.box!r}",
                              key="box")
        if self.kind == "passages" and not self.passages:
            raise ConfigError("a passage closing needs the passages", key="passages",
                              fix="e.g. passages = ['20-21', '6-7']")
        if self.use_states and (self.kind != "passages"
                                or len(self.use_states) != len(self.passages)):
            raise ConfigError(f"{len(self.use_states)} counting states for "
                              f"{len(self.passages)} passages", key="use_states",
                              fix="give one counting state per passage")

    def alternatives(self) -> int:
        """How many outcomes the change offers: one per passage when the more used one is
        closed (``use_states``), else 1."""
        return len(self.passages) if self.use_states else 1

    def closed(self, k: int) -> tuple[tuple[int, int], ...]:
        """The passages outcome ``k`` closes: the ``k``-th when the more used one is closed
        (``use_states``), else all of them."""
        return self.passages[k:k + 1] if self.use_states else self.passages

    def describe(self) -> str:
        if self.kind == "goal":
            return f"goal -> {'+'.join(map(str, self.goal))} at decision {self.at}"
        if self.kind == "passages":
            closed = (" or " if self.use_states else ", ").join(f"{u}<->{v}"
                                                                for u, v in self.passages)
            by_use = (f" (the more used: decisions in {'/'.join(map(str, self.use_states))})"
                      if self.use_states else "")
            how = "by boxes" if self.closing == "box" else "(transitions removed)"
            return f"passages {closed} closed {how}{by_use} at decision {self.at}"
        return f"box at ({self.box[0]:g}, {self.box[1]:g}) m added at decision {self.at}"


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
        if self.pose_source != "truth" and any(c.closing == "remove" for c in self.changes):
            raise ConfigError("a passage closed by removing its transitions takes moves back, "
                              f"which the {self.pose_source} pose source cannot follow",
                              key="closing", fix="use --pose-source truth or --closing box")

    def as_dict(self) -> dict[str, Any]:
        return {"goal": list(self.goal), "start_states": list(self.start_states),
                "pose_source": self.pose_source, "mcl_map": self.mcl_map,
                "changes": [{"at": c.at, "kind": c.kind, "goal": list(c.goal),
                             "box": list(c.box) if c.kind == "box" else [],
                             "passages": [list(p) for p in c.passages],
                             "use_states": list(c.use_states), "closing": c.closing}
                            for c in self.changes]}

    def check_states(self, n_states: int) -> None:
        """:class:`ConfigError` naming the field when a state is not in ``0..n_states-1``."""
        fields = [("goal", self.goal), ("start_states", self.start_states)]
        fields += [("new_goal", c.goal) for c in self.changes if c.kind == "goal"]
        for c in self.changes:
            if c.kind == "passages":
                fields.append(("passages", tuple(x for p in c.passages for x in p)))
                fields += [("use_states", c.use_states)] if c.use_states else []
        for key, states in fields:
            bad = [s for s in states if not 0 <= int(s) < n_states]
            if bad or not states:
                raise ConfigError(f"expected states in 0..{n_states - 1}, got {list(states)}",
                                  key=key)


@dataclass(frozen=True)
class PhysicsLab:
    """The robot and its world (they travel together to a worker): the ``arena``
    (:class:`~simlab.physics.arena.ArenaConfig`), the states' ``discretizer``, the
    primitive ``params`` (:class:`~simlab.physics.motion.PrimitiveParams`), the simlab
    ``primitives`` (A,) the agent's actions drive (all 16 by default; a real robot's 8
    through its action set), the ``pose_source_options`` of the ``mcl`` source and the
    world's ``physics_hz`` (None: :data:`simlab.physics.rate.DEFAULT_HZ`)."""

    arena: Any
    discretizer: Any
    params: Any
    primitives: tuple[int, ...] = tuple(range(16))
    pose_source_options: dict[str, Any] = field(default_factory=dict)
    physics_hz: float | None = None

    @property
    def n_states(self) -> int:
        return int(self.discretizer.n_states)

    @property
    def n_actions(self) -> int:
        return len(self.primitives)

    def walker(self, pose_source: str) -> Any:
        """A fresh :class:`~simlab.data.walkers.PhysicsWalker` of this lab (its own world)."""
        from simlab.data.walkers import PhysicsWalker

        return PhysicsWalker(self.arena, self.params, pose_source,
                             dict(self.pose_source_options), self.discretizer,
                             physics_hz=self.physics_hz)

    def boxes_of(self, change: PhysicsChange) -> list[list[tuple[float, ...]]]:
        """The boxes ``(x, y, size_x, size_y, yaw)`` each outcome of a change adds: one
        list per alternative (one per passage when the more used is closed; else a single
        list, empty for ``goal``)."""
        from simlab.online.doorway import doorway

        if change.kind == "box":
            return [[tuple(change.box) + (0.0,) * (5 - len(change.box))]]
        if change.kind != "passages" or change.closing == "remove":
            return [[]] * change.alternatives()
        d = self.discretizer
        doors = {p: doorway(self.arena.occupied, d.state_of, np.asarray(d.centres), *p)
                 for p in change.passages}
        return [[(doors[p].x, doors[p].y, doors[p].length, doors[p].thickness, doors[p].yaw)
                 for p in change.closed(k)] for k in range(change.alternatives())]


@dataclass(frozen=True)
class RunStreams:
    """The random streams of one run: ``env`` (start states), ``agent`` (the agent's
    draws), ``noise`` (the primitives' noise), ``mcl`` (the pose source: the particle
    filter, the twin's localization error)."""

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
    :class:`~simlab.online.loop.OnlineLog`, with its ``restarts`` and ``use_counts``), per
    decision ``blocked`` (n,) bool, the simulated ``duration`` (n,) s (primitive and
    decision latency; 0 for the published goal decision, whose move is the restart), the
    true position after it ``xy`` (n, 2) m and ``undone`` (n,) the moves taken back across
    a removed passage (the last attempt's duration is the decision's); ``robot_seconds``
    simulated, ``wall_seconds``, ``boxes`` the boxes added ``(x, y, size_x, size_y, yaw)``,
    ``mcl_field`` the :class:`~simlab.localization.likelihood.LikelihoodField` the filter
    used last (None for ``truth``)."""

    log: OnlineLog
    blocked: np.ndarray
    duration: np.ndarray
    xy: np.ndarray
    undone: np.ndarray
    robot_seconds: float
    wall_seconds: float
    boxes: list[tuple[float, ...]] = field(default_factory=list)
    mcl_field: Any = None

    def columns(self) -> dict[str, np.ndarray]:
        """The log's columns and the physics' own (``blocked``, ``duration``, ``x``, ``y``,
        ``undone``),
        and the run's ``restarts`` and ``use_counts``."""
        return {**self.log.columns(), "blocked": self.blocked, "duration": self.duration,
                "x": self.xy[:, 0], "y": self.xy[:, 1], "undone": self.undone,
                "restarts": np.asarray(self.log.restarts, dtype=np.int64),
                "use_counts": self.log.use_counts}


class _Lab:
    """One run's world: the walker, the state of a believed pose, the boxes added."""

    def __init__(self, lab: PhysicsLab, task: PhysicsTask, streams: RunStreams) -> None:
        from simlab.data.walkers import point_state_of

        self.lab, self.task, self.streams = lab, task, streams
        self.walker = lab.walker(task.pose_source)
        self.point_state = point_state_of(lab.discretizer)
        self.centres = np.asarray(lab.discretizer.centres, dtype=float)
        self.starts = np.asarray(task.start_states, dtype=np.int64)
        self.boxes: list[tuple[float, ...]] = []
        self.arena = lab.arena
        self.walker.reset(None, streams.mcl)

    def state(self, pose: np.ndarray) -> int:
        return int(self.point_state(float(pose[0]), float(pose[1])))

    def restart(self, state: int = -1) -> int:
        """The robot put down at the centre of ``state`` (-1: a start state drawn from the
        ``env`` stream), keeping its heading, or where it fits nearest to the centre in the
        state (module docstring); the state of its believed pose there."""
        from simlab.base.statecheck import start_in_state

        s0 = int(self.starts[self.streams.env.integers(0, self.starts.size)]) if state < 0 \
            else int(state)
        yaw = float(self.walker.world.pose()[2])
        footprint = self.walker.world.robot_spec.footprint
        xy = start_in_state(s0, self.lab.discretizer, self.arena, footprint, yaw)
        if xy is None:  # not at this heading (the setup checked +x), or a box covers the cell
            yaw = 0.0
            xy = start_in_state(s0, self.lab.discretizer, self.arena, footprint) \
                or (float(self.centres[s0, 0]), float(self.centres[s0, 1]))
        self.walker.place(np.array([xy[0], xy[1], yaw]), self.streams.mcl)
        return self.state(self.walker.believed_pose())

    def move(self, s: int, primitive: int, rng: np.random.Generator, cut: np.ndarray
             ) -> tuple[Any, int, int]:
        """One primitive from believed state ``s``: its outcome, the believed state after it
        and how many moves were taken back because they crossed a removed passage
        (``cut[s, s']``; module docstring)."""
        if not cut[s].any():
            out = self.walker.step(primitive, rng)
            return out, self.state(out.pose_after), 0
        held = self.walker.hold()
        for undone in range(REDRAWS + 1):
            out = self.walker.step(primitive, rng)
            s_next = self.state(out.pose_after)
            if not cut[s, s_next]:
                return out, s_next, undone
            self.walker.undo(held)
        return (dataclasses.replace(out, blocked=True, truth_after=out.truth_before,
                                    pose_after=out.pose_before), s, REDRAWS + 1)

    def add_box(self, box: tuple[float, ...]) -> None:
        """A box joins the running world; the filter's map follows it when ``updated``."""
        from simlab.physics.obstacles import add_box, arena_with_box

        x, y, sx, sy, yaw = box
        add_box(self.walker.world, x, y, (sx, sy), height=BOX_HEIGHT, yaw=yaw)
        self.boxes.append(box)
        self.arena = arena_with_box(self.arena, x, y, (sx, sy), height=BOX_HEIGHT, yaw=yaw)
        source = self.walker.source
        if getattr(source, "tracker", None) is None or self.task.mcl_map == "stale":
            return
        from simlab.localization.likelihood import LikelihoodField
        from simlab.localization.maps import arena_map

        source.field = LikelihoodField(arena_map(self.arena), source.params.sensor)
        source.tracker.filter.set_field(source.field)

    def close(self) -> None:
        self.walker.close()


class _Agent:
    """``meta.decide`` / ``meta.learn`` compiled once for this agent's types.

    Decision: a call of a numba dispatcher from Python first computes the numba type of
    every argument; for the nested records of a :class:`~simlab.online.meta.MetaAgent`
    that costs far more than the decision itself (measured: ~6 ms of dispatch against
    ~0.09 ms of work per decision and learning step, 38 states x 8 actions). The fused
    MDP loop pays it once per run; here each decision is a Python call, so the entry
    points of the two kernels are compiled (or loaded from numba's cache) for the types
    of this run's arguments once, and called directly.
    """

    def __init__(self, agent: meta.MetaAgent, rng: np.random.Generator) -> None:
        from numba import typeof, types

        ta = typeof(agent)
        self.agent, self.rng = agent, rng
        self._decide = meta.decide.compile((ta, types.int64, typeof(rng)))
        self._learn = meta.learn.compile((ta, types.int64, types.int64, types.float64,
                                          types.int64))

    def decide(self, s: int) -> tuple[Any, ...]:
        return self._decide(self.agent, int(s), self.rng)

    def learn(self, s: int, a: int, r: float, s_next: int) -> None:
        self._learn(self.agent, int(s), int(a), float(r), int(s_next))

    def phantom_start(self, s: int) -> None:
        """The published run's fictitious previous decision in its first state ``s``:
        ``(s, 0, 0, s)`` learned, ``s`` counted as visited (:mod:`simlab.online.loop`)."""
        self.learn(s, 0, 0.0, s)
        self.agent.seen[s] = True


def _check(agent: meta.MetaAgent, lab: PhysicsLab, task: PhysicsTask) -> None:
    S, A = lab.n_states, lab.n_actions
    if agent.mf.Q.shape != (S, A):
        raise ConfigError(f"the agent has {agent.mf.Q.shape} Q-tables; expected ({S}, {A}): "
                          "one row per state of the discretizer, one column per action",
                          key="agent")
    task.check_states(S)


class _Changes:
    """The task's changes as they happen: the phase index (an alternative chosen by use
    counts as its own phase, as in the MDP loop), the goal, the boxes each adds, and the
    decisions of the counting states (``use_counts``, one per phase, -1 where none);
    ``cut[s, s']`` the moves a removed passage takes back."""

    def __init__(self, lab: PhysicsLab, task: PhysicsTask) -> None:
        self.task = task
        self.pending = [(c, lab.boxes_of(c)) for c in task.changes]  # doorways found first
        self.n_states = lab.n_states
        self.use_counts = np.full(1 + sum(c.alternatives() for c in task.changes), -1,
                                  dtype=np.int64)
        self.rewind()

    def rewind(self) -> None:
        """Back to the task's start (a restart of the published protocol)."""
        self.todo = list(self.pending)
        self.phase, self.first = 0, 1
        self.goal = np.isin(np.arange(self.n_states), self.task.goal)
        self.cut = np.zeros((self.n_states, self.n_states), dtype=bool)

    def due(self, t: int, visits: np.ndarray, world: _Lab) -> None:
        """Apply every change due at decision ``t``."""
        while self.todo and self.todo[0][0].at <= t:
            c, outcomes = self.todo.pop(0)
            k = 0
            if c.use_states:
                counts = visits[list(c.use_states)]
                self.use_counts[self.first:self.first + counts.size] = counts
                k = int(np.argmax(counts))  # the first on ties
            self.phase = self.first + k
            self.first += c.alternatives()
            if c.kind == "goal":
                self.goal = np.isin(np.arange(self.n_states), c.goal)
            if c.kind == "passages" and c.closing == "remove":
                for u, v in c.closed(k):
                    self.cut[u, v] = self.cut[v, u] = True
            for box in outcomes[k]:
                world.add_box(box)


def run_physics_online(agent: meta.MetaAgent, lab: PhysicsLab, task: PhysicsTask,
                       streams: RunStreams, *, rules: Any = None,
                       progress: Any = None) -> PhysicsRun:
    """Let ``agent`` learn online for ``task.decisions`` decisions in a fresh world of
    ``lab`` (module docstring) under the environment ``rules``
    (:data:`~simlab.online.protocol.LoopRules`; default simlab's), as the MDP loop
    (:mod:`simlab.online.loop`) applies them. ``progress(k)``, when given, is told every
    decision made (k = 1); the agent learns in place."""
    from simlab.online.protocol import PROTOCOLS

    _check(agent, lab, task)
    rules = PROTOCOLS["simlab"].loop_rules(-1, -1) if rules is None else rules
    changes = _Changes(lab, task)
    n = int(task.decisions)
    log = OnlineLog.empty(n)
    blocked, duration, xy = np.zeros(n, dtype=bool), np.zeros(n), np.zeros((n, 2))
    undone = np.zeros(n, dtype=np.int64)
    visits = np.zeros(lab.n_states, dtype=np.int64)
    primitives = np.asarray(lab.primitives, dtype=np.int64)
    world = _Lab(lab, task, streams)
    calls = _Agent(agent, streams.agent)
    try:
        s = world.restart(rules.first_state)
        if rules.phantom_start:
            calls.phantom_start(s)
        t_wall0 = time.perf_counter()
        t, got, restarts = 0, 0.0, 0
        while t < n:
            changes.due(t, visits, world)
            a, e, h_mf, h_mb, c_mf, c_mb, backups, seconds = calls.decide(s)
            if rules.goal_decision and changes.goal[s]:  # the move from the goal: a restart
                s_next = world.restart()
                blocked[t], duration[t] = False, 0.0
            else:
                out, s_next, undone[t] = world.move(s, int(primitives[int(a)]), streams.noise,
                                                    changes.cut)
                blocked[t] = out.blocked
                duration[t] = out.duration + world.walker.decision_latency
            xy[t] = world.walker.world.pose()[:2]
            arrived = bool(changes.goal[s_next])
            r = 1.0 if arrived and t != rules.silent_at else 0.0
            calls.learn(s, a, r, s_next)
            for col, val in (("s", s), ("a", a), ("s_next", s_next), ("expert", e),
                             ("h_mf", h_mf), ("h_mb", h_mb), ("c_mf", c_mf), ("c_mb", c_mb),
                             ("backups", backups), ("seconds", seconds), ("reward", r),
                             ("phase", changes.phase)):
                getattr(log, col)[t] = val
            visits[s] += 1
            got += r
            t += 1
            s = world.restart() if arrived and not rules.goal_decision else s_next
            if t == rules.restart_after and got == 0.0 and restarts < rules.max_restarts:
                restarts, t = restarts + 1, 0
                changes.rewind()
                agent.seen[:] = False
                s = world.restart(rules.first_state)
                if rules.phantom_start:
                    calls.phantom_start(s)
            if progress is not None:
                progress(1)
        source = world.walker.source
        return PhysicsRun(log=dataclasses.replace(log, restarts=restarts,
                                                  use_counts=changes.use_counts),
                          blocked=blocked, duration=duration, xy=xy, undone=undone,
                          robot_seconds=float(duration.sum()),
                          wall_seconds=time.perf_counter() - t_wall0,
                          boxes=list(world.boxes), mcl_field=getattr(source, "field", None)
                          if task.pose_source == "mcl" else None)
    finally:
        world.close()
