"""``simlab/TableSocial-v0``: the physics social task as a Gymnasium env.

The env card is the docstring of :class:`TableSocialEnv` (``help(env.unwrapped)`` shows it).
"""

from __future__ import annotations

import copy
from typing import Any, ClassVar

import gymnasium as gym
from gymnasium import spaces
from gymnasium.error import ClosedEnvironmentError

from simlab.social.actions import N_SOCIAL_ACTIONS
from simlab.social.task import SocialConfig, SocialTable
from simlab.social.walk import N_SOCIAL_STATES


class TableSocialEnv(gym.Env):
    """The robot and a human on the table: the social task of Visit the lab in physics.

    * **Actions** ``Discrete(22)``: the 16 motion primitives, STAY, LOOK_H, HELLO, COME,
      POINTING, GO_TO_HUMAN (:mod:`simlab.social.actions`).
    * **Observation** ``Discrete(2560)``: the social state (interaction level, distance class,
      required direction, angle; :func:`simlab.social.walk.decode_social`).
    * **Reward** the social reward of :class:`~simlab.social.task.SocialTable`: 1.0 when the
      engaged human (level 7) moved in the required direction, else 0.0.
    * **Id** ``gym.make("simlab:simlab/TableSocial-v0")`` works in any process (spawned
      vector-env workers too); the short id needs ``import simlab`` first.
    * **Episode** random robot and human poses (or ``options["robot_pose"]`` /
      ``options["human_pose"]``); never terminates; truncated after ``max_steps`` decisions
      when set (the registered id sets ``max_steps=None`` and ``max_episode_steps=40``, the
      grid's social trial length, so Gymnasium's ``TimeLimit`` truncates).
    * **Seeding** ``reset(seed)`` seeds ``self.np_random``, which draws the task's seed
      (:meth:`SocialTable.reset`); the same seed and actions give the same rollout.
    * **Copies** ``copy.deepcopy`` and ``pickle`` rebuild a fresh PyBullet world from the
      configuration (as ``simlab/TableArena-v0``): the robot at rest at the copied pose, the
      same human pose, engagement, required direction, clock, task and noise generators; the
      copy's odometry (and any pose estimate, ``SocialConfig.pose_source``) restarts at that
      pose.
    * **Info** ``level``, ``moved``, ``duration``, ``blocked``, ``time``, ``robot_pose``,
      ``human_pose``.
    * **Physics** steps at ``physics_hz`` as every physics env (default
      :data:`simlab.physics.rate.DEFAULT_HZ`; outside
      :data:`~simlab.physics.rate.MIN_HZ`-:data:`~simlab.physics.rate.MAX_HZ` is refused).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": []}

    def __init__(self, config: SocialConfig | None = None, *,
                 max_steps: int | None = 40, physics_hz: float | None = None) -> None:
        from simlab.physics.rate import resolve_rate

        if max_steps is not None and max_steps < 1:
            raise ValueError(f"max_steps must be >= 1 or None, got {max_steps}")
        physics_hz = resolve_rate(physics_hz)
        self._config = {"config": config, "max_steps": max_steps, "physics_hz": physics_hz}
        self.task: SocialTable | None = SocialTable(config, physics_hz=physics_hz)
        self.max_steps = None if max_steps is None else int(max_steps)
        self.observation_space = spaces.Discrete(N_SOCIAL_STATES)
        self.action_space = spaces.Discrete(N_SOCIAL_ACTIONS)
        self._steps = 0

    def _live(self) -> SocialTable:
        if self.task is None:
            raise ClosedEnvironmentError(
                f"{type(self).__name__} was closed; make a new env (gym.make) to continue")
        return self.task

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        task = self._live()
        options = options or {}
        obs = task.reset(int(self.np_random.integers(0, 2**63 - 1)),
                         robot_pose=options.get("robot_pose"),
                         human_pose=options.get("human_pose"))
        self._steps = 0
        return obs, {"level": task.level(), "time": 0.0}

    def step(self, action):
        task = self._live()
        if not self.action_space.contains(action):
            raise ValueError(f"action must be an int in 0..{N_SOCIAL_ACTIONS - 1}, "
                             f"got {action!r}")
        obs, reward, info = task.step(int(action))
        self._steps += 1
        truncated = self.max_steps is not None and self._steps >= self.max_steps
        return obs, float(reward), False, truncated, {
            "level": info.level, "moved": info.moved, "duration": info.duration,
            "blocked": info.blocked, "time": info.time, "robot_pose": info.robot_pose,
            "human_pose": info.human_pose}

    def close(self) -> None:
        """Disconnect the physics (idempotent); any later use raises."""
        if getattr(self, "task", None) is not None:
            self.task.close()
            self.task = None

    # ------------------------------------------------------------------ copies
    def __getstate__(self) -> dict[str, Any]:
        """The configuration and the episode's progress, never the PyBullet client."""
        task = self._live()
        started = task._rng is not None
        return {
            "config": dict(self._config), "steps": self._steps, "started": started,
            "robot_pose": task.world.pose(), "human_pose": task.human_pose.copy(),
            "engaged": task.engaged, "required_direction": task.required_direction,
            "time": task.time, "rng": task._rng, "noise": task._noise,
            "np_random": self._np_random, "np_random_seed": self._np_random_seed,
        }

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Rebuild a fresh world from the configuration, the robot at rest at the pose."""
        self.__init__(**state["config"])
        self._steps = int(state["steps"])
        self._np_random = state["np_random"]
        self._np_random_seed = state["np_random_seed"]
        if not state["started"]:
            return
        task = self._live()
        task.reset(0, robot_pose=state["robot_pose"], human_pose=state["human_pose"])
        task.engaged = int(state["engaged"])
        task.required_direction = int(state["required_direction"])
        task.time = float(state["time"])
        task._rng, task._noise = state["rng"], state["noise"]

    def __deepcopy__(self, memo: dict[int, Any]) -> TableSocialEnv:
        new = type(self).__new__(type(self))
        memo[id(self)] = new
        new.__setstate__(copy.deepcopy(self.__getstate__(), memo))  # fresh world, own RNG
        return new
