"""One agent core: act / learn / plan steps with a named parameter record (numba).

The Python agent classes (:mod:`simlab.agents.agents`), the empirical-MDP fused loop
(:mod:`simlab.training.fused`) and the Visit-the-lab loops call these steps, so an
agent's rules live here once.

Parameters travel as :class:`AgentParams`, a named tuple (numba types it as a
named record: ``p.gamma``, ``p.synchronous`` ...) built by :func:`agent_params`
from a frozen config of :mod:`simlab.agents.config`.

Optional inputs shared by the steps (``NO_MASK`` / ``NO_TERMINAL``, empty arrays,
mean "none"):

* ``valid`` — (S, A) bool, the actions allowed in each state. Selection draws only
  among the valid actions of ``s``; Q-learning targets and planning max only over
  valid actions. A state without any valid action falls back to all actions. With
  an all-True mask the random draws are bit-identical to no mask (an index among
  the ``k`` valid actions is drawn exactly as among ``A``).
* ``terminal`` — (S,) bool. A transition into a terminal state is learned with no
  bootstrap (its value is 0: nothing follows); model-based agents pin the
  terminal state's Q row to 0 and planning treats its value as 0.

Planning options of the paper's rules (Chartouny et al. 2024, sec. 2-3, and the code
published with it; the thesis variant, thesis 1.5-1.6, keeps them off). They implement the
rules as read from that code; simlab runs no side-by-side comparison with it, so no claim
of identical curves is made:

* ``synchronous`` (rule 2) — :func:`plan` runs ``max_sweeps`` Jacobi sweeps over
  *all* (s, a): every backup reads the previous sweep's values. Thesis variant:
  Gauss-Seidel sweeps in place over the visited pairs only.
* ``untried_uniform`` (rule 1) — a pair never tried keeps a uniform transition
  model over all states and reward 0, so a synchronous sweep values it at
  ``gamma * mean(V)`` (optimistic exploration, the rule of the code published with
  Chartouny et al. 2024). Thesis
  variant: untried pairs keep their initial Q. Only used by synchronous sweeps.
* ``freeze`` (rule 7, R-max) — a pair's model stops changing at its m-th visit.
  Thesis variant: counts keep accumulating after m visits.
"""

from __future__ import annotations

from collections import namedtuple
from typing import Any

import numpy as np
from numba import njit

from simlab.agents.config import (
    ModelBasedConfig,
    PassiveObserverConfig,
    QLearningConfig,
    RMaxConfig,
    Selection,
)
from simlab.agents.kernels import (
    ALL_VALID,
    count_model_new,
    masked_select,
    model_backup,
    model_observe,
    model_q_value,
    model_value_iteration,
    n_valid,
    q_learning_update,
)
from simlab.base.errors import ConfigError

__all__ = [
    "KIND_MB",
    "KIND_MF",
    "KIND_RMAX",
    "NO_MASK",
    "NO_MODEL",
    "NO_OBSERVER_Q",
    "NO_TERMINAL",
    "AgentParams",
    "Learner",
    "Observer",
    "act",
    "agent_params",
    "as_mask",
    "as_terminal",
    "learn",
    "learner_act",
    "learner_learn",
    "masked_select",
    "plan",
    "q_step",
    "synchronous_sweep",
]

KIND_MF, KIND_MB, KIND_RMAX = 0, 1, 2

#: Named parameter record of one agent (all scalars; see :func:`agent_params`).
AgentParams = namedtuple(
    "AgentParams",
    ["kind", "selection", "alpha", "gamma", "epsilon", "tau", "m_known", "incremental",
     "replan_when_known", "plan_every", "max_sweeps", "tol", "synchronous",
     "untried_uniform", "freeze"],
)

#: A passive Q-learning observer beside the acting agent: its ``Q`` (S, A) float64 (0
#: rows: no observer), its ``params`` (:class:`AgentParams`, a Q-learner) and the episode
#: (trial) from which it acts (-1: never; from then on only the observer learns).
Observer = namedtuple("Observer", ["Q", "params", "takeover_episode"])

#: One learning agent of a fused loop: its ``Q`` (S, A) float64, its ``model`` (a count
#: or window model; :data:`NO_MODEL` for Q-learning), its ``params``
#: (:class:`AgentParams`) and its ``observer`` (:class:`Observer`). :func:`learner_act`
#: and :func:`learner_learn` are its steps; every fused loop (empirical MDP,
#: Visit-the-lab tasks, combined architecture) calls them.
Learner = namedtuple("Learner", ["Q", "model", "params", "observer"])

NO_MASK = np.zeros((0, 0), dtype=np.bool_)
#: The ``Observer.Q`` of "no observer".
NO_OBSERVER_Q = np.zeros((0, 0), dtype=np.float64)
NO_TERMINAL = np.zeros(0, dtype=np.bool_)
#: A model stand-in for Q-learning (never read).
NO_MODEL = count_model_new(1, 1, 1)


def agent_params(cfg: Any) -> AgentParams:
    """The :class:`AgentParams` of an agent config (the actor's for a passive observer)."""
    if isinstance(cfg, PassiveObserverConfig):
        cfg = cfg.actor
    if isinstance(cfg, QLearningConfig):
        return AgentParams(KIND_MF, int(cfg.selection), float(cfg.alpha), float(cfg.gamma),
                           float(cfg.epsilon), float(cfg.tau), 1, False, False, 0, 1, 0.0,
                           False, False, False)
    if isinstance(cfg, RMaxConfig):
        return AgentParams(KIND_RMAX, int(Selection.GREEDY), 0.0, float(cfg.gamma), 0.0, 0.0,
                           int(cfg.m), bool(cfg.incremental), bool(cfg.replan_when_known),
                           int(cfg.plan_every), int(cfg.max_sweeps), float(cfg.tol),
                           bool(cfg.synchronous), False, bool(cfg.freeze))
    if isinstance(cfg, ModelBasedConfig):
        return AgentParams(KIND_MB, int(cfg.selection), 0.0, float(cfg.gamma),
                           float(cfg.epsilon), float(cfg.tau), 1, bool(cfg.incremental), False,
                           int(cfg.plan_every), int(cfg.max_sweeps), float(cfg.tol),
                           bool(cfg.synchronous), bool(cfg.untried_uniform), False)
    raise ConfigError(f"unsupported agent config {type(cfg).__name__}", key="agent")


def as_mask(valid: np.ndarray | None, n_states: int, n_actions: int) -> np.ndarray:
    """Validated (S, A) bool mask, or :data:`NO_MASK` for None."""
    if valid is None:
        return NO_MASK
    v = np.asarray(valid)
    if v.shape != (n_states, n_actions) or v.dtype != np.bool_:
        raise ConfigError(f"expected a bool array of shape {(n_states, n_actions)}, got "
                          f"{v.dtype} {v.shape}", key="valid",
                          fix="pass valid[s, a] = True for each allowed action")
    return np.ascontiguousarray(v)


def as_terminal(terminal: np.ndarray | None, n_states: int) -> np.ndarray:
    """Validated (S,) bool terminal flags, or :data:`NO_TERMINAL` for None."""
    if terminal is None:
        return NO_TERMINAL
    t = np.asarray(terminal)
    if t.shape != (n_states,) or t.dtype != np.bool_:
        raise ConfigError(f"expected a bool array of shape {(n_states,)}, got {t.dtype} "
                          f"{t.shape}", key="terminal")
    return np.ascontiguousarray(t)


# --------------------------------------------------------------------------- selection
# one implementation of every selection rule, with or without a mask: kernels.masked_*


@njit(cache=True, inline="always")
def act(Q, s, p, valid, rng):
    """Behaviour action in state ``s`` (``p.selection`` on ``Q[s]``, masked by ``valid``)."""
    if valid.shape[0] == 0:
        return masked_select(Q[s], ALL_VALID, p.selection, p.epsilon, p.tau, rng)
    return masked_select(Q[s], valid[s], p.selection, p.epsilon, p.tau, rng)


# --------------------------------------------------------------------------- values
@njit(cache=True)
def _value(Q, s, valid, terminal):
    """max over the valid actions of ``Q[s]`` (0 for a terminal state)."""
    if terminal.shape[0] > 0 and terminal[s]:
        return 0.0
    best = -np.inf
    if valid.shape[0] > 0 and n_valid(valid[s], Q.shape[1]) > 0:
        for b in range(Q.shape[1]):
            if valid[s, b] and Q[s, b] > best:
                best = Q[s, b]
        return best
    for b in range(Q.shape[1]):
        if Q[s, b] > best:
            best = Q[s, b]
    return best


@njit(cache=True)
def synchronous_sweep(model, Q, p, valid, terminal):
    """One Jacobi sweep over all (s, a) (rule 2); ``untried_uniform`` values untried
    pairs at ``gamma * mean(V)`` (rule 1). Returns the largest ``|dQ|``.

    Every backup reads ``V`` of the previous sweep. Pairs tried fewer than
    ``max(m_known, 1)`` times (but at least once) keep their Q (R-max's optimism).
    Cost per sweep: O(S * A + observed triples).
    """
    S, A = Q.shape
    V = np.empty(S)
    for s in range(S):
        V[s] = _value(Q, s, valid, terminal)
    mean_v = V.mean()
    floor = max(p.m_known, 1)
    delta = 0.0
    for s in range(S):
        if terminal.shape[0] > 0 and terminal[s]:
            continue
        for a in range(A):
            known, new = model_q_value(model, s, a, V, p.gamma, floor)
            if not known:
                if model.n_sa[s, a] > 0 or not p.untried_uniform:
                    continue
                new = p.gamma * mean_v
            d = abs(new - Q[s, a])
            if d > delta:
                delta = d
            Q[s, a] = new
    return delta


@njit(cache=True)
def plan(model, Q, p, valid, terminal):
    """Planning now: ``p.max_sweeps`` sweeps (synchronous or the in-place kernel);
    returns the sweeps done. With a mask or terminal flags the sweeps are synchronous
    (the in-place kernel maxes over all actions)."""
    if p.synchronous or valid.shape[0] > 0 or terminal.shape[0] > 0:
        for k in range(p.max_sweeps):
            if synchronous_sweep(model, Q, p, valid, terminal) <= p.tol:
                return k + 1
        return p.max_sweeps
    return model_value_iteration(model, Q, p.gamma, p.max_sweeps, p.tol, p.m_known)


@njit(cache=True)
def _q_update(Q, s, a, r, s_next, alpha, gamma, valid, terminal):
    target = r + gamma * _value(Q, s_next, valid, terminal)
    td = target - Q[s, a]
    Q[s, a] += alpha * td
    return td


@njit(cache=True, inline="always")
def q_step(Q, s, a, r, s_next, p, valid, terminal):
    """One Q-learning update of ``Q`` from ``(s, a, r, s_next)`` with ``p.alpha``,
    ``p.gamma`` (target max over the valid actions of ``s_next``; no bootstrap into a
    terminal state)."""
    if valid.shape[0] == 0 and terminal.shape[0] == 0:
        q_learning_update(Q, s, a, r, s_next, p.alpha, p.gamma)
    else:
        _q_update(Q, s, a, r, s_next, p.alpha, p.gamma, valid, terminal)


@njit(cache=True, inline="always")
def learn(model, Q, s, a, r, s_next, p, valid, terminal, t):
    """Learn from ``(s, a, r, s_next)``; returns the step counter ``t`` after it.

    Q-learning: one update (target max over valid actions; no bootstrap into a
    terminal state). Model-based / R-max: observe (unless ``p.freeze`` and the pair
    already has ``m_known`` visits), R-max replanning or one incremental backup, and
    :func:`plan` every ``p.plan_every`` steps.
    """
    if p.kind == KIND_MF:
        q_step(Q, s, a, r, s_next, p, valid, terminal)
        return t + 1
    if terminal.shape[0] > 0 and terminal[s_next]:
        Q[s_next, :] = 0.0
    if not (p.freeze and model.n_sa[s, a] >= p.m_known):
        n = model_observe(model, s, a, r, s_next)
        if p.replan_when_known and n == p.m_known:
            plan(model, Q, p, valid, terminal)
        elif p.incremental:
            _backup(model, Q, s, a, p, valid, terminal)
    elif p.incremental:
        _backup(model, Q, s, a, p, valid, terminal)
    t += 1
    if p.plan_every > 0 and t % p.plan_every == 0:
        plan(model, Q, p, valid, terminal)
    return t


@njit(cache=True, inline="always")
def _backup(model, Q, s, a, p, valid, terminal):
    if valid.shape[0] == 0 and terminal.shape[0] == 0:
        model_backup(model, Q, s, a, p.gamma, p.m_known)
        return
    S = Q.shape[0]
    V = np.empty(S)
    for s2 in range(S):
        V[s2] = _value(Q, s2, valid, terminal)
    known, new = model_q_value(model, s, a, V, p.gamma, max(p.m_known, 1))
    if known:
        Q[s, a] = new


# --------------------------------------------------------------------------- learner (agent + observer)
@njit(cache=True, inline="always")
def learner_act(lr, s, episode, valid, rng):
    """Action of :class:`Learner` ``lr`` in state ``s`` during ``episode``: the
    observer's (its own selection rule) from its take-over episode on, else the actor's."""
    ob = lr.observer
    if ob.Q.shape[0] > 0 and 0 <= ob.takeover_episode <= episode:
        return act(ob.Q, s, ob.params, valid, rng)
    return act(lr.Q, s, lr.params, valid, rng)


@njit(cache=True, inline="always")
def learner_learn(lr, s, a, r, s_next, episode, valid, terminal, t):
    """Learning of :class:`Learner` ``lr`` from ``(s, a, r, s_next)``; returns the actor's
    step counter ``t`` after it.

    The observer (if any) learns first, from every transition; after its take-over the
    actor stops learning (no observation, no planning; ``t`` stops). Otherwise
    :func:`learn` on the actor.

    The observer is always a Q-learner (:class:`Observer`), so its update is
    :func:`q_step`, not the whole of :func:`learn`: a second inlined copy of the
    model-based paths in every fused loop measured 10-20 % slower Q-learning on the
    Visit-the-lab social task (thesis 2.1.2), with the same results.
    """
    ob = lr.observer
    if ob.Q.shape[0] > 0:
        q_step(ob.Q, s, a, r, s_next, ob.params, valid, terminal)
        if 0 <= ob.takeover_episode <= episode:
            return t
    return learn(lr.model, lr.Q, s, a, r, s_next, lr.params, valid, terminal, t)
