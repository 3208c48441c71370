"""Plain per-step Python training loop: Gymnasium env ``step`` + Python Q-learning.

The baseline of ``benchmarks/visitlab_speed.py`` and the cross-check of the fused
loops: for an epsilon-greedy Q-learner it consumes the environment and agent
random streams exactly as :mod:`simlab.visitlab.training` does, so the same seeds
give the same curve and Q table (tests assert this), and the speed ratio compares
the same computation.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from simlab.agents.config import QLearningConfig, Selection
from simlab.base.errors import ConfigError


def python_greedy(q: np.ndarray, rng: np.random.Generator) -> int:
    """Argmax with uniform random tie-breaking (one draw only when there is a tie)."""
    best = q.max()
    ties = np.flatnonzero(q == best)
    if ties.size == 1:
        return int(ties[0])
    return int(ties[rng.integers(0, ties.size)])


def python_epsilon_greedy(q: np.ndarray, epsilon: float, rng: np.random.Generator) -> int:
    """Uniform action with probability ``epsilon``, else :func:`python_greedy`."""
    if epsilon > 0.0 and rng.random() < epsilon:
        return int(rng.integers(0, q.shape[0]))
    return python_greedy(q, rng)


def train_python(
    env: Any,
    config: QLearningConfig,
    trials: int,
    env_rng: np.random.Generator,
    agent_rng: np.random.Generator,
    Q: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Q-learning, one Python call per step; returns ``(returns (trials,), Q (S, A))``.

    ``env`` is an unwrapped Visit-the-lab env; its ``np_random`` is replaced by
    ``env_rng``. Epsilon-greedy or greedy selection only. ``Q`` defaults to the
    config's initial value everywhere.
    """
    if not isinstance(config, QLearningConfig) or config.selection == Selection.SOFTMAX:
        raise ConfigError("the Python reference loop runs epsilon-greedy Q-learning only",
                          key="agent")
    env.np_random = env_rng
    if Q is None:
        Q = np.full((env.observation_space.n, env.action_space.n), config.initial_value)
    epsilon = config.epsilon if config.selection == Selection.EPSILON_GREEDY else 0.0
    alpha, gamma = config.alpha, config.gamma
    returns = np.zeros(trials, dtype=np.float64)
    for k in range(trials):
        s, _ = env.reset()
        total = 0.0
        truncated = False
        while not truncated:
            a = python_epsilon_greedy(Q[s], epsilon, agent_rng)
            s_next, r, _, truncated, _ = env.step(a)
            td = r + gamma * Q[s_next].max() - Q[s, a]
            Q[s, a] += alpha * td
            total += r
            s = s_next
        returns[k] = total
    return returns, Q
