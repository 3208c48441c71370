"""Fused njit training loops: a dense tabular MDP and an agent in one compiled loop.

The environment is given by ``cdf`` (S, A, S), the cumulative sums of ``T`` along
``s'``; ``reward_next`` (S,) the reward earned on arriving in a state;
``start_cdf`` (S,) the cumulative start-state distribution; ``horizon`` steps
per episode. Two Generators: ``env_rng`` draws start and next states,
``agent_rng`` the agent's choices.

Per step, in this order (the Python agents of :mod:`simlab.agents.agents` make
exactly the same draws, see :func:`simlab.training.harness.run_episodes`)::

    a  = select_action(Q[s], ...)            # agent_rng
    s' = sample_from_cdf(cdf[s, a], env_rng)
    r  = reward_next[s']
    update(s, a, r, s')                       # no randomness

and at the start of each episode ``s = sample_from_cdf(start_cdf, env_rng)``.
Each function returns the (n_episodes,) total reward per episode and updates
the agent state it is given (``Q``, ``model``) in place.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from simlab.agents.kernels import (
    model_based_update,
    model_value_iteration,
    q_learning_update,
    sample_from_cdf,
    select_action,
)

__all__ = ["run_model_based", "run_q_learning"]


@njit(cache=True)
def run_q_learning(
    cdf, reward_next, start_cdf, horizon, n_episodes, Q, alpha, gamma, method, epsilon, tau,
    env_rng, agent_rng,
):  # fmt: skip
    """Q-learning (eq. 1.12) with ``method`` selection; returns rewards per episode."""
    totals = np.zeros(n_episodes)
    for ep in range(n_episodes):
        s = sample_from_cdf(start_cdf, env_rng)
        total = 0.0
        for _ in range(horizon):
            a = select_action(Q[s], method, epsilon, tau, agent_rng)
            s_next = sample_from_cdf(cdf[s, a], env_rng)
            r = reward_next[s_next]
            q_learning_update(Q, s, a, r, s_next, alpha, gamma)
            total += r
            s = s_next
        totals[ep] = total
    return totals


@njit(cache=True)
def run_model_based(
    cdf, reward_next, start_cdf, horizon, n_episodes,
    Q, model, gamma, method, epsilon, tau,
    m_known, incremental, replan_when_known, plan_every, max_sweeps, tol, steps0,
    Q_obs, alpha_obs, gamma_obs, method_obs, epsilon_obs, tau_obs, takeover_episode,
    env_rng, agent_rng,
):  # fmt: skip
    """Model-based agent (count or window ``model``), optionally with a passive observer.

    The actor selects with ``method`` on ``Q``, observes into ``model`` and
    updates ``Q`` with :func:`~simlab.agents.kernels.model_based_update`; every
    ``plan_every`` actor steps (counted from ``steps0``) it runs value iteration.
    If ``Q_obs`` has rows, a Q-learner (``alpha_obs``, ``gamma_obs``) learns from
    every transition; from episode ``takeover_episode`` on (``-1``: never) the
    observer selects the actions (``method_obs``) and the actor stops learning.
    Returns ``(rewards (n_episodes,), actor steps done in total)``.
    """
    totals = np.zeros(n_episodes)
    observe = Q_obs.shape[0] > 0
    steps = steps0
    for ep in range(n_episodes):
        acting = takeover_episode < 0 or ep < takeover_episode
        s = sample_from_cdf(start_cdf, env_rng)
        total = 0.0
        for _ in range(horizon):
            if acting:
                a = select_action(Q[s], method, epsilon, tau, agent_rng)
            else:
                a = select_action(Q_obs[s], method_obs, epsilon_obs, tau_obs, agent_rng)
            s_next = sample_from_cdf(cdf[s, a], env_rng)
            r = reward_next[s_next]
            if observe:
                q_learning_update(Q_obs, s, a, r, s_next, alpha_obs, gamma_obs)
            if acting:
                model_based_update(
                    model, Q, s, a, r, s_next, gamma, m_known, incremental,
                    replan_when_known, max_sweeps, tol,
                )  # fmt: skip
                steps += 1
                if plan_every > 0 and steps % plan_every == 0:
                    model_value_iteration(model, Q, gamma, max_sweeps, tol, m_known)
            total += r
            s = s_next
        totals[ep] = total
    return totals, steps
