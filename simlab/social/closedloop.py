"""The combined Visit-the-lab architecture closed loop in physics (thesis 3.1.1, Fig. 3.1).

The grid's combined architecture (:mod:`simlab.visitlab.combined`) re-stated on the table
with the robot in PyBullet and the kinematic human of :mod:`simlab.social`. Every decision:

1. **Required direction** (:func:`goal_direction`): the heading from the *human's*
   position to the centre of the current goal area, quantised to the nearest of the 8
   directions (:func:`simlab.social.perception.quantise_direction`). Decision: not a
   navigation Q-table of ``simlab train``. Such a table is indexed by the *robot's*
   empirical state (its LIDAR/pose cell), so evaluating it at the human's position needs a
   state for a pose where no robot stands (no scan), and it needs a dataset and an
   estimated MDP per goal: minutes of physics for every run. On the open table the
   straight heading is what an optimal navigation policy yields (no obstacle to go around,
   goal areas are discs). When the straight line from the human to the goal centre is
   blocked (a disc of the human's radius swept along it meets a wall or obstacle,
   :func:`simlab.social.planning.segment_free`, analytic as the planner's free grid),
   the required direction is the first leg of
   :func:`simlab.social.planning.plan_path` from the human's position (clearance: the
   human's radius) instead (:func:`simlab.social.planning.first_leg_bearing`), so the
   human is led around the obstacle; without a path, the straight heading. On the open
   table the line is never blocked (both ends lie in the convex free floor), so nothing
   changes there.
2. **Social module**: the grid social Q-table (``(2560, 30)``, trained with
   :func:`simlab.visitlab.training.train` on ``"social"``) read through
   :func:`simlab.social.actions.grid_q_to_physics` (``(2560, 22)``) at the physics social
   observation whose required direction is the one of step 1; greedy, ties broken
   uniformly at random (unvisited states are all ties: a uniform choice there).
   Decision (``skip_idle``, default on): an action that left everything as it was (the
   same observation, the robot and the human within 5 mm and 2 deg) or whose
   primitive was blocked is not chosen again until the observation changes; the next
   best is taken. A greedy table otherwise repeats a no-op forever (e.g. driving into
   the human standing in the required direction, which on the grid's rarely visited
   states was never learned). Decision (``epsilon``, default 0.05): with that
   probability the action is uniform over the 22 instead (one draw of the policy stream
   per decision, then one more for the action). The greedy table alone cycles for hours
   through a few states the grid never meets (a physics step is a third of a cell, the
   follower stops 0.25 m short), e.g. the robot trapped in a corner by the following
   human, stepping back and forth. Measured, 6 seeds x 0.25 h, goals reached with the
   human (random policy: 4): greedy 22, epsilon 0.05: 41, 0.1: 35; a tabu memory
   (skip actions already chosen at a revisited observation) got 10.
3. **Delegation**: GO_TO_HUMAN is the physics option of :class:`SocialTable` (planned
   drive into the human's facing field; the default tries 0, +30, -30 deg off the gaze,
   ``SocialConfig.gth_offsets_deg``, so a human facing a wall can still be approached).
   Decision: no go-to-human Q-table; on the grid the
   option needs one because the grid has no planner, here the planner is the module.
4. **World step**: :meth:`SocialTable.step` with ``redraw_p = 0`` (the required direction
   comes from navigation, as on the grid).
5. **Goal switch**: when the human's centre lies inside the goal area while it is engaged
   (interaction level >= 5 after the step), one goal is counted ("reached with the
   human") and a new goal is drawn uniformly among the other goal areas.

The baseline picks uniformly among the 22 physics actions instead of step 2, with the same
seed: the same table placements, the same first goal. A run is one continuous episode of
``hours`` simulated hours (no resets: the robot must re-engage the human itself).

Randomness: :meth:`SocialTable.reset` gets ``seed``; the policy's and the goals'
draws come from ``SeedSequence([seed, 1])`` (policy) and ``SeedSequence([seed, 2])``
(goals). Same seed -> the same run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from simlab.base import validation
from simlab.base.errors import ConfigError
from simlab.physics.arena import ArenaConfig, GoalArea
from simlab.social.actions import N_SOCIAL_ACTIONS, grid_q_to_physics
from simlab.social.perception import bearing, quantise_direction
from simlab.social.planning import first_leg_bearing, segment_free
from simlab.social.task import SocialConfig, SocialTable


@dataclass(frozen=True)
class ClosedLoopConfig:
    """Settings of the closed loop.

    Attributes:
        social: the physics social task; its ``redraw_p`` is forced to 0.
        goals: names of the goal areas used (empty: every goal area of the arena).
        engaged_level: lowest interaction level counted as "with the human" (5: engaged,
            the social module's HELLO succeeded; the grid counts any level).
        max_decisions: safety cap on decisions per run (0: none; the run stops at
            ``hours``).
        skip_idle: do not repeat an action that changed nothing (module docstring).
        epsilon: probability of a uniformly random action instead of the social module's
            (module docstring, step 2); 0 is the pure greedy table.
    """

    social: SocialConfig = field(
        default_factory=lambda: SocialConfig(gth_offsets_deg=(0.0, 30.0, -30.0)))
    goals: tuple[str, ...] = ()
    engaged_level: int = 5
    max_decisions: int = 0
    skip_idle: bool = True
    epsilon: float = 0.05

    def __post_init__(self) -> None:
        if not isinstance(self.social, SocialConfig):
            raise ConfigError(f"expected a SocialConfig, got {self.social!r}",
                              key="ClosedLoopConfig.social")
        object.__setattr__(self, "social", replace(self.social, redraw_p=0.0))
        object.__setattr__(self, "goals", tuple(str(g) for g in self.goals))
        validation.whole(self.engaged_level, "ClosedLoopConfig.engaged_level", minimum=5)
        if self.engaged_level > 7:
            raise ConfigError(f"must be 5, 6 or 7, got {self.engaged_level}",
                              key="ClosedLoopConfig.engaged_level")
        validation.whole(self.max_decisions, "ClosedLoopConfig.max_decisions", minimum=0)
        validation.boolean(self.skip_idle, "ClosedLoopConfig.skip_idle")
        validation.probability(self.epsilon, "ClosedLoopConfig.epsilon")


@dataclass
class ClosedLoopRun:
    """One run. Per decision (length n): ``time`` simulated s after it, ``action``
    0-21, ``level`` 0-7, ``goal`` index into ``goal_names`` of the goal pursued during it,
    ``robot`` and ``human`` poses (n, 3) after it. ``goal_times`` (s) of each goal
    reached with the human; ``social_reward`` the social module's reward summed."""

    policy: str
    seed: int
    goal_names: tuple[str, ...]
    time: NDArray[np.float64]
    action: NDArray[np.int64]
    level: NDArray[np.int64]
    goal: NDArray[np.int64]
    robot: NDArray[np.float64]
    human: NDArray[np.float64]
    goal_times: NDArray[np.float64]
    social_reward: float
    start_robot: NDArray[np.float64]
    start_human: NDArray[np.float64]

    @property
    def goals_reached(self) -> int:
        return int(self.goal_times.size)

    @property
    def hours(self) -> float:
        """Simulated hours run."""
        return float(self.time[-1]) / 3600.0 if self.time.size else 0.0

    def summary(self) -> dict[str, float | int | str]:
        """JSON-ready figures of the run."""
        n = int(self.time.size)
        return {"policy": self.policy, "seed": self.seed, "decisions": n,
                "simulated_hours": round(self.hours, 6),
                "goals_reached": self.goals_reached,
                "goals_per_hour": round(self.goals_reached / self.hours, 4) if n else 0.0,
                "social_reward": self.social_reward,
                "social_reward_per_decision": round(self.social_reward / n, 6) if n else 0.0,
                "engaged_fraction": round(float(np.mean(self.level >= 5)), 6) if n else 0.0}


def goal_direction(human_xy: NDArray[np.float64], goal: GoalArea,
                   arena: ArenaConfig | None = None, clearance: float = 0.0) -> int:
    """Required direction 0-7: the heading from ``human_xy`` (m) to the goal's centre,
    quantised (module docstring, step 1). With ``arena``: the first leg of the planned
    path around walls and obstacles (kept ``clearance`` m away) when the straight line
    is blocked."""
    centre = np.array([goal.x, goal.y])
    if arena is not None and not segment_free(arena, human_xy, centre, clearance):
        leg = first_leg_bearing(arena, human_xy, centre, clearance)
        if leg is not None:
            return quantise_direction(leg)
    return quantise_direction(bearing(human_xy, centre))


def select_goals(arena: ArenaConfig, names: tuple[str, ...] = ()) -> tuple[GoalArea, ...]:
    """The goal areas named (all of the arena's when empty); at least two are needed."""
    goals = tuple(arena.goal(n) for n in names) if names else tuple(arena.goals)
    if len(goals) < 2:
        raise ConfigError(f"the closed loop switches goals and needs at least 2, got "
                          f"{len(goals)}", key="goals", fix="name two or more goal areas")
    return goals


def _next_goal(goals: tuple[GoalArea, ...], human_xy: NDArray[np.float64], exclude: int,
               rng: np.random.Generator) -> int:
    """Uniform among the goals other than ``exclude`` not containing the human (one draw);
    all but ``exclude`` if the human is in every other one."""
    cands = [i for i, g in enumerate(goals) if i != exclude and not bool(g.contains(human_xy))]
    if not cands:
        cands = [i for i in range(len(goals)) if i != exclude]
    return cands[int(rng.integers(0, len(cands)))]


def _greedy(q_row: NDArray[np.float64], rng: np.random.Generator,
            excluded: set[int] | frozenset[int] = frozenset()) -> int:
    if excluded and len(excluded) < q_row.size:
        q_row = q_row.copy()
        q_row[list(excluded)] = -np.inf
    best = np.flatnonzero(q_row == q_row.max())
    return int(best[0]) if best.size == 1 else int(best[int(rng.integers(0, best.size))])


def _unchanged(before: NDArray[np.float64], after: NDArray[np.float64]) -> bool:
    """A pose (x, y, angle) moved less than 5 mm and turned less than 2 deg."""
    turn = abs(math.remainder(float(after[2]) - float(before[2]), 2.0 * math.pi))
    return bool(math.hypot(*(after[:2] - before[:2])) < 5e-3 and turn < math.radians(2.0))


def run_closed_loop(q_social: NDArray[np.float64] | None, seed: int, hours: float,
                    config: ClosedLoopConfig | None = None,
                    table: SocialTable | None = None) -> ClosedLoopRun:
    """Run the combined architecture (or the random baseline) for ``hours`` simulated hours.

    Args:
        q_social: a grid social Q-table ``(2560, 30)`` or an already mapped ``(2560, 22)``;
            None runs the uniform random policy over the 22 actions.
        seed: root seed (module docstring).
        hours: simulated hours (> 0); the run stops at the first decision ending past it.
        config: settings (default :class:`ClosedLoopConfig`).
        table: an existing task to reuse (its config must equal ``config.social``); else
            one is built and closed here.
    """
    cfg = config or ClosedLoopConfig()
    validation.positive(hours, "hours")
    validation.whole(seed, "seed", minimum=0)
    q = None
    if q_social is not None:
        q = np.asarray(q_social, dtype=float)
        q = grid_q_to_physics(q) if q.shape[-1] == 30 else q
        if q.shape != (2560, N_SOCIAL_ACTIONS):
            raise ValueError(f"expected a (2560, 30) or (2560, 22) Q-table, got {q.shape}")
    own = table is None
    env = SocialTable(cfg.social) if own else table
    if not own and env.config != cfg.social:
        raise ValueError("table.config must equal config.social (redraw_p = 0)")
    try:
        return _loop(env, q, seed, hours, cfg)
    finally:
        if own:
            env.close()


def _loop(env: SocialTable, q: NDArray[np.float64] | None, seed: int, hours: float,
          cfg: ClosedLoopConfig) -> ClosedLoopRun:
    goals = select_goals(env.world.arena, cfg.goals)
    env.reset(seed)
    policy_rng = np.random.default_rng(np.random.SeedSequence([seed, 1]))
    goal_rng = np.random.default_rng(np.random.SeedSequence([seed, 2]))
    start_robot, start_human = env.world.pose().copy(), env.human_pose.copy()
    g = _next_goal(goals, env.human_pose[:2], -1, goal_rng)
    rec: dict[str, list] = {k: [] for k in ("time", "action", "level", "goal", "robot",
                                            "human")}
    goal_times: list[float] = []
    social_reward, limit = 0.0, hours * 3600.0
    excluded: set[int] = set()
    last_obs = -1
    while env.time < limit and not (cfg.max_decisions and len(rec["time"]) >= cfg.max_decisions):
        env.required_direction = goal_direction(env.human_pose[:2], goals[g], env.world.arena,
                                                env.config.body.radius)
        obs = env.observation()
        if obs != last_obs:
            excluded.clear()
        last_obs = obs
        robot0, human0 = env.world.pose().copy(), env.human_pose.copy()
        if q is None or (cfg.epsilon and policy_rng.random() < cfg.epsilon):
            a = int(policy_rng.integers(0, N_SOCIAL_ACTIONS))
        else:
            a = _greedy(q[obs], policy_rng, excluded if cfg.skip_idle else frozenset())
        new_obs, reward, info = env.step(a)
        if info.blocked or (new_obs == obs and _unchanged(robot0, info.robot_pose)
                            and _unchanged(human0, info.human_pose)):
            excluded.add(a)
        social_reward += reward
        for key, value in (("time", info.time), ("action", a), ("level", info.level),
                           ("goal", g), ("robot", info.robot_pose), ("human", info.human_pose)):
            rec[key].append(value)
        if env.engaged >= cfg.engaged_level and bool(goals[g].contains(env.human_pose[:2])):
            goal_times.append(info.time)
            g = _next_goal(goals, env.human_pose[:2], g, goal_rng)
    return ClosedLoopRun(
        policy="random" if q is None else "combined", seed=int(seed),
        goal_names=tuple(x.name for x in goals), time=np.asarray(rec["time"], dtype=float),
        action=np.asarray(rec["action"], dtype=np.int64),
        level=np.asarray(rec["level"], dtype=np.int64),
        goal=np.asarray(rec["goal"], dtype=np.int64),
        robot=np.asarray(rec["robot"], dtype=float).reshape(-1, 3),
        human=np.asarray(rec["human"], dtype=float).reshape(-1, 3),
        goal_times=np.asarray(goal_times, dtype=float), social_reward=float(social_reward),
        start_robot=start_robot, start_human=start_human)


def goal_rate_ratio(learned: list[ClosedLoopRun], random: list[ClosedLoopRun]) -> float:
    """Goals per simulated hour of ``learned`` over ``random`` (pooled over runs; inf if the
    random runs reached none)."""
    def rate(runs: list[ClosedLoopRun]) -> float:
        return sum(r.goals_reached for r in runs) / max(sum(r.hours for r in runs), 1e-12)
    lr, rr = rate(learned), rate(random)
    return math.inf if rr == 0 else lr / rr


def closed_loop_frames(run: ClosedLoopRun, config: ClosedLoopConfig | None = None,
                       start: int = 0, count: int = 120, stride: int = 1,
                       pixels_per_metre: float = 200.0, trail: int = 20
                       ) -> list[NDArray[np.uint8]]:
    """RGB frames (HEADER_PX + H, W, 3) of decisions ``start, start + stride, ...`` of
    ``run`` (at most ``count``; frame 0 is the state before decision ``start``): the table
    with the pursued goal highlighted, the human with its visual/facing fields and its last
    ``trail`` positions, the robot; the caption gives time, level, action, goals reached."""
    from simlab.physics.arena import load_arena
    from simlab.physics.robot import load_robot_spec
    from simlab.social.render import LoopFrame, LoopScene, closed_loop_frame

    cfg = config or ClosedLoopConfig()
    validation.whole(count, "count", minimum=1)
    validation.whole(stride, "stride", minimum=1)
    validation.whole(start, "start", minimum=0)
    scene = LoopScene(load_arena(cfg.social.arena), load_robot_spec("turtlebot3_burger"),
                      cfg.social.body, cfg.social.perception, pixels_per_metre,
                      cfg.social.human_body)
    n = run.time.size
    robots = np.vstack([run.start_robot[None], run.robot])
    humans = np.vstack([run.start_human[None], run.human])
    levels = np.concatenate([[0], run.level])
    frames = []
    for k in range(min(start, n), n + 1, stride):
        if len(frames) >= count:
            break
        goal = run.goal_names[int(run.goal[min(k, n - 1)])] if n else None
        reached = int(np.searchsorted(run.goal_times, run.time[k - 1], side="right")) if k else 0
        t = float(run.time[k - 1]) if k else 0.0
        act = f" a={int(run.action[k - 1])}" if k else ""
        caption = (f"{run.policy} t={t:7.1f}s level={int(levels[k])}{act} goal={goal} "
                   f"reached={reached}")
        frames.append(closed_loop_frame(LoopFrame(scene, robots[k], humans[k], int(levels[k]),
                                                  goal, caption,
                                                  humans[max(0, k - trail):k + 1, :2])))
    return frames


def write_closed_loop_gif(frames: list[NDArray[np.uint8]], path: str | Path,
                          fps: float = 4.0) -> Path:
    """Write ``frames`` as a looping GIF at ``path`` atomically (:func:`simlab.base.io.atomic_write`;
    an existing file is replaced: callers check with :func:`simlab.base.io.ensure_new`)."""
    import imageio.v3 as iio

    from simlab.base.io import atomic_write

    if not frames:
        raise ValueError("no frames to write")
    validation.positive(fps, "fps")
    path = Path(path)
    with atomic_write(path, "wb") as fh:
        iio.imwrite(fh, np.stack(frames), extension=".gif", duration=1000.0 / fps, loop=0)
    return path
