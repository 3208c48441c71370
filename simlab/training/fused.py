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

__all__ = ["MdpTask", "Observer", "run_loop"]

#: The environment of :func:`run_loop`: ``cdf`` (S, A, S) cumulative ``T`` along
#: ``s'``; ``reward_next`` (S,); ``start_cdf`` (S,); ``horizon`` steps per episode;
#: ``valid`` (S, A) bool or ``core.NO_MASK``; ``terminal`` (S,) bool or
#: ``core.NO_TERMINAL``.
MdpTask = namedtuple("MdpTask", ["cdf", "reward_next", "start_cdf", "horizon", "valid",
                                 "terminal"])

#: A passive Q-learning observer: its ``Q`` (0 rows: none), its ``params``
#: (:class:`~simlab.agents.core.AgentParams`) and the episode it takes over at (-1: never).
Observer = namedtuple("Observer", ["Q", "params", "takeover_episode"])


@njit(cache=True)
def run_loop(task, Q, model, p, observer, n_episodes, steps0, env_rng, agent_rng):
    """Train agent ``(Q, model, p)`` for ``n_episodes`` on ``task``.

    If ``observer.Q`` has rows, a Q-learner learns from every transition; from episode
    ``observer.takeover_episode`` on it selects the actions and the actor stops
    learning. Returns ``(rewards (n_episodes,), actor steps done in total)``.
    """
    totals = np.zeros(n_episodes)
    watching = observer.Q.shape[0] > 0
    takeover = observer.takeover_episode
    steps = steps0
    for ep in range(n_episodes):
        acting = takeover < 0 or ep < takeover
        s = sample_from_cdf(task.start_cdf, env_rng)
        total = 0.0
        for _ in range(task.horizon):
            if acting:
                a = core.act(Q, s, p, task.valid, agent_rng)
            else:
                a = core.act(observer.Q, s, observer.params, task.valid, agent_rng)
            s_next = sample_from_cdf(task.cdf[s, a], env_rng)
            r = task.reward_next[s_next]
            if watching:
                core.learn(model, observer.Q, s, a, r, s_next, observer.params, task.valid,
                           task.terminal, 0)
            if acting:
                steps = core.learn(model, Q, s, a, r, s_next, p, task.valid, task.terminal,
                                   steps)
            total += r
            s = s_next
            if task.terminal.shape[0] > 0 and task.terminal[s]:
                break
        totals[ep] = total
    return totals, steps
