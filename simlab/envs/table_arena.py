"""``simlab/TableArena-v0``: the physics TurtleBot3 in an arena, acting by motion primitives.

The env card is the docstring of :class:`TableArenaEnv` (``help(env.unwrapped)`` shows it).
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.error import ClosedEnvironmentError

from simlab.base.actions import SIMLAB16, ActionSet
from simlab.base.errors import ConfigError
from simlab.physics.arena import ArenaConfig
from simlab.physics.driver import DecisionDriver
from simlab.physics.motion import PrimitiveParams
from simlab.physics.render import render_topdown
from simlab.physics.world import World

#: Observation variants of the LIDAR (see the env card).
LIDAR_MODES = ("finite", "raw")


def finite_scan(ranges: np.ndarray, range_max: float) -> tuple[np.ndarray, np.ndarray]:
    """``(ranges, valid)``: float32 ranges (n,) with every non-finite beam set to
    ``range_max`` (m), and the int8 validity mask (n,), 1 where the beam had a return."""
    r = np.asarray(ranges, dtype=np.float32)
    valid = np.isfinite(r)
    return np.where(valid, r, np.float32(range_max)).astype(np.float32), valid.astype(np.int8)


def rep117_scan(ranges: np.ndarray, hit: np.ndarray, range_min: float,
                range_max: float, near: np.ndarray | None = None) -> np.ndarray:
    """Float32 ranges (n,) in the convention of ROS REP 117 from noisy ranges (m), a hit
    mask (n,) bool (a return in ``[range_min, range_max]``) and ``near`` (n,) bool (a
    surface closer than ``range_min`` along the beam): ``-inf`` ("too close") for a near
    surface or a return read below ``range_min``, ``+inf`` for no return or one read
    beyond ``range_max``."""
    r = np.asarray(ranges, dtype=np.float64).copy()
    too_close = hit & (r < range_min)
    if near is not None:
        too_close |= ~hit & np.asarray(near, dtype=bool)
    far = ~hit | (r > range_max)
    r[far] = np.inf
    r[too_close] = -np.inf
    return r.astype(np.float32)


def near_surface(world: World, beams: np.ndarray) -> np.ndarray:
    """(k,) bool: whether beam ``beams`` (k,) of ``world``'s LIDAR meets a surface between
    the sensor centre and ``range_min`` (other than the robot itself).

    The simulated LDS-01 casts its rays from ``range_min`` outwards, as the real sensor
    sees nothing nearer, so a wall the robot stands against reads as no return; REP 117
    tells the two apart ("too close" is ``-inf``, nothing in range ``+inf``). One short
    ray per beam from the sensor centre in the base link's full 3-D pose, as the scan.
    """
    client, body, lidar = world.client, world.body, world.lidar
    com, orn = client.getBasePositionAndOrientation(body)
    rot = np.array(client.getMatrixFromQuaternion(orn), dtype=np.float64).reshape(3, 3)
    inertial = np.asarray(client.getDynamicsInfo(body, -1)[3], dtype=np.float64)
    origin = np.asarray(com, dtype=np.float64) - rot @ inertial + rot @ lidar.offset
    a = lidar.spec.angles[np.asarray(beams, dtype=np.int64)]
    dirs = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1) @ rot.T
    starts = np.repeat(origin[None, :], len(a), axis=0)
    results = client.rayTestBatch(starts, starts + lidar.spec.range_min * dirs)
    ids = np.fromiter((r[0] for r in results), dtype=np.int64, count=len(a))
    return (ids >= 0) & (ids != body)


class TableArenaEnv(gym.Env):
    """The physics TurtleBot3 in an arena, acting by motion primitives.

    * **Actions** ``Discrete(action_set.n_actions)``: by default (``action_set`` SIMLAB16)
      the thesis's 16 motion primitives, index = speed * 8 + direction (UP, DOWN, LEFT, RIGHT,
      UP-LEFT, UP-RIGHT, DOWN-LEFT, DOWN-RIGHT in the map frame; slow 0.10 m/s or fast
      0.22 m/s for 0.5 s), each preceded by the LIDAR obstacle check (see
      :mod:`simlab.physics.motion`). Another :class:`~simlab.base.actions.ActionSet` (e.g. a real
      robot's 8 actions numbered counter-clockwise from East) renumbers them: action ``a``
      executes the primitive ``action_set.to_primitive(a)``; ``info["primitive"]`` says which.
    * **Observation** ``Dict(pose=Box(3), lidar=Box(360), lidar_valid=MultiBinary(360))``
      (``lidar_mode="finite"``, the default): the true pose (x, y in metres, yaw in radians)
      after the primitive, a full 360-beam LIDAR scan (float32 metres in
      ``[0, range_max]``) in which every beam without a return in ``[range_min, range_max]``
      reads ``range_max`` (3.5 m), and ``lidar_valid`` (int8 0/1), 1 where the beam has a real
      return. Every observation is finite and inside its bounded space, so deep-RL libraries
      (PPO logits, observation normalisation) can use it as is. ``lidar_mode="raw"``
      gives the scanner's ranges in the convention of ROS REP 117 instead,
      ``Dict(pose, lidar=Box(-inf, inf))``: ``+inf`` for no return within ``range_max`` and
      ``-inf`` for "too close", a surface nearer than ``range_min`` (0.12 m) along the beam
      (the robot's own body excluded) or a noisy reading below ``range_min``.
    * **Goal-conditioned** ``goal_conditioned=True`` makes a :class:`GoalTableArenaEnv`
      (``desired_goal``/``achieved_goal`` keys and ``compute_reward``, see its card). Without
      it the env has no ``compute_reward``: Stable-Baselines3 and hindsight replay take any
      env with that method for a goal env.
    * **Reward** 1.0 when the robot ends the step inside the current goal area, else 0.0
      (thesis eq. 2.1).
    * **Id** ``gym.make("simlab:simlab/TableArena-v0")`` imports simlab first (Gymnasium's
      ``module:id`` form), so it also works in a fresh process, e.g. the workers of
      ``AsyncVectorEnv(..., context="spawn")``; ``gym.make("simlab/TableArena-v0")`` needs
      ``import simlab`` in that process first.
    * **Episode** starts at the arena's start pose (or ``options["pose"]``; where the robot
      does not fit, at the nearest place where it does, with a warning:
      :func:`simlab.base.statecheck.put_down`, the rule of every command) with a goal drawn
      uniformly from the arena's goal areas (or ``options["goal"]``); never terminates;
      truncated after ``max_steps`` primitives when ``max_steps`` is set (the registered id sets
      ``max_steps=None`` and registers ``max_episode_steps=50``, the thesis's 50-step trials,
      so Gymnasium's ``TimeLimit`` truncates and ``gym.make(id, max_episode_steps=N)`` works).
    * **Copies** ``copy.deepcopy`` and ``pickle`` rebuild a fresh PyBullet world from the
      env's configuration (never share the client), with the robot at rest at the copied
      pose, the same goal, step count and ``np_random`` state; the copy's odometry restarts
      at that pose. So ``AsyncVectorEnv`` and SB3 subprocess envs are independent. Using a
      closed env raises ``gymnasium.error.ClosedEnvironmentError``.
    * **Info** ``blocked``, ``duration`` (simulated s stepped), ``time`` (simulated s since
      reset, including the decision latency), ``goal``, ``odometry`` (3,).
    * **Physics** steps at ``physics_hz`` (default :data:`simlab.physics.rate.DEFAULT_HZ`,
      the rate of ``simlab collect`` and ``replay``; outside
      :data:`~simlab.physics.rate.MIN_HZ`-:data:`~simlab.physics.rate.MAX_HZ` is refused).
    * **Seeding** the LIDAR noise and the goal draw use ``self.np_random``; the physics is
      deterministic, so the same seed and actions give identical rollouts.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 4}

    def __new__(cls, *args: Any, **kwargs: Any) -> TableArenaEnv:
        # ``gym.make("simlab/TableArena-v0", goal_conditioned=True)`` builds the goal env:
        # only that one may carry compute_reward (SB3 takes any env that has it for a GoalEnv)
        if cls is TableArenaEnv and kwargs.get("goal_conditioned") is True:
            cls = GoalTableArenaEnv
        return super().__new__(cls)

    def __init__(
        self,
        arena: ArenaConfig | str = "table",
        *,
        goal: str | None = None,
        max_steps: int | None = 50,
        params: PrimitiveParams | None = None,
        render_mode: str | None = None,
        physics_hz: float | None = None,
        action_set: ActionSet | Mapping[str, Any] | None = None,
        lidar_mode: str = "finite",
        goal_conditioned: bool = False,
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']}, "
                             f"got {render_mode!r}")
        if max_steps is not None and max_steps < 1:
            raise ValueError(f"max_steps must be >= 1 or None, got {max_steps}")
        if lidar_mode not in LIDAR_MODES:
            raise ConfigError(f"expected one of {', '.join(LIDAR_MODES)}, got {lidar_mode!r}",
                              key="lidar_mode")
        if not isinstance(goal_conditioned, bool):
            raise ConfigError(f"expected true or false, got {goal_conditioned!r}",
                              key="goal_conditioned")
        self._config = {"arena": arena, "goal": goal, "max_steps": max_steps, "params": params,
                        "render_mode": render_mode, "physics_hz": physics_hz,
                        "action_set": action_set, "lidar_mode": lidar_mode,
                        "goal_conditioned": goal_conditioned}
        from simlab.physics.rate import DEFAULT_HZ, check_rate

        physics_hz = check_rate(DEFAULT_HZ if physics_hz is None else physics_hz)
        self._config["physics_hz"] = physics_hz
        self.world: World | None = World(arena, physics_hz=physics_hz)
        self.arena = self.world.arena
        if goal is not None:
            self.arena.goal(goal)  # validates the name
        self._fixed_goal = goal
        self.max_steps = None if max_steps is None else int(max_steps)
        self.params = params or PrimitiveParams()
        self.render_mode = render_mode
        self.lidar_mode = lidar_mode
        self.goal_conditioned = goal_conditioned
        self.observation_space = self._observation_space()
        if isinstance(action_set, Mapping):  # the JSON record, e.g. from a Q-table's metadata
            action_set = ActionSet.from_json(action_set)
        self.action_set = SIMLAB16 if action_set is None else action_set
        if not isinstance(self.action_set, ActionSet):
            raise ValueError(f"action_set must be an ActionSet or its JSON record, "
                             f"got {action_set!r}")
        self._primitives = self.action_set.primitives()
        # one decision = one primitive of the action set, noise from self.np_random
        self._driver = DecisionDriver(self.world, self.params, primitives=self._primitives)
        self.action_space = spaces.Discrete(self.action_set.n_actions)
        self.goal = self.arena.goals[0]
        self._steps = 0
        self._time = 0.0
        self._trail: list[np.ndarray] = []
        self._scan_points = np.empty((0, 2))

    def _observation_space(self) -> spaces.Dict:
        x0, y0, x1, y1 = self.arena.bounds
        spec = self._live().lidar_spec
        n = spec.n_beams
        pose = spaces.Box(np.array([x0, y0, -math.pi], dtype=np.float32),
                          np.array([x1, y1, math.pi], dtype=np.float32), dtype=np.float32)
        if self.lidar_mode == "raw":
            keys: dict[str, spaces.Space[Any]] = {
                "pose": pose, "lidar": spaces.Box(-np.inf, np.inf, shape=(n,), dtype=np.float32)}
        else:
            keys = {"pose": pose,
                    "lidar": spaces.Box(0.0, np.float32(spec.range_max), shape=(n,),
                                        dtype=np.float32),
                    "lidar_valid": spaces.MultiBinary(n)}
        return spaces.Dict(keys)

    def _live(self) -> World:
        """The world, or :class:`ClosedEnvironmentError` after :meth:`close`."""
        if self.world is None:
            raise ClosedEnvironmentError(
                f"{type(self).__name__} was closed; make a new env (gym.make) to continue")
        return self.world

    def _pose_obs(self) -> np.ndarray:
        """Pose (3,) float32 clipped to the pose box (the robot's base cannot leave the walls;
        the clip only guards float32 rounding at the bounds)."""
        box = self.observation_space["pose"]
        return np.clip(self._live().pose().astype(np.float32), box.low, box.high)

    def _observe(self) -> dict[str, np.ndarray]:
        world = self._live()
        spec = world.lidar_spec
        if self.lidar_mode == "raw":
            # noise-free cast, then the scanner's own noise draw (same stream, same size),
            # so the reading below range_min can be told from a miss
            scan = world.scan(None)
            ranges = scan.ranges.copy()
            if spec.noise_sigma > 0:
                ranges = ranges + self.np_random.normal(0.0, spec.noise_sigma, size=ranges.shape)
            hit = scan.hit_ids >= 0
            near = np.zeros_like(hit)
            if not hit.all():
                near[~hit] = near_surface(world, np.flatnonzero(~hit))
            lidar = rep117_scan(ranges, hit, spec.range_min, spec.range_max, near=near)
            self._scan_points = scan.points_world()
            return {"pose": self._pose_obs(), "lidar": lidar}
        scan = world.scan(self.np_random)
        self._scan_points = scan.points_world()
        lidar, valid = finite_scan(scan.ranges, spec.range_max)
        return {"pose": self._pose_obs(), "lidar": lidar, "lidar_valid": valid}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        world = self._live()
        options = options or {}
        from simlab.base.statecheck import placed_pose

        pose = self.arena.start if options.get("pose") is None else options["pose"]
        if np.shape(pose) == (3,) and np.all(np.isfinite(np.asarray(pose, dtype=float))):
            pose = placed_pose(pose, self.arena, world.robot_spec.footprint,
                               what="the reset pose")
        world.reset(pose)  # a malformed pose is refused there
        name = options.get("goal", self._fixed_goal)
        if name is None:
            self.goal = self.arena.goals[int(self.np_random.integers(len(self.arena.goals)))]
        else:
            self.goal = self.arena.goal(name)
        self._steps = 0
        self._time = 0.0
        self._trail = [world.pose()]
        self._driver.observe()
        obs = self._observe()
        return obs, {"goal": self.goal.name, "time": 0.0, "odometry": world.odometry()}

    def step(self, action):
        self._live()  # ClosedEnvironmentError after close()
        if not self.action_space.contains(action):
            raise ValueError(f"action must be an int in 0..{self.action_space.n - 1}, "
                             f"got {action!r}")
        primitive = int(self._primitives[int(action)])
        res = self._driver.execute(int(action), self.np_random).result
        self._steps += 1
        self._time += res.duration + self.params.decision_latency
        self._trail.append(res.pose_after)
        obs = self._observe()
        reward = self._reward(res.pose_after)
        truncated = self.max_steps is not None and self._steps >= self.max_steps
        info = {"blocked": res.blocked, "duration": res.duration, "time": self._time,
                "goal": self.goal.name, "odometry": res.odom_after, "primitive": primitive}
        return obs, reward, False, truncated, info

    def _reward(self, pose: np.ndarray) -> float:
        """1.0 when ``pose`` (x, y, yaw) lies in the current goal area (thesis eq. 2.1)."""
        return float(self.goal.contains(pose[:2]))

    def render(self):
        world = self._live()
        if self.render_mode != "rgb_array":
            return None
        return render_topdown(self.arena, world.robot_spec, world.pose(),
                              trail=np.array(self._trail), scan_points=self._scan_points,
                              active_goal=self.goal.name)

    def close(self) -> None:
        """Disconnect the physics (idempotent); any later use raises."""
        if getattr(self, "world", None) is not None:
            self.world.close()
            self.world = None

    # ------------------------------------------------------------------ copies
    def __getstate__(self) -> dict[str, Any]:
        """The configuration and the episode's progress, never the PyBullet client."""
        world = self._live()
        return {
            "config": dict(self._config),
            "pose": world.pose(),
            "goal": self.goal.name,
            "steps": self._steps,
            "time": self._time,
            "trail": [np.asarray(p).copy() for p in self._trail],
            "np_random": self._np_random,  # a Generator pickles and deep-copies its state
            "np_random_seed": self._np_random_seed,
        }

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Rebuild a fresh world from the configuration, the robot at rest at the pose."""
        self.__init__(**state["config"])
        self._live().reset(state["pose"])
        self.goal = self.arena.goal(state["goal"])
        self._steps = int(state["steps"])
        self._time = float(state["time"])
        self._trail = list(state["trail"])
        self._np_random = state["np_random"]
        self._np_random_seed = state["np_random_seed"]

    def __deepcopy__(self, memo: dict[int, Any]) -> TableArenaEnv:
        new = type(self).__new__(type(self))
        memo[id(self)] = new
        new.__setstate__(copy.deepcopy(self.__getstate__(), memo))  # fresh world, own RNG
        return new


class GoalTableArenaEnv(TableArenaEnv):
    """:class:`TableArenaEnv` with the current goal in the observation, a ``GoalEnv``.

    ``gym.make("simlab:simlab/TableArena-v0", goal_conditioned=True)`` builds this class
    (so does ``TableArenaEnv(goal_conditioned=True)``); everything else is the card of
    :class:`TableArenaEnv`.

    * **Observation** the sensors' keys plus those of Gymnasium-Robotics' ``GoalEnv`` (used
      by hindsight experience replay): ``desired_goal`` Box(2), the goal area's centre (x, y
      in metres), and ``achieved_goal`` Box(2), the robot's position (x, y in metres).
    * **Reward** :meth:`compute_reward` gives the reward of any such pair (the step reward
      for the observed one), so one policy can serve every goal of the arena.
    * **Id** ``"simlab:simlab/TableArena-v0"`` with ``goal_conditioned=True``.
    """

    def __init__(
        self,
        arena: ArenaConfig | str = "table",
        *,
        goal: str | None = None,
        max_steps: int | None = 50,
        params: PrimitiveParams | None = None,
        render_mode: str | None = None,
        physics_hz: float | None = None,
        action_set: ActionSet | Mapping[str, Any] | None = None,
        lidar_mode: str = "finite",
        goal_conditioned: bool = True,
    ) -> None:
        if goal_conditioned is not True:
            raise ConfigError(f"{type(self).__name__} is always goal-conditioned, got "
                              f"{goal_conditioned!r}", key="goal_conditioned",
                              fix="use TableArenaEnv for an env without goals in its "
                                  "observation")
        super().__init__(arena, goal=goal, max_steps=max_steps, params=params,
                         render_mode=render_mode, physics_hz=physics_hz,
                         action_set=action_set, lidar_mode=lidar_mode, goal_conditioned=True)
        #: (G, 2) goal centres and (G,) radii (m), for :meth:`compute_reward`
        self._goal_xy = np.array([[g.x, g.y] for g in self.arena.goals], dtype=np.float64)
        self._goal_r = np.array([g.radius for g in self.arena.goals], dtype=np.float64)

    def _observation_space(self) -> spaces.Dict:
        keys = dict(super()._observation_space().spaces)
        x0, y0, x1, y1 = self.arena.bounds
        xy = spaces.Box(np.array([x0, y0], dtype=np.float32),
                        np.array([x1, y1], dtype=np.float32), dtype=np.float32)
        keys["achieved_goal"] = xy
        keys["desired_goal"] = copy.deepcopy(xy)
        return spaces.Dict(keys)

    def _observe(self) -> dict[str, np.ndarray]:
        obs = super()._observe()
        obs["achieved_goal"] = obs["pose"][:2].copy()
        obs["desired_goal"] = np.array([self.goal.x, self.goal.y], dtype=np.float32)
        return obs

    def compute_reward(self, achieved_goal: np.ndarray, desired_goal: np.ndarray,
                       info: Any = None) -> np.ndarray:
        """Reward (...,) float64 of robot positions ``achieved_goal`` (..., 2) (m) against
        goal centres ``desired_goal`` (..., 2) (m): 1.0 inside the goal area, else 0.0.

        The area's radius is that of the arena goal nearest to ``desired_goal`` (exactly
        the goal itself for observed goals; a relabelled goal, as hindsight experience
        replay makes them, gets its nearest goal's radius). ``info`` is unused (the
        ``GoalEnv`` signature). Equals the step reward for the observed pair.
        """
        a = np.asarray(achieved_goal, dtype=np.float64)
        d = np.asarray(desired_goal, dtype=np.float64)
        nearest = np.argmin(np.linalg.norm(d[..., None, :] - self._goal_xy, axis=-1), axis=-1)
        inside = np.linalg.norm(a - d, axis=-1) <= self._goal_r[nearest]
        return inside.astype(np.float64)
