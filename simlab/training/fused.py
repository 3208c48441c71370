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
If ``s'`` is a terminal state (``task.terminal``) its reward is counted and the
episode ends early; the next one starts from the start distribution (the real
robot's "reward on arrival, then restart"). Actions are drawn among the valid
ones (``task.valid``). :func:`run_loop` returns the (n_episodes,) total reward per
episode and updates the agent state it is given (``Q``, ``model``) in place.

One loop serves every agent: the act / learn / plan steps are those of
:mod:`simlab.agents.core` (the Python agent classes call the same steps).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from simlab.agents import core
from simlab.agents.kernels import sample_from_cdf

__all__ = ["MdpTask", "Observer", "run_learner", "run_loop"]

#: The environment of :func:`run_loop`: ``cdf`` (S, A, S) cumulative ``T`` along
#: ``s'``; ``reward_next`` (S,); ``start_cdf`` (S,); ``horizon`` steps per episode;
#: ``valid`` (S, A) bool or ``core.NO_MASK``; ``terminal`` (S,) bool or
#: ``core.NO_TERMINAL``.
MdpTask = namedtuple("MdpTask", ["cdf", "reward_next", "start_cdf", "horizon", "valid",
                                 "terminal"])

#: A passive Q-learning observer (:class:`simlab.agents.core.Observer`): its ``Q`` (0
#: rows: none), its ``params`` and the episode it takes over at (-1: never).
Observer = core.Observer


@njit(cache=True)
def run_learner(task, lr, n_episodes, steps0, env_rng, agent_rng):
    """Train :class:`~simlab.agents.core.Learner` ``lr`` for ``n_episodes`` on ``task``.

    Per step :func:`~simlab.agents.core.learner_act` then
    :func:`~simlab.agents.core.learner_learn` (the observer, if any, learns from every
    transition and acts from its take-over episode on). Returns ``(rewards
    (n_episodes,), actor steps done in total)``.
    """
    totals = np.zeros(n_episodes)
    steps = steps0
    for ep in range(n_episodes):
        s = sample_from_cdf(task.start_cdf, env_rng)
        total = 0.0
        for _ in range(task.horizon):
            a = core.learner_act(lr, s, ep, task.valid, agent_rng)
            s_next = sample_from_cdf(task.cdf[s, a], env_rng)
            r = task.reward_next[s_next]
            steps = core.learner_learn(lr, s, a, r, s_next, ep, task.valid, task.terminal,
                                       steps)
            total += r
            s = s_next
            if task.terminal.shape[0] > 0 and task.terminal[s]:
                break
        totals[ep] = total
    return totals, steps


def run_loop(task, Q, model, p, observer, n_episodes, steps0, env_rng, agent_rng):
    """:func:`run_learner` of agent ``(Q, model, p)`` watched by ``observer`` (kept for
    callers of the former signature; updates ``Q`` and ``model`` in place)."""
    return run_learner(task, core.Learner(Q, model, p, observer), n_episodes, steps0,
                       env_rng, agent_rng)
