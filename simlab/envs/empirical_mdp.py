"""``simlab/EmpiricalMDP-v0``: navigation on an empirical transition matrix (thesis 4.5).

The env card is the docstring of :class:`EmpiricalMDPEnv` (``help(env.unwrapped)`` shows it).
"""

from __future__ import annotations

import os
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from simlab.base.errors import ConfigError
from simlab.data.mdp import EmpiricalMDP, load_mdp, mdp_from_arrays

__all__ = ["EmpiricalMDPEnv", "render_states_rgb"]

class EmpiricalMDPEnv(gym.Env):
    """Gymnasium env sampling ``s'`` from an empirical ``T`` (thesis 4.5).

    * **Built from** an ``mdp.npz`` (written by ``simlab estimate``) or arrays, and a
      goal (name from the file's ``goal_names``, index, or an explicit (S,) mask).
    * **Observation** ``Discrete(S)``: the Markov state (Voronoi cell index).
    * **Action** ``Discrete(A)``: what action ``a`` does is the MDP's ``action_set``
      (:class:`~simlab.base.actions.ActionSet`; simlab's 16 primitives ``speed * 8 + direction``
      for the table arena, 8 actions for a real robot's data). ``env.action_set`` and
      ``env.valid_actions`` ((S, A) bool, the ``mask`` rule for unvisited pairs; None when every
      action is allowed) tell an agent which actions mean what and which were never tried.
    * **Dynamics** ``s' ~ T[s, a, :]`` drawn with ``self.np_random``.
    * **Reward** 1.0 when the state reached ``s'`` is in the goal area, else 0.0 (the
      thesis's +1 per step inside the goal area; the start state earns nothing).
    * **Greedy policy** of a Q-table trained on this MDP: :func:`simlab.agents.greedy` (the
      argmax over ``valid_actions`` only; an untried pair keeps its optimistic initial value,
      which a plain ``Q[s].argmax()`` would pick)::

          from simlab.agents import greedy

          env = gym.make("simlab:simlab/EmpiricalMDP-v0", mdp="mdp/table.npz", goal="NE")
          policy = greedy("q/table/q_NE.npz")
          s, _ = env.reset(seed=0)
          s, r, terminated, truncated, info = env.step(int(policy[s]))

    * **Id** ``"simlab:simlab/EmpiricalMDP-v0"`` works in any process (spawned vector-env
      workers too); the short id needs ``import simlab`` first.
    * **Episode** ``horizon`` steps (thesis: 50), ended by truncation; never terminated.
      ``horizon=None`` leaves the limit to Gymnasium: the registered id does so and registers
      ``max_episode_steps=50``, so ``gym.make(id, max_episode_steps=N)`` truncates at N.
    * **Render** ``ansi`` (one text line: the step, out of ``horizon`` when the env
      has one, the state and the goal) or ``rgb_array`` (``render_fps`` 4): an (H, W, 3)
      uint8 top-down picture of the Voronoi centres (grey), the goal states (green) and the
      current state (red), or a strip of S squares when the MDP has no centres.
    * **Start** uniform over all states by default (so the learned policy is good
      everywhere — the replay switches goals without returning to the start), or a
      fixed ``start_state``. ``reset(options={"state": s, "goal": name})`` overrides
      both for one episode/for the rest of the run respectively.

    The npz arrays are described in :mod:`simlab.data.mdp`.

    Parameters
    ----------
    mdp:
        Path to an ``mdp.npz``, an :class:`EmpiricalMDP`, or ``None`` with ``T=``.
    goal:
        Goal name or index (from the MDP's ``goal_names``). Alternatively ``goal_mask``.
    T:
        (S, A, S) transition matrix when ``mdp`` is ``None``.
    goal_mask:
        (S,) bool goal area, instead of ``goal``.
    horizon:
        Steps per episode (thesis 50).
    start_state:
        Fixed start state; ``None`` (default) draws it uniformly each episode.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["ansi", "rgb_array"],
                                          "render_fps": 4}

    def __init__(
        self,
        mdp: str | os.PathLike[str] | EmpiricalMDP | None = None,
        goal: str | int | None = None,
        *,
        T: np.ndarray | None = None,
        goal_mask: np.ndarray | None = None,
        horizon: int | None = 50,
        start_state: int | None = None,
        render_mode: str | None = None,
    ) -> None:
        if isinstance(mdp, EmpiricalMDP):
            self.mdp = mdp
        elif mdp is not None:
            self.mdp = load_mdp(mdp)
        elif T is not None:
            self.mdp = mdp_from_arrays(T)
        else:
            raise ConfigError("pass an mdp.npz path, an EmpiricalMDP or T=", key="mdp")
        S, A = self.mdp.n_states, self.mdp.n_actions
        if horizon is not None and not (isinstance(horizon, int | np.integer) and horizon >= 1):
            raise ConfigError(f"expected an integer >= 1 or None, got {horizon!r}",
                              key="horizon")
        self.horizon = None if horizon is None else int(horizon)
        if start_state is not None and not (0 <= int(start_state) < S):
            raise ConfigError(f"expected a state in [0, {S}), got {start_state}", key="start_state")
        self.start_state = None if start_state is None else int(start_state)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError(f"unsupported render mode {render_mode!r}", key="render_mode")
        self.render_mode = render_mode
        self.observation_space = spaces.Discrete(S)
        self.action_space = spaces.Discrete(A)
        self.action_set = self.mdp.action_set
        self.valid_actions = self.mdp.valid
        self._set_goal(goal, goal_mask)
        self._state = 0
        self._t = 0

    def _set_goal(self, goal: str | int | None, goal_mask: np.ndarray | None) -> None:
        if goal_mask is not None:
            mask = np.asarray(goal_mask, dtype=bool)
            if mask.shape != (self.mdp.n_states,):
                raise ConfigError(
                    f"expected shape ({self.mdp.n_states},), got {mask.shape}", key="goal_mask"
                )
            self.goal = "custom"
        elif goal is not None:
            mask = self.mdp.goal_mask(goal)
            self.goal = self.mdp.goal_names[self.mdp.goal_index(goal)]
        else:
            valid = ", ".join(self.mdp.goal_names) if self.mdp.goal_names else "none in this MDP"
            raise ConfigError(
                f"no goal given; valid goals: {valid}",
                path=self.mdp.source,
                key="goal",
                fix="pass goal=NAME or goal_mask=",
            )
        self.goal_mask = mask
        self._reward = mask.astype(np.float64)

    @property
    def state(self) -> int:
        """Current state."""
        return self._state

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[int, dict[str, Any]]:
        super().reset(seed=seed)
        options = options or {}
        if "goal" in options:
            self._set_goal(options["goal"], None)
        if options.get("state") is not None:
            s = int(options["state"])
            if not 0 <= s < self.mdp.n_states:
                raise ConfigError(
                    f"expected a state in [0, {self.mdp.n_states}), got {s}", key="state"
                )
        elif self.start_state is not None:
            s = self.start_state
        else:
            s = int(self.np_random.integers(0, self.mdp.n_states))
        self._state = s
        self._t = 0
        return s, {"goal": self.goal, "in_goal": bool(self.goal_mask[s])}

    def step(self, action: int) -> tuple[int, float, bool, bool, dict[str, Any]]:
        a = int(action)
        if not 0 <= a < self.mdp.n_actions:
            raise ConfigError(
                f"expected an action in [0, {self.mdp.n_actions}), got {action}", key="action"
            )
        cdf = self.mdp.cdf[self._state, a]
        u = self.np_random.random() * cdf[-1]
        s_next = int(np.searchsorted(cdf, u, side="right"))
        s_next = min(s_next, self.mdp.n_states - 1)
        reward = float(self._reward[s_next])
        self._state = s_next
        self._t += 1
        truncated = self.horizon is not None and self._t >= self.horizon
        return s_next, reward, False, truncated, {"goal": self.goal, "in_goal": reward > 0}

    def render(self) -> str | None:
        if self.render_mode == "ansi":
            # without a horizon the limit is the TimeLimit wrapper's, which the env cannot
            # see (gym.make gives the unwrapped env a spec without max_episode_steps)
            step = f"t={self._t}" if self.horizon is None else f"t={self._t}/{self.horizon}"
            return f"{step} state={self._state} goal={self.goal}\n"
        if self.render_mode == "rgb_array":
            return render_states_rgb(self.mdp.centres, self.mdp.n_states, self.goal_mask,
                                     self._state)
        return None


def render_states_rgb(centres: np.ndarray | None, n_states: int, goal_mask: np.ndarray,
                      state: int, *, size: int = 256) -> np.ndarray:
    """(size, size, 3) uint8 picture: a disc per state at its centre (grey, goal states
    green, ``state`` red), y up; without centres a row-major grid of squares."""
    if centres is None:
        side = int(np.ceil(np.sqrt(n_states)))
        idx = np.arange(n_states)
        xy = np.stack([idx % side, -(idx // side)], axis=1).astype(np.float64)
    else:
        xy = np.asarray(centres, dtype=np.float64)
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    span = float(max(hi[0] - lo[0], hi[1] - lo[1], 1e-9))
    margin = size * 0.08
    px = margin + (xy[:, 0] - lo[0]) / span * (size - 2 * margin)
    py = size - margin - (xy[:, 1] - lo[1]) / span * (size - 2 * margin)
    radius = max(2.0, (size - 2 * margin) / (2.5 * max(1.0, np.sqrt(n_states))))
    image = np.full((size, size, 3), 255, dtype=np.uint8)
    yy, xx = np.mgrid[0:size, 0:size]
    for s in range(n_states):
        colour = (220, 40, 40) if s == state else (60, 170, 60) if goal_mask[s] else (150,) * 3
        disc = (xx - px[s]) ** 2 + (yy - py[s]) ** 2 <= radius**2
        image[disc] = colour
    return image
