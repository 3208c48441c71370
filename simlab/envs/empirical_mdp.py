"""``simlab/EmpiricalMDP-v0``: navigation on an empirical transition matrix (thesis 4.5).

Env card
--------
* **Built from** an ``mdp.npz`` (written by ``simlab estimate``) or arrays, and a
  goal (name from the file's ``goal_names``, index, or an explicit (S,) mask).
* **Observation** ``Discrete(S)``: the Markov state (Voronoi cell index).
* **Action** ``Discrete(A)``: what action ``a`` does is the MDP's ``action_set``
  (:class:`~simlab.actions.ActionSet`; simlab's 16 primitives ``speed * 8 + direction``
  for the table arena, 8 actions for a real robot's data). ``env.action_set`` and
  ``env.valid_actions`` ((S, A) bool, the ``mask`` rule for unvisited pairs; None when every
  action is allowed) tell an agent which actions mean what and which were never tried.
* **Dynamics** ``s' ~ T[s, a, :]`` drawn with ``self.np_random``.
* **Reward** 1.0 when the state reached ``s'`` is in the goal area, else 0.0 (the
  thesis's +1 per step inside the goal area; the start state earns nothing).
* **Episode** ``horizon`` steps (thesis: 50), ended by truncation; never terminated.
  ``horizon=None`` leaves the limit to Gymnasium: the registered id does so and registers
  ``max_episode_steps=50``, so ``gym.make(id, max_episode_steps=N)`` truncates at N.
* **Render** ``ansi`` (one text line) or ``rgb_array`` (``render_fps`` 4): an (H, W, 3)
  uint8 top-down picture of the Voronoi centres (grey), the goal states (green) and the
  current state (red), or a strip of S squares when the MDP has no centres.
* **Start** uniform over all states by default (so the learned policy is good
  everywhere — the replay switches goals without returning to the start), or a
  fixed ``start_state``. ``reset(options={"state": s, "goal": name})`` overrides
  both for one episode/for the rest of the run respectively.

The npz arrays (see :func:`load_mdp`): ``T`` (S, A, S) float64, rows summing to 1
(required); ``counts`` (S, A, S) int64, ``visited`` (S, A) bool, ``entropy``
(S, A) float64 bits (optional, kept for reports); ``centres`` (S, 2) float64
metres, ``goal_names`` (G,) unicode, ``goal_masks`` (G, S) bool (needed to pick a
goal by name); ``bounds`` (4,) ``x_min, y_min, x_max, y_max`` metres (optional, for plots; the
convention of :attr:`simlab.physics.arena.ArenaConfig.bounds`); ``meta_json`` (optional):
``action_set`` (absent: simlab's 16 primitives; for another number of actions unknown, None,
which training accepts and heat-map arrows and replay refuse)
and ``unvisited`` (``mask``, the default also for files without it, or ``self-loop``).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from simlab.actions import ActionSet, action_set_from_metadata
from simlab.errors import ConfigError

__all__ = ["EmpiricalMDP", "EmpiricalMDPEnv", "load_mdp", "mdp_from_arrays"]

_ROW_ATOL = 1e-6


@dataclass(frozen=True, eq=False)
class EmpiricalMDP:
    """A validated empirical MDP and its goal areas (arrays are read-only)."""

    T: np.ndarray
    """(S, A, S) float64 transition probabilities, rows sum to 1."""
    goal_names: tuple[str, ...] = ()
    """Names of the goal areas (G,)."""
    goal_masks: np.ndarray | None = None
    """(G, S) bool, ``goal_masks[g, s]``: state s lies in goal g."""
    centres: np.ndarray | None = None
    """(S, 2) float64 metres, the Voronoi centres."""
    bounds: tuple[float, float, float, float] | None = None
    """``(x_min, y_min, x_max, y_max)`` metres of the arena, if known."""
    counts: np.ndarray | None = None
    """(S, A, S) int64 transition counts, if known."""
    visited: np.ndarray | None = None
    """(S, A) bool, pairs observed at least once, if known."""
    entropy: np.ndarray | None = None
    """(S, A) float64 entropy of T(s, a, .) in bits, if known."""
    source: str | None = None
    """File the MDP was read from (for messages)."""
    action_set: ActionSet | None = None
    """What each action index means (None only for MDPs built from bare arrays)."""
    unvisited: str = "mask"
    """Rule for unvisited (s, a): ``mask`` (planners never choose them) or ``self-loop``."""
    cdf: np.ndarray = field(init=False, repr=False)
    """(S, A, S) cumulative sums of T along s' (for sampling)."""

    def __post_init__(self) -> None:
        cdf = np.cumsum(self.T, axis=2)
        cdf.setflags(write=False)
        object.__setattr__(self, "cdf", cdf)

    @property
    def n_states(self) -> int:
        return int(self.T.shape[0])

    @property
    def n_actions(self) -> int:
        return int(self.T.shape[1])

    @property
    def valid(self) -> np.ndarray | None:
        """(S, A) bool actions a planner may choose, or None when all are allowed.

        Under the ``mask`` rule the visited pairs (a state with no visited action keeps
        all of them); None under ``self-loop``, without ``visited``/``counts``, or when
        every pair was visited (so fully covered data trains exactly as before).
        """
        from simlab.data.estimate import valid_actions

        if self.unvisited != "mask":
            return None
        visited = self.visited
        if visited is None and self.counts is not None:
            visited = self.counts.sum(axis=2) > 0
        if visited is None:
            return None
        v = valid_actions(visited)
        return None if v.all() else v

    def goal_index(self, goal: str | int) -> int:
        """Index of a goal given by name or index; :class:`ConfigError` lists the valid ones."""
        if self.goal_masks is None or not self.goal_names:
            raise ConfigError(
                "has no goal areas (arrays goal_names and goal_masks)",
                path=self.source,
                key="goal",
                fix="re-run simlab estimate with an arena that defines goals, or pass goal_mask=",
            )
        if isinstance(goal, int | np.integer) and not isinstance(goal, bool):
            if 0 <= int(goal) < len(self.goal_names):
                return int(goal)
        elif isinstance(goal, str) and goal in self.goal_names:
            return self.goal_names.index(goal)
        raise ConfigError(
            f"unknown goal {goal!r}; valid goals: {', '.join(self.goal_names)}",
            path=self.source,
            key="goal",
        )

    def goal_mask(self, goal: str | int) -> np.ndarray:
        """(S,) bool mask of a goal."""
        return self.goal_masks[self.goal_index(goal)].copy()

    def goal_reward(self, goal: str | int | np.ndarray) -> np.ndarray:
        """(S,) float64 reward on arrival: 1.0 inside the goal, 0.0 elsewhere."""
        mask = goal if isinstance(goal, np.ndarray) else self.goal_mask(goal)
        return np.asarray(mask, dtype=np.float64)


def _readonly(a: np.ndarray | None) -> np.ndarray | None:
    if a is None:
        return None
    a = np.array(a)
    a.setflags(write=False)
    return a


def mdp_from_arrays(
    T: np.ndarray,
    *,
    goal_names: Any = None,
    goal_masks: np.ndarray | None = None,
    centres: np.ndarray | None = None,
    bounds: Any = None,
    counts: np.ndarray | None = None,
    visited: np.ndarray | None = None,
    entropy: np.ndarray | None = None,
    source: str | os.PathLike[str] | None = None,
    action_set: ActionSet | None = None,
    unvisited: str = "mask",
) -> EmpiricalMDP:
    """Validate arrays and build an :class:`EmpiricalMDP`.

    ``action_set`` must have A actions (default: simlab's 16 primitives when A is 16, else
    None); ``unvisited`` is ``mask`` or ``self-loop`` (see :attr:`EmpiricalMDP.valid`).

    Raises :class:`ConfigError` naming ``source`` and the array: T not
    (S, A, S), negative or non-finite entries, rows not summing to 1, goal
    arrays or centres of the wrong shape.
    """
    from simlab.agents.planning import validate_mdp

    path = None if source is None else str(source)
    T = np.asarray(T)
    validate_mdp(T, atol=_ROW_ATOL, path=path, p_name="T")
    T = T.astype(np.float64)
    S, A = T.shape[:2]
    names: tuple[str, ...] = ()
    if goal_names is not None or goal_masks is not None:
        if goal_names is None or goal_masks is None:
            missing = "goal_masks" if goal_masks is None else "goal_names"
            raise ConfigError("goal_names and goal_masks come together", path=path, key=missing)
        names = tuple(str(n) for n in np.asarray(goal_names).ravel())
        goal_masks = np.asarray(goal_masks)
        if goal_masks.shape != (len(names), S):
            raise ConfigError(
                f"expected shape (G, S) = ({len(names)}, {S}), got {goal_masks.shape}",
                path=path,
                key="goal_masks",
            )
        if len(set(names)) != len(names):
            raise ConfigError(f"duplicate goal names in {list(names)}", path=path, key="goal_names")
        goal_masks = goal_masks.astype(bool)
    if centres is not None:
        centres = np.asarray(centres, dtype=np.float64)
        if centres.shape != (S, 2):
            raise ConfigError(
                f"expected shape (S, 2) = ({S}, 2), got {centres.shape}", path=path, key="centres"
            )
    bounds_t = None
    if bounds is not None:
        b = np.asarray(bounds, dtype=np.float64).ravel()
        if b.shape != (4,) or not (b[0] < b[2] and b[1] < b[3]):
            raise ConfigError(
                f"expected (x_min, y_min, x_max, y_max) with min < max, got {b.tolist()}",
                path=path,
                key="bounds",
            )
        bounds_t = (float(b[0]), float(b[1]), float(b[2]), float(b[3]))
    for name, arr, shape in (("counts", counts, (S, A, S)), ("visited", visited, (S, A)),
                             ("entropy", entropy, (S, A))):  # fmt: skip
        if arr is not None and np.shape(arr) != shape:
            raise ConfigError(f"expected shape {shape}, got {np.shape(arr)}", path=path, key=name)
    from simlab.data.estimate import check_unvisited_rule

    check_unvisited_rule(unvisited)
    if action_set is None and A == 16:
        action_set = action_set_from_metadata(None, A, where=path or "mdp")
    if action_set is not None and action_set.n_actions != A:
        raise ConfigError(f"action_set says {action_set.n_actions} actions, T has {A}",
                          path=path, key="action_set")
    return EmpiricalMDP(
        T=_readonly(T),
        goal_names=names,
        goal_masks=_readonly(goal_masks),
        centres=_readonly(centres),
        bounds=bounds_t,
        counts=_readonly(counts),
        visited=_readonly(visited),
        entropy=_readonly(entropy),
        source=path,
        action_set=action_set,
        unvisited=unvisited,
    )


def load_mdp(path: str | os.PathLike[str]) -> EmpiricalMDP:
    """Read and validate an ``mdp.npz`` (no pickle). Only ``T`` is required.

    Errors name the file and the array (missing ``T``, rows not summing to 1,
    shapes that disagree).
    """
    from simlab.agents.storage import load_npz

    arrays, meta = load_npz(path, ("T",))
    path = Path(path)
    T = arrays["T"]
    n_actions = int(T.shape[1]) if T.ndim == 3 else 16
    return mdp_from_arrays(
        T,
        goal_names=arrays.get("goal_names"),
        goal_masks=arrays.get("goal_masks"),
        centres=arrays.get("centres"),
        bounds=arrays.get("bounds"),
        counts=arrays.get("counts"),
        visited=arrays.get("visited"),
        entropy=arrays.get("entropy"),
        source=path,
        action_set=(action_set_from_metadata(meta, n_actions, where=str(path))
                    if meta.get("action_set") is not None or n_actions == 16 else None),
        unvisited=str(meta.get("unvisited", "mask")),
    )


class EmpiricalMDPEnv(gym.Env):
    """Gymnasium env sampling ``s'`` from an empirical ``T`` (see the module's env card).

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
            return f"t={self._t}/{self.horizon} state={self._state} goal={self.goal}\n"
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
