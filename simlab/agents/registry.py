"""Agent names used by the CLI and experiments, with their default hyper-parameters.

=====================  ==================================================================
name                   agent
=====================  ==================================================================
``q-learning``         Q-learning, epsilon-greedy (thesis Fig. 4.1a, model-free)
``q-softmax``          Q-learning, softmax (Fig. 4.1b, model-free)
``mb-egreedy``         model-based, epsilon-greedy (Fig. 4.1a)
``vi-softmax``         model-based value-iteration softmax (Algorithm 4, Fig. 4.1b/4.9)
``rmax``               R-max (m=1; the paper uses m=5 for the social task)
``sliding-window``     model-based, softmax, model = last 20 outcomes per pair
``passive-observer``   Q-learner observing an epsilon-greedy MB actor (IMOL poster)
=====================  ==================================================================

``make_agent("vi-softmax", S, A, rng, tau=0.05)`` overrides fields of the preset;
for the passive observer, prefix with ``actor.`` / ``observer.`` (``observer.alpha=0.5``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from simlab.agents.agents import (
    ModelBasedAgent,
    PassiveObserverAgent,
    QLearningAgent,
    RMaxAgent,
    SlidingWindowAgent,
    TabularAgent,
)
from simlab.agents.config import (
    ModelBasedConfig,
    PassiveObserverConfig,
    QLearningConfig,
    RMaxConfig,
    Selection,
    SlidingWindowConfig,
    config_from_dict,
    config_to_dict,
)
from simlab.base.errors import ConfigError

__all__ = ["AGENTS", "AgentSpec", "agent_config", "agent_names", "make_agent"]


@dataclasses.dataclass(frozen=True)
class AgentSpec:
    """A registered agent: its class and its preset configuration."""

    name: str
    agent_class: type[TabularAgent]
    config: Any
    description: str


AGENTS: dict[str, AgentSpec] = {
    spec.name: spec
    for spec in (
        AgentSpec("q-learning", QLearningAgent, QLearningConfig(), "Q-learning, epsilon-greedy"),
        AgentSpec(
            "q-softmax",
            QLearningAgent,
            QLearningConfig(selection=Selection.SOFTMAX),
            "Q-learning, softmax",
        ),
        AgentSpec("mb-egreedy", ModelBasedAgent, ModelBasedConfig(), "model-based, epsilon-greedy"),
        AgentSpec(
            "vi-softmax",
            ModelBasedAgent,
            ModelBasedConfig(selection=Selection.SOFTMAX),
            "model-based value-iteration softmax",
        ),
        AgentSpec("rmax", RMaxAgent, RMaxConfig(), "R-max (optimistic until m visits)"),
        AgentSpec(
            "sliding-window",
            SlidingWindowAgent,
            SlidingWindowConfig(selection=Selection.SOFTMAX),
            "model-based softmax on the last H outcomes per pair",
        ),
        AgentSpec(
            "passive-observer",
            PassiveObserverAgent,
            PassiveObserverConfig(),
            "Q-learner observing an epsilon-greedy model-based actor, then taking over",
        ),
    )
}


def agent_names() -> list[str]:
    """Registered agent names."""
    return list(AGENTS)


def _spec(name: str) -> AgentSpec:
    try:
        return AGENTS[name]
    except KeyError:
        raise ConfigError(
            f"unknown agent {name!r}; known agents: {', '.join(AGENTS)}", key="agent"
        ) from None


def agent_config(name: str, overrides: Mapping[str, Any] | None = None) -> Any:
    """The preset config of agent ``name`` with ``overrides`` applied (validated).

    Keys of nested configs use a dot: ``{"observer.alpha": 0.5}``.
    """
    spec = _spec(name)
    values = config_to_dict(spec.config)
    for key, value in (overrides or {}).items():
        target = values
        parts = key.split(".")
        for part in parts[:-1]:
            if not isinstance(target.get(part), dict):
                raise ConfigError(f"unknown parameter {key!r} for agent {name!r}", key=key)
            target = target[part]
        if parts[-1] not in target:
            raise ConfigError(
                f"unknown parameter {key!r} for agent {name!r}; known: "
                f"{', '.join(_flat_keys(values))}",
                key=key,
            )
        target[parts[-1]] = value
    return config_from_dict(type(spec.config), values)


def _flat_keys(values: Mapping[str, Any], prefix: str = "") -> list[str]:
    keys = []
    for k, v in values.items():
        if isinstance(v, Mapping):
            keys.extend(_flat_keys(v, f"{prefix}{k}."))
        else:
            keys.append(f"{prefix}{k}")
    return keys


def make_agent(
    name: str,
    n_states: int,
    n_actions: int,
    rng: np.random.Generator,
    config: Any | None = None,
    **overrides: Any,
) -> TabularAgent:
    """Build agent ``name`` for an (S, A) task.

    ``config`` replaces the preset entirely; otherwise keyword ``overrides``
    change fields of the preset (``make_agent("vi-softmax", S, A, rng, tau=0.05)``).
    """
    spec = _spec(name)
    if config is None:
        config = agent_config(name, overrides)
    elif overrides:
        raise ConfigError("pass either a config or keyword overrides, not both", key="config")
    agent = spec.agent_class(n_states, n_actions, config, rng)
    agent.name = name
    return agent
