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
  simlab does not spend simulated time driving it there. Because that teleport would
  corrupt wheel odometry, the believed pose is the simulator's (``truth``); the state
  noise of a real robot's localisation is left to the MDP half (its estimated ``T``).
* changes at a decision: ``goal`` (the goal states move) or ``box`` (a box is added to
  the running world with :func:`simlab.physics.obstacles.add_box`: the LIDAR sees it from
  the next scan, the obstacle detector blocks moves into it; the agent is not told).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from simlab.base.errors import ConfigError
from simlab.online import meta
from simlab.online.loop import OnlineLog

__all__ = ["PhysicsChange", "PhysicsRun", "run_physics_online"]


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


@dataclass
class PhysicsRun:
    """What :func:`run_physics_online` did: the decision ``log`` (the columns of
    :class:`~simlab.online.loop.OnlineLog`), ``blocked`` (n,) bool, ``robot_seconds``
    simulated, ``wall_seconds``, ``boxes`` the body ids added."""

    log: OnlineLog
    blocked: np.ndarray
    robot_seconds: float
    wall_seconds: float
    boxes: list[int] = field(default_factory=list)


def run_physics_online(agent: meta.MetaAgent, world: Any, discretizer: Any, *,
                       goal: Sequence[int], start_states: Sequence[int], decisions: int,
                       params: Any = None, changes: Sequence[PhysicsChange] = (),
                       env_rng: np.random.Generator, agent_rng: np.random.Generator,
                       noise_rng: np.random.Generator) -> PhysicsRun:
    """Let ``agent`` (states of ``discretizer``, 16 primitive actions) learn online for
    ``decisions`` decisions in ``world`` (module docstring). Randomness: ``env_rng`` start
    states, ``agent_rng`` the agent's draws, ``noise_rng`` the primitives' noise."""
    from simlab.physics.driver import DecisionDriver
    from simlab.physics.motion import PrimitiveParams
    from simlab.physics.obstacles import add_box

    S = int(discretizer.n_states)
    if agent.mf.Q.shape != (S, 16):
        raise ConfigError(f"the agent has {agent.mf.Q.shape} Q-tables; expected ({S}, 16): "
                          "one row per state of the discretizer, one column per primitive",
                          key="agent")
    for key, states in (("goal", goal), ("start_states", start_states)):
        bad = [s for s in states if not 0 <= int(s) < S]
        if bad or not states:
            raise ConfigError(f"expected states in 0..{S - 1}, got {list(states)}", key=key)
    centres = np.asarray(discretizer.centres, dtype=float)

    def state_of(pose: np.ndarray) -> int:
        return int(discretizer.state_of(np.asarray(pose[:2], dtype=float)[None])[0])

    p = PrimitiveParams() if params is None else params
    driver = DecisionDriver(world, p, state_of=state_of)
    goal_mask = np.zeros(S, dtype=bool)
    goal_mask[list(goal)] = True
    pending = sorted(changes, key=lambda c: c.at)
    log = OnlineLog.empty(int(decisions))
    blocked = np.zeros(int(decisions), dtype=bool)
    boxes: list[int] = []
    starts = np.asarray(start_states, dtype=np.int64)

    def restart() -> None:
        s0 = int(starts[env_rng.integers(0, starts.size)])
        pose = world.pose()
        world.set_pose((centres[s0, 0], centres[s0, 1], pose[2]))
        driver.observe()

    restart()
    t_robot0, t_wall0 = world.time, time.perf_counter()
    phase = 0
    for t in range(int(decisions)):
        while pending and pending[0].at <= t:
            c = pending.pop(0)
            phase += 1
            if c.kind == "goal":
                goal_mask[:] = False
                goal_mask[list(c.goal)] = True
            else:
                x, y, sx, sy = c.box
                boxes.append(add_box(world, x, y, (sx, sy)))
        s = int(driver.state)
        a, e, h_mf, h_mb, c_mf, c_mb, backups, seconds = meta.decide(agent, s, agent_rng)
        step = driver.execute(int(a), noise_rng)
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
                      wall_seconds=time.perf_counter() - t_wall0, boxes=boxes)
