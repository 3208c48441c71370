"""``simlab/TableArenaStates-v0``: the physics robot seen through the Voronoi states.

The env card is the docstring of :class:`TableArenaStatesEnv` (``help(env.unwrapped)``
shows it).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

import numpy as np
from gymnasium import spaces

from simlab.base.actions import ActionSet, action_set_from_metadata
from simlab.base.errors import ConfigError
from simlab.envs.table_arena import TableArenaEnv
from simlab.localization.sources import SCANLESS_POSE_SOURCES
from simlab.physics.arena import ArenaConfig
from simlab.physics.motion import PrimitiveParams

#: The pose sources of this env (no LIDAR filter): the shared list's scanless ones.
POSE_SOURCES = SCANLESS_POSE_SOURCES


def _discretizer(states: Any) -> Any:
    from discretize.voronoi import Discretizer, load_states

    if isinstance(states, Discretizer):
        return states
    if isinstance(states, str | os.PathLike):
        return load_states(states)
    if isinstance(states, list | tuple | np.ndarray):  # centres (S, 2) m, in state order
        centres = np.asarray(states, dtype=np.float64)
        if centres.ndim != 2 or centres.shape[1] != 2 or len(centres) == 0:
            raise ConfigError(f"expected centres of shape (S, 2), got {centres.shape}",
                              key="states")
        return Discretizer.from_centres(centres)
    raise ConfigError(f"expected a states file, centres (S, 2) or a Discretizer, got "
                      f"{type(states).__name__}",
                      key="states", fix="pass the states.json written by simlab discretize")


def _qtable_action_set(path: str | os.PathLike[str]) -> ActionSet:
    from simlab.agents.storage import load_q_table

    q, meta = load_q_table(path)
    return action_set_from_metadata(meta, int(q.shape[1]), where=str(path))


class TableArenaStatesEnv(TableArenaEnv):
    """The physics TurtleBot3 observed through the Voronoi states of a discretization.

    The physics of :class:`~simlab.envs.table_arena.TableArenaEnv` (same primitives, obstacle
    check, decision latency, seeding, copies, close), observed and rewarded as the empirical
    MDP that ``simlab train`` learned on, so a Q-table from training is evaluated in physics
    with a few lines of Gymnasium code::

        import gymnasium as gym
        from simlab.agents import greedy

        env = gym.make("simlab:simlab/TableArenaStates-v0", states="states.json", goal="NE",
                       q_table="q/table/q_NE.npz")
        policy = greedy("q/table/q_NE.npz")  # (S,) the best *tried* action of each state
        s, _ = env.reset(seed=0)
        done = False
        while not done:
            s, r, terminated, truncated, _ = env.step(int(policy[s]))
            done = terminated or truncated

    Use :func:`simlab.agents.greedy`, not ``Q[s].argmax()``: a pair the robot never tried keeps
    its optimistic initial value (10.0), which ``argmax`` would pick.

    * **States** ``states``: a states file (``simlab discretize`` JSON or centres text), a
      :class:`~discretize.voronoi.Discretizer`, or the centres (S, 2) in metres in state
      order (JSON-able, as a Minari env spec records them).
    * **Observation** ``Discrete(S)``: the Voronoi state (nearest centre, see
      :mod:`discretize.voronoi`) of the pose after the primitive; the pose source is the
      simulator's truth (``pose_source="truth"``) or the wheel odometry (``"odometry"``).
    * **Actions** as ``TableArena-v0``: ``action_set`` (an ActionSet or its JSON record), or
      the action set recorded in a Q-table file ``q_table`` (only its metadata is read).
    * **Reward** 1.0 when the state reached is a goal state of the current goal
      (:func:`simlab.data.goals.goal_state_masks`, the rule ``simlab estimate`` and ``replay``
      use), else 0.0: the empirical MDP's reward, not the metric goal circle.
    * **Episode** registered ``max_episode_steps=50`` (thesis trials); never terminates.
    * **Id** ``"simlab:simlab/TableArenaStates-v0"`` works in any process (spawned vector-env
      workers too); the short id needs ``import simlab`` first.
    * **Info** as ``TableArena-v0`` plus ``pose`` (3,) (m, m, rad) of the pose source.

    No LIDAR scan is taken for the observation (the obstacle check still casts its beams), so
    this env steps faster than ``TableArena-v0``.
    """

    def __init__(
        self,
        states: Any = None,
        arena: ArenaConfig | str = "table",
        *,
        goal: str | None = None,
        q_table: str | os.PathLike[str] | None = None,
        action_set: ActionSet | Mapping[str, Any] | None = None,
        pose_source: str = "truth",
        max_steps: int | None = 50,
        params: PrimitiveParams | None = None,
        render_mode: str | None = None,
        physics_hz: float | None = None,
    ) -> None:
        if states is None:
            raise ConfigError("no states given", key="states",
                              fix="pass states= the states.json written by simlab discretize")
        if pose_source not in POSE_SOURCES:
            raise ConfigError(f"expected one of {', '.join(POSE_SOURCES)}, got {pose_source!r}",
                              key="pose_source")
        if q_table is not None:
            if action_set is not None:
                raise ConfigError("pass q_table or action_set, not both", key="action_set")
            action_set = _qtable_action_set(q_table)
        self.discretizer = _discretizer(states)
        self.pose_source = pose_source
        super().__init__(arena, goal=goal, max_steps=max_steps, params=params,
                         render_mode=render_mode, physics_hz=physics_hz, action_set=action_set)
        from simlab.data.goals import goal_state_masks

        names, masks = goal_state_masks(self.arena, self.discretizer.centres)
        self.goal_names: tuple[str, ...] = tuple(names)
        self.goal_masks = np.asarray(masks, dtype=bool)  # (G, S)
        self._config.update(states=self.discretizer, pose_source=pose_source,
                            action_set=self.action_set)
        self._config.pop("lidar_mode", None)
        self._config.pop("goal_conditioned", None)
        self._state = 0

    def _observation_space(self) -> spaces.Discrete:
        return spaces.Discrete(self.discretizer.n_states)

    def _pose_obs(self) -> np.ndarray:
        world = self._live()
        return world.pose() if self.pose_source == "truth" else world.odometry()

    def _observe(self) -> int:
        pose = self._pose_obs()
        self._state = int(self.discretizer.state_of(np.asarray(pose[:2]))[()])
        return self._state

    def _reward(self, pose: np.ndarray) -> float:
        g = self.goal_names.index(self.goal.name)
        return float(self.goal_masks[g, self._state])

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        obs, info = super().reset(seed=seed, options=options)
        info["pose"] = self._pose_obs()
        return obs, info

    def step(self, action):
        obs, reward, term, trunc, info = super().step(action)
        info["pose"] = self._pose_obs()
        return obs, reward, term, trunc, info
