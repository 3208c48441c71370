"""Thin tabular agents built on the numba kernels (thesis 1.2-1.6).

Each agent owns a Q-table ``Q`` (S, A) float64, its hyper-parameters (a frozen
config from :mod:`simlab.agents.config`) and a ``numpy.random.Generator``:

* ``act(s) -> a`` — behaviour action (exploration included);
* ``greedy_action(s) -> a`` — exploitation only (random tie-breaking);
* ``update(s, a, r, s_next)`` — learn from one transition;
* ``fit(env, n_episodes)`` — run episodes on a Gymnasium env with ``Discrete``
  spaces and return the reward of each episode.

The per-step work happens in the act / learn / plan steps of the agent core
(:mod:`simlab.agents.core`), which the fused njit loops of
:mod:`simlab.training.fused` and :mod:`simlab.visitlab.training` call too, so an
agent used from Python makes the same random draws, in the same order (tested):
``act`` consumes the agent's Generator, ``update`` consumes nothing.

Every agent takes keyword arguments ``valid`` (S, A) bool and ``terminal`` (S,) bool
(None: no constraint), also settable with :meth:`TabularAgent.constrain`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from simlab.agents import core
from simlab.agents import kernels as K
from simlab.agents.config import (
    ModelBasedConfig,
    PassiveObserverConfig,
    QLearningConfig,
    RMaxConfig,
    Selection,
    SlidingWindowConfig,
)
from simlab.agents.sparse_model import CountModel
from simlab.agents.window_model import WindowModel
from simlab.base.errors import ConfigError

__all__ = [
    "ModelBasedAgent",
    "PassiveObserverAgent",
    "QLearningAgent",
    "RMaxAgent",
    "SlidingWindowAgent",
    "TabularAgent",
]


def _check_sizes(n_states: int, n_actions: int) -> None:
    for name, value in (("n_states", n_states), ("n_actions", n_actions)):
        if not (isinstance(value, int | np.integer) and value >= 1):
            raise ConfigError(f"expected an integer >= 1, got {value!r}", key=name)


def _check_rng(rng: Any) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise ConfigError(
            f"expected a numpy.random.Generator, got {type(rng).__name__}",
            key="rng",
            fix="pass np.random.default_rng(seed)",
        )
    return rng


class TabularAgent:
    """Common interface; subclasses set ``Q`` and implement ``act`` and ``update``."""

    name: str = "agent"
    n_states: int
    n_actions: int
    Q: np.ndarray
    rng: np.random.Generator
    valid: np.ndarray = core.NO_MASK
    """(S, A) bool valid-action mask (empty: every action valid); see :meth:`constrain`."""
    terminal: np.ndarray = core.NO_TERMINAL
    """(S,) bool terminal states (empty: none); see :meth:`constrain`."""

    def constrain(self, valid: np.ndarray | None = None,
                  terminal: np.ndarray | None = None) -> None:
        """Set the valid-action mask ``valid`` (S, A) bool and the ``terminal`` (S,) bool
        flags (None: all valid / no terminal state); semantics in :mod:`simlab.agents.core`.
        """
        self.valid = core.as_mask(valid, self.n_states, self.n_actions)
        self.terminal = core.as_terminal(terminal, self.n_states)

    def act(self, s: int) -> int:
        raise NotImplementedError

    def update(self, s: int, a: int, r: float, s_next: int) -> None:
        raise NotImplementedError

    def greedy_action(self, s: int) -> int:
        """``argmax_a Q[s, a]`` with random tie-breaking (consumes ``rng`` on ties)."""
        return int(K.greedy_action(self.Q[s], self.rng))

    def end_episode(self) -> None:
        """Called by :meth:`fit` after each episode (no-op by default)."""

    def fit(self, env: Any, n_episodes: int, *, progress: bool = False) -> np.ndarray:
        """Run ``n_episodes`` on a Gymnasium env (``Discrete`` obs/actions); returns rewards.

        The env is reset without a seed after the first episode (seed the env
        once yourself with ``env.reset(seed=...)`` beforehand for reproducibility).
        Returns (n_episodes,) float64 total reward per episode.
        """
        from tqdm.auto import tqdm

        totals = np.zeros(n_episodes)
        for ep in tqdm(range(n_episodes), disable=not progress, desc=self.name, unit="ep"):
            s, _ = env.reset()
            s = int(s)
            done = False
            while not done:
                a = self.act(s)
                s_next, r, terminated, truncated, _ = env.step(a)
                s_next = int(s_next)
                if terminated:
                    self.update_terminal(s, a, float(r))
                else:
                    self.update(s, a, float(r), s_next)
                totals[ep] += r
                s = s_next
                done = terminated or truncated
            self.end_episode()
        return totals

    def update_terminal(self, s: int, a: int, r: float) -> None:
        """Update on a transition into a terminal state (default: treat as ``s_next = s``).

        simlab's tabular tasks have fixed-length episodes (time-limit truncation,
        never termination), so this default is rarely used; Q-learning overrides it
        to drop the bootstrap.
        """
        self.update(s, a, r, s)

    @property
    def V(self) -> np.ndarray:
        """(S,) ``max_a Q[s, a]``."""
        return self.Q.max(axis=1)


class QLearningAgent(TabularAgent):
    """Model-free Q-learning with epsilon-greedy or softmax selection."""

    name = "q-learning"

    def __init__(
        self,
        n_states: int,
        n_actions: int,
        config: QLearningConfig | None = None,
        rng: np.random.Generator | None = None,
        *,
        valid: np.ndarray | None = None,
        terminal: np.ndarray | None = None,
    ) -> None:
        _check_sizes(n_states, n_actions)
        self.config = QLearningConfig() if config is None else config
        self.rng = _check_rng(rng)
        self.n_states, self.n_actions = int(n_states), int(n_actions)
        self.Q = np.full((self.n_states, self.n_actions), self.config.initial_value)
        self.params = core.agent_params(self.config)
        self.constrain(valid, terminal)

    def act(self, s: int) -> int:
        return int(core.act(self.Q, s, self.params, self.valid, self.rng))

    def update(self, s: int, a: int, r: float, s_next: int) -> None:
        core.learn(core.NO_MODEL, self.Q, s, a, r, s_next, self.params, self.valid,
                   self.terminal, 0)

    def update_terminal(self, s: int, a: int, r: float) -> None:
        K.q_learning_update(self.Q, s, a, r, s, self.config.alpha, 0.0)


class _ModelAgentBase(TabularAgent):
    """Shared stepping logic of the model-based agents (count or window model)."""

    model: CountModel | WindowModel
    # Effective kernel settings (read by the fused loops; derived from the config):
    m_known: int
    """Visits after which a pair's model is used (1; R-max: ``m``)."""
    replan_when_known: bool
    """Run value iteration the step a pair becomes known."""
    selection: int
    """Selection code (:class:`~simlab.agents.config.Selection`)."""
    epsilon: float
    """Exploration probability (epsilon-greedy)."""
    tau: float
    """Softmax temperature."""

    def act(self, s: int) -> int:
        return int(core.act(self.Q, s, self.params, self.valid, self.rng))

    def update(self, s: int, a: int, r: float, s_next: int) -> None:
        self.steps = int(core.learn(self.model, self.Q, s, a, r, s_next, self.params,
                                    self.valid, self.terminal, self.steps))

    def plan(self, max_sweeps: int | None = None) -> int:
        """Plan on the current model now (:func:`simlab.agents.core.plan`); returns the
        sweeps done."""
        p = self.params if max_sweeps is None else self.params._replace(max_sweeps=max_sweeps)
        return int(core.plan(self.model, self.Q, p, self.valid, self.terminal))

    def transition_matrix(self) -> tuple[np.ndarray, np.ndarray]:
        """Dense ``(T, R)`` of the learned model (small MDPs only)."""
        return self.model.transition_matrix()


class ModelBasedAgent(_ModelAgentBase):
    """Model-based agent: count model + incremental backups + periodic value iteration.

    With ``selection="epsilon-greedy"`` it is the thesis's epsilon-greedy MB agent;
    with ``selection="softmax"`` its value-iteration-softmax agent (Algorithm 4).
    """

    name = "model-based"

    def __init__(
        self,
        n_states: int,
        n_actions: int,
        config: ModelBasedConfig | None = None,
        rng: np.random.Generator | None = None,
        *,
        valid: np.ndarray | None = None,
        terminal: np.ndarray | None = None,
    ) -> None:
        _check_sizes(n_states, n_actions)
        self.config = ModelBasedConfig() if config is None else config
        self.rng = _check_rng(rng)
        c = self.config
        self.n_states, self.n_actions = int(n_states), int(n_actions)
        self.Q = np.full((self.n_states, self.n_actions), c.initial_value)
        self.model = self._new_model()
        self.m_known = 1
        self.replan_when_known = False
        self.selection = int(c.selection)
        self.epsilon, self.tau = c.epsilon, c.tau
        self.steps = 0
        self.params = core.agent_params(c)
        self.constrain(valid, terminal)

    def _new_model(self) -> CountModel | WindowModel:
        return CountModel(self.n_states, self.n_actions, self.config.capacity)


class SlidingWindowAgent(ModelBasedAgent):
    """Model-based agent whose model keeps only the last ``window`` outcomes per pair."""

    name = "sliding-window"

    def __init__(
        self,
        n_states: int,
        n_actions: int,
        config: SlidingWindowConfig | None = None,
        rng: np.random.Generator | None = None,
        *,
        valid: np.ndarray | None = None,
        terminal: np.ndarray | None = None,
    ) -> None:
        super().__init__(
            n_states, n_actions, SlidingWindowConfig() if config is None else config, rng,
            valid=valid, terminal=terminal,
        )

    def _new_model(self) -> WindowModel:
        cap = max(1, min(self.config.capacity, self.n_states * self.n_actions))
        return WindowModel(self.n_states, self.n_actions, self.config.window, cap)


class RMaxAgent(_ModelAgentBase):
    """R-max: optimistic ``r_max / (1 - gamma)`` until ``m`` visits, greedy action selection."""

    name = "rmax"

    def __init__(
        self,
        n_states: int,
        n_actions: int,
        config: RMaxConfig | None = None,
        rng: np.random.Generator | None = None,
        *,
        valid: np.ndarray | None = None,
        terminal: np.ndarray | None = None,
    ) -> None:
        _check_sizes(n_states, n_actions)
        self.config = RMaxConfig() if config is None else config
        self.rng = _check_rng(rng)
        c = self.config
        self.n_states, self.n_actions = int(n_states), int(n_actions)
        self.Q = K.rmax_q_init(self.n_states, self.n_actions, float(c.r_max), float(c.gamma))
        self.model = CountModel(self.n_states, self.n_actions, c.capacity)
        self.m_known = c.m
        self.replan_when_known = c.replan_when_known
        self.selection = int(Selection.GREEDY)
        self.epsilon, self.tau = 0.0, 0.0
        self.steps = 0
        self.params = core.agent_params(c)
        self.constrain(valid, terminal)

    def known(self) -> np.ndarray:
        """(S, A) bool: pairs visited at least ``m`` times."""
        return self.model.n_sa >= self.config.m


class PassiveObserverAgent(TabularAgent):
    """A model-free observer learning from a model-based actor, able to take over.

    Before :meth:`take_over`: the actor chooses actions and both learn from each
    transition. After: the observer chooses (with its own selection rule) and
    only the observer learns. ``Q`` is the observer's table; ``actor.Q`` the actor's.
    """

    name = "passive-observer"

    def __init__(
        self,
        n_states: int,
        n_actions: int,
        config: PassiveObserverConfig | None = None,
        rng: np.random.Generator | None = None,
        *,
        valid: np.ndarray | None = None,
        terminal: np.ndarray | None = None,
    ) -> None:
        _check_sizes(n_states, n_actions)
        self.config = PassiveObserverConfig() if config is None else config
        self.rng = _check_rng(rng)
        self.n_states, self.n_actions = int(n_states), int(n_actions)
        # one Generator shared by both, so the draw order matches the fused loop
        self.actor = ModelBasedAgent(n_states, n_actions, self.config.actor, self.rng)
        self.observer = QLearningAgent(n_states, n_actions, self.config.observer, self.rng)
        self.controlling = "actor"
        self.constrain(valid, terminal)

    def constrain(self, valid: np.ndarray | None = None,
                  terminal: np.ndarray | None = None) -> None:
        super().constrain(valid, terminal)
        if hasattr(self, "actor"):
            self.actor.constrain(valid, terminal)
            self.observer.constrain(valid, terminal)

    @property
    def Q(self) -> np.ndarray:  # type: ignore[override]
        return self.observer.Q

    def take_over(self) -> None:
        """Hand control to the observer (irreversible)."""
        self.controlling = "observer"

    def act(self, s: int) -> int:
        if self.controlling == "actor":
            return self.actor.act(s)
        return self.observer.act(s)

    def update(self, s: int, a: int, r: float, s_next: int) -> None:
        self.observer.update(s, a, r, s_next)
        if self.controlling == "actor":
            self.actor.update(s, a, r, s_next)
