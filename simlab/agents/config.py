"""Hyper-parameters of every agent: frozen, validated dataclasses (thesis 1.3-1.6).

Defaults are the thesis's (gamma 0.9, alpha 0.7, epsilon 0.05, tau 0.1); the
paper's settings (alpha 0.5, R-max m=1 navigation / m=5 social, one VI sweep
every 1000 steps) are a ``dataclasses.replace`` away. A bad value raises
:class:`~simlab.base.errors.ConfigError` naming the field.

Decision (the thesis says "arbitrarily initialised"): Q-values of state-action
pairs an agent has never tried start **optimistic**, ``r_max / (1 - gamma)``
(``q_init=None``), so every action is tried before being dismissed. With
``q_init=0`` and softmax at tau 0.1 an agent locks onto the first action that
ever paid off: on a stochastic 41-state synthetic arena MDP
(:func:`simlab.training.synthetic.synthetic_arena_mdp`, 9 goals, 2000 episodes)
value-iteration softmax then ends at 37-81 % of the optimal return, against
93-98 % with optimistic values. Pass ``q_init=0.0`` for zero initialisation.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any

from simlab.base import validation
from simlab.base.errors import ConfigError

__all__ = [
    "AgentConfig",
    "ModelBasedConfig",
    "PassiveObserverConfig",
    "QLearningConfig",
    "RMaxConfig",
    "Selection",
    "SlidingWindowConfig",
    "config_from_dict",
    "config_to_dict",
]


class Selection(IntEnum):
    """Action-selection rule; values are the kernel codes (``simlab.agents.kernels``)."""

    GREEDY = 0
    EPSILON_GREEDY = 1
    SOFTMAX = 2

    @classmethod
    def parse(cls, value: Selection | str | int, *, key: str = "selection") -> Selection:
        """Accept a member, its value, or a name such as ``"softmax"`` / ``"epsilon-greedy"``."""
        if isinstance(value, cls):
            return value
        if isinstance(value, str):
            name = value.strip().upper().replace("-", "_")
            if name in cls.__members__:
                return cls[name]
        elif isinstance(value, int) and not isinstance(value, bool):
            try:
                return cls(value)
            except ValueError:
                pass
        known = ", ".join(m.name.lower().replace("_", "-") for m in cls)
        raise ConfigError(f"unknown selection rule {value!r}; expected one of: {known}", key=key)


def _check_bool(name: str, value: bool) -> None:
    if not isinstance(value, bool):
        raise ConfigError(f"expected true or false, got {value!r}", key=name)


def _check_selection(cfg: Any) -> None:
    object.__setattr__(cfg, "selection", Selection.parse(cfg.selection))
    validation.probability(cfg.epsilon, "epsilon")
    validation.positive(cfg.tau, "tau")


def _initial_value(cfg: Any) -> float:
    if cfg.q_init is not None:
        return float(cfg.q_init)
    return float(cfg.r_max) / (1.0 - float(cfg.gamma))


@dataclass(frozen=True)
class QLearningConfig:
    """Q-learning (thesis eq. 1.12), model-free."""

    gamma: float = 0.9
    """Discount factor in [0, 1)."""
    alpha: float = 0.7
    """Learning rate in (0, 1] (thesis 0.7, paper 0.5)."""
    selection: Selection = Selection.EPSILON_GREEDY
    """Action selection: ``epsilon-greedy``, ``softmax`` or ``greedy``."""
    epsilon: float = 0.05
    """Exploration probability of epsilon-greedy."""
    tau: float = 0.1
    """Softmax temperature (> 0)."""
    q_init: float | None = None
    """Initial value of every Q entry; ``None``: optimistic ``r_max / (1 - gamma)``."""
    r_max: float = 1.0
    """Largest one-step reward (sets the optimistic initial value)."""

    def __post_init__(self) -> None:
        validation.discount(self.gamma)
        _check_selection(self)
        if not (isinstance(self.alpha, int | float) and 0.0 < self.alpha <= 1.0):
            raise ConfigError(
                f"expected a learning rate in (0, 1], got {self.alpha!r}", key="alpha"
            )
        if self.q_init is not None:
            validation.number(self.q_init, "q_init")
        validation.number(self.r_max, "r_max")

    @property
    def initial_value(self) -> float:
        """The value Q starts at (``q_init``, or ``r_max / (1 - gamma)`` when ``None``)."""
        return _initial_value(self)


@dataclass(frozen=True)
class ModelBasedConfig:
    """Model-based agent on a sparse count model (thesis Algorithm 4, eq. 1.13-1.14).

    Planning: with ``incremental`` one Bellman backup at the visited ``(s, a)``
    every step, plus ``max_sweeps`` value-iteration sweeps (stopping early below
    ``tol``) every ``plan_every`` steps (0: never). Defaults: the thesis's 50 VI
    iterations every 10,000 steps (Fig. 4.1 caption); the paper ran one sweep
    every 1,000 steps (``plan_every=1000, max_sweeps=1``).
    """

    gamma: float = 0.9
    """Discount factor in [0, 1)."""
    selection: Selection = Selection.EPSILON_GREEDY
    """Action selection: ``epsilon-greedy``, ``softmax`` or ``greedy``."""
    epsilon: float = 0.05
    """Exploration probability of epsilon-greedy."""
    tau: float = 0.1
    """Softmax temperature (> 0)."""
    incremental: bool = True
    """One backup at the visited pair after every step."""
    plan_every: int = 10_000
    """Steps between value-iteration calls (0 = never)."""
    max_sweeps: int = 50
    """Sweeps per value-iteration call."""
    tol: float = 1e-6
    """A value-iteration call stops when a sweep changes no Q entry by more than this."""
    q_init: float | None = None
    """Value of pairs never visited; ``None``: optimistic ``r_max / (1 - gamma)``."""
    r_max: float = 1.0
    """Largest one-step reward (sets the optimistic value of unvisited pairs)."""
    capacity: int = 4096
    """Initial pool size of the sparse model in distinct (s, a, s') triples (it grows)."""
    synchronous: bool = False
    """Paper rule 2: each planning sweep is a Jacobi sweep over *all* (s, a), every
    backup reading the previous sweep's values. Thesis (False): Gauss-Seidel sweeps in
    place over the visited pairs only."""
    untried_uniform: bool = False
    """Paper rule 1 (with ``synchronous``): a never-tried pair has a uniform transition
    model over all states and reward 0, so a sweep values it at ``gamma * mean(V)``.
    Thesis (False): untried pairs keep their initial value ``q_init``."""

    def __post_init__(self) -> None:
        validation.discount(self.gamma)
        _check_selection(self)
        _check_bool("incremental", self.incremental)
        _check_bool("synchronous", self.synchronous)
        _check_bool("untried_uniform", self.untried_uniform)
        if self.untried_uniform and not self.synchronous:
            raise ConfigError("untried_uniform needs synchronous sweeps (the uniform model "
                              "of untried pairs is applied by the full sweep)",
                              key="untried_uniform", fix="also set synchronous = true")
        validation.whole(self.plan_every, "plan_every", minimum=0)
        validation.whole(self.max_sweeps, "max_sweeps", minimum=1)
        validation.positive(self.tol, "tol", allow_zero=True)
        if self.q_init is not None:
            validation.number(self.q_init, "q_init")
        validation.number(self.r_max, "r_max")
        validation.whole(self.capacity, "capacity", minimum=1)

    @property
    def initial_value(self) -> float:
        """The value of unvisited pairs (``q_init``, or ``r_max / (1 - gamma)``)."""
        return _initial_value(self)


@dataclass(frozen=True)
class SlidingWindowConfig(ModelBasedConfig):
    """Model-based agent whose model of ``(s, a)`` is its last ``window`` outcomes."""

    window: int = 20
    """Outcomes kept per state-action pair (H >= 1)."""

    def __post_init__(self) -> None:
        super().__post_init__()
        validation.whole(self.window, "window", minimum=1)


@dataclass(frozen=True)
class RMaxConfig:
    """R-max: every pair is worth ``r_max / (1 - gamma)`` until visited ``m`` times.

    Acts greedily (random tie-breaking) on optimistic values. Defaults follow the
    paper: one backup per step at the visited known pair and one value-iteration
    sweep every 1,000 steps. ``replan_when_known=True`` gives the classic R-max
    (value iteration, ``max_sweeps`` / ``tol``, the step a pair becomes known):
    exact but one full planning per pair, too slow for thousands of pairs (see
    ``benchmarks/agent_speed.py``).
    """

    gamma: float = 0.9
    """Discount factor in [0, 1)."""
    m: int = 1
    """Visits after which a pair is known (paper: 1 navigation, 5 social)."""
    r_max: float = 1.0
    """Largest one-step reward (the optimistic value is ``r_max / (1 - gamma)``)."""
    replan_when_known: bool = False
    """Run value iteration the step a pair becomes known (classic R-max)."""
    incremental: bool = True
    """One backup at the visited (known) pair after every step."""
    plan_every: int = 1000
    """Steps between value-iteration calls (0 = never)."""
    max_sweeps: int = 1
    """Sweeps per value-iteration call (also the budget of ``replan_when_known``)."""
    tol: float = 1e-6
    """A value-iteration call stops when a sweep changes no entry by more than this."""
    capacity: int = 4096
    """Initial pool size of the sparse model (it grows)."""
    synchronous: bool = False
    """Paper rule 2: Jacobi planning sweeps over all (s, a) (see ModelBasedConfig).
    Thesis (False): Gauss-Seidel sweeps in place over the visited pairs."""
    freeze: bool = False
    """Paper rule 7: a pair's model is frozen at its m-th visit (later outcomes are not
    counted). Thesis (False): counts keep accumulating after m visits."""

    def __post_init__(self) -> None:
        validation.discount(self.gamma)
        validation.whole(self.m, "m", minimum=1)
        _check_bool("synchronous", self.synchronous)
        _check_bool("freeze", self.freeze)
        validation.number(self.r_max, "r_max")
        _check_bool("replan_when_known", self.replan_when_known)
        _check_bool("incremental", self.incremental)
        validation.whole(self.plan_every, "plan_every", minimum=0)
        validation.whole(self.max_sweeps, "max_sweeps", minimum=1)
        validation.positive(self.tol, "tol", allow_zero=True)
        validation.whole(self.capacity, "capacity", minimum=1)


@dataclass(frozen=True)
class PassiveObserverConfig:
    """A Q-learner that learns from a model-based actor's transitions (IMOL 2023 poster).

    The actor (epsilon-greedy model-based by default) chooses the actions; the
    observer updates its own Q-table on every transition. After
    :meth:`~simlab.agents.agents.PassiveObserverAgent.take_over` (the training
    harness calls it after ``takeover_fraction`` of the episodes) the observer
    acts alone and the actor stops learning (no more planning cost).
    """

    actor: ModelBasedConfig = field(default_factory=ModelBasedConfig)
    """The acting model-based agent."""
    observer: QLearningConfig = field(default_factory=lambda: QLearningConfig(q_init=0.0))
    """The passive model-free learner (zero-initialised, so that after the take-over
    it exploits what it watched instead of trying every action it never saw)."""
    takeover_fraction: float = 0.5
    """Fraction of the training episodes after which the observer takes control."""

    def __post_init__(self) -> None:
        if isinstance(self.actor, dict):
            object.__setattr__(self, "actor", _build(ModelBasedConfig, self.actor, "actor"))
        if isinstance(self.observer, dict):
            object.__setattr__(self, "observer", _build(QLearningConfig, self.observer, "observer"))
        if not isinstance(self.actor, ModelBasedConfig):
            raise ConfigError("expected a ModelBasedConfig", key="actor")
        if not isinstance(self.observer, QLearningConfig):
            raise ConfigError("expected a QLearningConfig", key="observer")
        validation.probability(self.takeover_fraction, "takeover_fraction")

    @property
    def gamma(self) -> float:
        return self.observer.gamma


AgentConfig = (
    QLearningConfig | ModelBasedConfig | SlidingWindowConfig | RMaxConfig | PassiveObserverConfig
)


def _build(cls: type, values: dict[str, Any], prefix: str = "") -> Any:
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(values) - names)
    if unknown:
        where = f"{prefix}." if prefix else ""
        raise ConfigError(
            f"unknown parameter {where}{unknown[0]!r} for {cls.__name__}; "
            f"known: {', '.join(sorted(names))}",
            key=f"{where}{unknown[0]}",
        )
    return cls(**values)


def config_to_dict(cfg: Any) -> dict[str, Any]:
    """JSON-ready dict of a config (enums as lower-case names)."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(cfg):
        value = getattr(cfg, f.name)
        if dataclasses.is_dataclass(value):
            value = config_to_dict(value)
        elif isinstance(value, Selection):
            value = value.name.lower().replace("_", "-")
        out[f.name] = value
    return out


def config_from_dict(cls: type, values: dict[str, Any]) -> Any:
    """Inverse of :func:`config_to_dict`; unknown keys raise :class:`ConfigError`."""
    return _build(cls, dict(values))
