"""``simlab/TableArena-v0``: the physics TurtleBot3 in an arena, acting by motion primitives.

Card
----
* **Actions** ``Discrete(action_set.n_actions)``: by default (``action_set`` SIMLAB16)
  the thesis's 16 motion primitives, index = speed * 8 + direction (UP, DOWN, LEFT, RIGHT,
  UP-LEFT, UP-RIGHT, DOWN-LEFT, DOWN-RIGHT in the map frame; slow 0.10 m/s or fast
  0.22 m/s for 0.5 s), each preceded by the LIDAR obstacle check (see
  :mod:`simlab.physics.motion`). Another :class:`~simlab.actions.ActionSet` (e.g. a real
  robot's 8 actions numbered counter-clockwise from East) renumbers them: action ``a``
  executes the primitive ``action_set.to_primitive(a)``; ``info["primitive"]`` says which.
* **Observation** ``Dict(pose=Box(3), lidar=Box(360))``: the true pose (x, y in metres,
  yaw in radians) after the primitive, and a full 360-beam LIDAR scan (metres, ``inf`` for
  no return).
* **Reward** 1.0 when the robot ends the step inside the current goal area, else 0.0
  (thesis eq. 2.1).
* **Episode** starts at the arena's start pose (or ``options["pose"]``) with a goal drawn
  uniformly from the arena's goal areas (or ``options["goal"]``); never terminates;
  truncated after ``max_steps`` primitives (thesis: 50-step trials).
* **Info** ``blocked``, ``duration`` (simulated s stepped), ``time`` (simulated s since
  reset, including the decision latency), ``goal``, ``odometry`` (3,).
* **Seeding** the LIDAR noise and the goal draw use ``self.np_random``; the physics is
  deterministic, so the same seed and actions give identical rollouts.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from simlab.actions import SIMLAB16, ActionSet
from simlab.physics.arena import ArenaConfig
from simlab.physics.motion import PrimitiveParams, execute_primitive
from simlab.physics.render import render_topdown
from simlab.physics.world import World


class TableArenaEnv(gym.Env):
    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 4}

    def __init__(
        self,
        arena: ArenaConfig | str = "table",
        *,
        goal: str | None = None,
        max_steps: int = 50,
        params: PrimitiveParams | None = None,
        render_mode: str | None = None,
        physics_hz: float = 200.0,
        action_set: ActionSet | Mapping[str, Any] | None = None,
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']}, "
                             f"got {render_mode!r}")
        if max_steps < 1:
            raise ValueError(f"max_steps must be >= 1, got {max_steps}")
        self.world = World(arena, physics_hz=physics_hz)
        self.arena = self.world.arena
        if goal is not None:
            self.arena.goal(goal)  # validates the name
        self._fixed_goal = goal
        self.max_steps = int(max_steps)
        self.params = params or PrimitiveParams()
        self.render_mode = render_mode
        x0, y0, x1, y1 = self.arena.bounds
        n = self.world.lidar_spec.n_beams
        self.observation_space = spaces.Dict({
            "pose": spaces.Box(np.array([x0, y0, -math.pi], dtype=np.float32),
                               np.array([x1, y1, math.pi], dtype=np.float32), dtype=np.float32),
            "lidar": spaces.Box(0.0, np.inf, shape=(n,), dtype=np.float32),
        })
        if isinstance(action_set, Mapping):  # the JSON record, e.g. from a Q-table's metadata
            action_set = ActionSet.from_json(action_set)
        self.action_set = SIMLAB16 if action_set is None else action_set
        if not isinstance(self.action_set, ActionSet):
            raise ValueError(f"action_set must be an ActionSet or its JSON record, "
                             f"got {action_set!r}")
        self._primitives = self.action_set.primitives()
        self.action_space = spaces.Discrete(self.action_set.n_actions)
        self.goal = self.arena.goals[0]
        self._steps = 0
        self._time = 0.0
        self._trail: list[np.ndarray] = []
        self._scan_points = np.empty((0, 2))

    def _observe(self) -> dict[str, np.ndarray]:
        scan = self.world.scan(self.np_random)
        self._scan_points = scan.points_world()
        pose = self.world.pose()
        return {"pose": pose.astype(np.float32), "lidar": scan.ranges.astype(np.float32)}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        options = options or {}
        self.world.reset(options.get("pose"))
        name = options.get("goal", self._fixed_goal)
        if name is None:
            self.goal = self.arena.goals[int(self.np_random.integers(len(self.arena.goals)))]
        else:
            self.goal = self.arena.goal(name)
        self._steps = 0
        self._time = 0.0
        self._trail = [self.world.pose()]
        obs = self._observe()
        return obs, {"goal": self.goal.name, "time": 0.0, "odometry": self.world.odometry()}

    def step(self, action):
        if not self.action_space.contains(action):
            raise ValueError(f"action must be an int in 0..{self.action_space.n - 1}, "
                             f"got {action!r}")
        primitive = int(self._primitives[int(action)])
        res = execute_primitive(self.world, primitive, self.np_random, self.params)
        self._steps += 1
        self._time += res.duration + self.params.decision_latency
        self._trail.append(res.pose_after)
        obs = self._observe()
        reward = float(self.goal.contains(res.pose_after[:2]))
        truncated = self._steps >= self.max_steps
        info = {"blocked": res.blocked, "duration": res.duration, "time": self._time,
                "goal": self.goal.name, "odometry": res.odom_after, "primitive": primitive}
        return obs, reward, False, truncated, info

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        return render_topdown(self.arena, self.world.robot_spec, self.world.pose(),
                              trail=np.array(self._trail), scan_points=self._scan_points,
                              active_goal=self.goal.name)

    def close(self) -> None:
        self.world.close()
