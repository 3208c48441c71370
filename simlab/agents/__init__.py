"""Agent library shared by the physics half and Visit-the-lab (thesis 1.2-1.6).

Layers, each its own module:

* :mod:`simlab.agents.kernels` — numba ``@njit`` kernels (action selection, Q-learning,
  sparse count model, sliding-window model, R-max) for fused env + agent loops;
* :mod:`simlab.agents.planning` — pure planners on dense ``(P, R, gamma)``: value and
  policy iteration, Bellman operators, exact returns;
* :mod:`simlab.agents.config` — frozen, validated hyper-parameter dataclasses;
* :mod:`simlab.agents.agents` — thin agent classes (``act``, ``update``, ``fit``);
* :mod:`simlab.agents.registry` — agent names (``vi-softmax``, ``rmax``, ...) and presets;
* :mod:`simlab.agents.policy` — the greedy policy of a Q-table, untried actions masked
  (:func:`greedy`);
* :mod:`simlab.agents.storage` — save/load of Q-tables, models and agents (npz, no pickle).

Agents know only ``(state, action, reward, next state)`` or ``(P, R)``; nothing
here knows about environments, physics or files other than their own.
"""

from __future__ import annotations

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
)
from simlab.agents.planning import (
    bellman_expectation_operator,
    bellman_optimality_operator,
    expected_return,
    greedy_policy,
    optimal_finite_horizon_return,
    policy_evaluation,
    policy_iteration,
    reward_on_arrival,
    validate_mdp,
    value_iteration,
)
from simlab.agents.policy import greedy, masked_argmax
from simlab.agents.registry import AGENTS, agent_config, agent_names, make_agent
from simlab.agents.sparse_model import CountModel
from simlab.agents.storage import (
    load_agent,
    load_model,
    load_q_table,
    save_agent,
    save_model,
    save_q_table,
)
from simlab.agents.window_model import WindowModel

__all__ = [
    "AGENTS",
    "CountModel",
    "ModelBasedAgent",
    "ModelBasedConfig",
    "PassiveObserverAgent",
    "PassiveObserverConfig",
    "QLearningAgent",
    "QLearningConfig",
    "RMaxAgent",
    "RMaxConfig",
    "Selection",
    "SlidingWindowAgent",
    "SlidingWindowConfig",
    "TabularAgent",
    "WindowModel",
    "agent_config",
    "agent_names",
    "bellman_expectation_operator",
    "bellman_optimality_operator",
    "expected_return",
    "greedy",
    "greedy_policy",
    "load_agent",
    "load_model",
    "load_q_table",
    "make_agent",
    "masked_argmax",
    "optimal_finite_horizon_return",
    "policy_evaluation",
    "policy_iteration",
    "reward_on_arrival",
    "save_agent",
    "save_model",
    "save_q_table",
    "validate_mdp",
    "value_iteration",
]
