"""The fused online loop: a :class:`~simlab.online.meta.MetaAgent` learning on an
empirical MDP while it acts, one compiled loop (numba).

Per decision, in this order (the physics loop of :mod:`simlab.online.physics` makes the
same agent calls)::

    a, e, ... = meta.decide(agent, s, agent_rng)     # criterion, planning, action
    s'        = sample_from_cdf(cdf[phase, s, a], env_rng)
    r         = reward_next[phase, s']
    meta.learn(agent, s, a, r, s')                   # both experts, no randomness
    s         = a start state (env_rng) if r > 0 else s'

and the first state is drawn from the start distribution. The phase is the last one whose
``phase_start`` is <= the decision index; among alternative phases of one change (the same
``phase_start``) the one whose counting state ``use_state`` saw the most decisions so far
(the first on ties).

The environment's rules come from :class:`~simlab.online.protocol.Protocol` (as
:data:`~simlab.online.protocol.LoopRules`; default simlab's): with the published rules the
decision in a goal moves to a start state (``goal_decision``, instead of the teleport after
a reward), the reward of decision ``silent_at`` is forced to 0, the first state is the
first listed start state, the experts learn a phantom ``(s0, 0, 0, s0)`` before the first
decision (``phantom_start``), and a run without reward in its first ``restart_after``
decisions starts again (the experts keep what they learned).
"""

from __future__ import annotations

import dataclasses
from collections import namedtuple
from dataclasses import dataclass

import numpy as np
from numba import njit

from simlab.agents.kernels import sample_from_cdf
from simlab.online import meta
from simlab.online.protocol import PROTOCOLS, LoopRules

__all__ = ["COLUMNS", "RUN_FIELDS", "OnlineLog", "run_online"]

#: The per-decision columns of :class:`OnlineLog`, in order.
COLUMNS = ("s", "a", "s_next", "expert", "h_mf", "h_mb", "c_mf", "c_mb", "backups", "seconds",
           "reward", "phase")
#: The fields of :class:`OnlineLog` that describe the whole run, not one decision.
RUN_FIELDS = ("restarts", "use_counts")

#: The columns as the compiled loop writes them (one record of arrays).
_Columns = namedtuple("_Columns", COLUMNS)


@dataclass(frozen=True)
class OnlineLog:
    """One row per decision (arrays of length n): states ``s``/``s_next``, action ``a``,
    ``expert`` (0 MF, 1 MB), normalised entropies ``h_mf``/``h_mb`` in [0, 1] and the
    filtered costs ``c_mf``/``c_mb`` (backups, or seconds under ``use_time``) the criterion
    read, the chosen expert's planning cost ``backups`` and ``seconds`` (wall clock),
    ``reward``, ``phase`` (index of the task phase: with alternatives, the one chosen).

    Of the whole run: ``restarts`` (how many times it started again for want of a reward,
    ``restart_after``) and ``use_counts`` (P,) int64, per phase chosen by use the decisions
    its counting state saw before the change (-1 for the others; None before a run)."""

    s: np.ndarray
    a: np.ndarray
    s_next: np.ndarray
    expert: np.ndarray
    h_mf: np.ndarray
    h_mb: np.ndarray
    c_mf: np.ndarray
    c_mb: np.ndarray
    backups: np.ndarray
    seconds: np.ndarray
    reward: np.ndarray
    phase: np.ndarray
    restarts: int = 0
    use_counts: np.ndarray | None = None

    @classmethod
    def empty(cls, n: int) -> OnlineLog:
        i, f = np.int64, np.float64
        return cls(*(np.zeros(n, dtype=t) for t in (i, i, i, np.int8, f, f, f, f, i, f, f,
                                                     np.int8)))

    @property
    def n(self) -> int:
        return int(self.s.shape[0])

    def columns(self) -> dict[str, np.ndarray]:
        """The per-decision columns (:data:`COLUMNS`)."""
        return {k: getattr(self, k) for k in COLUMNS}


@njit(cache=True)
def _first_state(task, rules, env_rng):
    if rules.first_state >= 0:
        return rules.first_state
    return sample_from_cdf(task.start_cdf, env_rng)


@njit(cache=True)
def _phantom_start(ag, s):
    """The published run's fictitious previous decision: learned ``(s, 0, 0, s)``, and
    ``s`` counts as visited."""
    meta.learn(ag, s, 0, 0.0, s)
    ag.seen[s] = True


@njit(cache=True)
def _choose_phase(task, visits, nxt, use_counts):
    """The phase from the change starting at phase ``nxt``: among the phases with its start,
    the one whose counting state has the most ``visits`` (the first on ties). Returns
    ``(phase, next change's first phase)`` and records the counts in ``use_counts``."""
    n_phases = task.phase_start.shape[0]
    at = task.phase_start[nxt]
    best = nxt
    j = nxt
    while j < n_phases and task.phase_start[j] == at:
        u = task.use_state[j]
        if u >= 0:
            use_counts[j] = visits[u]
            if visits[u] > visits[task.use_state[best]]:
                best = j
        j += 1
    return best, j


@njit(cache=True)
def _loop(ag, task, rules, n, env_rng, agent_rng, log, use_counts):
    n_phases = task.phase_start.shape[0]
    visits = np.zeros(task.start_cdf.shape[0], dtype=np.int64)
    s = _first_state(task, rules, env_rng)
    if rules.phantom_start:
        _phantom_start(ag, s)
    phase = 0
    nxt = 1
    got = 0.0
    restarts = 0
    t = 0
    while t < n:
        while nxt < n_phases and task.phase_start[nxt] <= t:
            phase, nxt = _choose_phase(task, visits, nxt, use_counts)
        a, e, h_mf, h_mb, c_mf, c_mb, backups, seconds = meta.decide(ag, s, agent_rng)
        if rules.goal_decision and task.reward_next[phase, s] > 0.0:
            s_next = sample_from_cdf(task.start_cdf, env_rng)
        else:
            s_next = sample_from_cdf(task.cdf[phase, s, a], env_rng)
        r = task.reward_next[phase, s_next]
        arrived = r > 0.0  # in a goal: the episode ends even when its reward is silenced
        if t == rules.silent_at:
            r = 0.0
        meta.learn(ag, s, a, r, s_next)
        log.s[t] = s
        log.a[t] = a
        log.s_next[t] = s_next
        log.expert[t] = e
        log.h_mf[t] = h_mf
        log.h_mb[t] = h_mb
        log.c_mf[t] = c_mf
        log.c_mb[t] = c_mb
        log.backups[t] = backups
        log.seconds[t] = seconds
        log.reward[t] = r
        log.phase[t] = phase
        visits[s] += 1
        got += r
        t += 1
        if arrived and not rules.goal_decision:
            s = sample_from_cdf(task.start_cdf, env_rng)
        else:
            s = s_next
        if t == rules.restart_after and got == 0.0 and restarts < rules.max_restarts:
            restarts += 1
            t = 0
            phase = 0
            nxt = 1
            ag.seen[:] = False
            s = _first_state(task, rules, env_rng)
            if rules.phantom_start:
                _phantom_start(ag, s)
    return restarts


def run_online(agent: meta.MetaAgent, task: object, n_decisions: int,
               env_rng: np.random.Generator, agent_rng: np.random.Generator,
               rules: LoopRules | None = None) -> OnlineLog:
    """Run ``n_decisions`` decisions of ``agent`` on the compiled task
    (:class:`~simlab.online.task.OnlineMdp`) under the environment ``rules``
    (:meth:`~simlab.online.protocol.Protocol.loop_rules`; default simlab's); the agent
    learns in place. Returns the :class:`OnlineLog`."""
    if rules is None:
        rules = PROTOCOLS["simlab"].loop_rules(-1, -1)
    log = OnlineLog.empty(int(n_decisions))
    use_counts = np.full(task.phase_start.shape[0], -1, dtype=np.int64)  # type: ignore[attr-defined]
    restarts = _loop(agent, task, rules, int(n_decisions), env_rng, agent_rng,
                     _Columns(**log.columns()), use_counts)
    return dataclasses.replace(log, restarts=int(restarts), use_counts=use_counts)
