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
``phase_start`` is <= the decision index.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from simlab.agents.kernels import sample_from_cdf
from simlab.online import meta

__all__ = ["OnlineLog", "run_online"]


@dataclass(frozen=True)
class OnlineLog:
    """One row per decision (arrays of length n): states ``s``/``s_next``, action ``a``,
    ``expert`` (0 MF, 1 MB), normalised entropies ``h_mf``/``h_mb`` in [0, 1] and the
    filtered costs ``c_mf``/``c_mb`` (backups, or seconds under ``use_time``) the criterion
    read, the chosen expert's planning cost ``backups`` and ``seconds`` (wall clock),
    ``reward``, ``phase`` (index of the task phase)."""

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

    @classmethod
    def empty(cls, n: int) -> OnlineLog:
        i, f = np.int64, np.float64
        return cls(*(np.zeros(n, dtype=t) for t in (i, i, i, np.int8, f, f, f, f, i, f, f,
                                                     np.int8)))

    @property
    def n(self) -> int:
        return int(self.s.shape[0])

    def columns(self) -> dict[str, np.ndarray]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


@njit(cache=True)
def _loop(ag, task, n, env_rng, agent_rng, s_log, a_log, s2_log, e_log, hmf_log, hmb_log,
          cmf_log, cmb_log, b_log, sec_log, r_log, ph_log):
    s = sample_from_cdf(task.start_cdf, env_rng)
    phase = 0
    n_phases = task.phase_start.shape[0]
    for t in range(n):
        while phase + 1 < n_phases and task.phase_start[phase + 1] <= t:
            phase += 1
        a, e, h_mf, h_mb, c_mf, c_mb, backups, seconds = meta.decide(ag, s, agent_rng)
        s_next = sample_from_cdf(task.cdf[phase, s, a], env_rng)
        r = task.reward_next[phase, s_next]
        meta.learn(ag, s, a, r, s_next)
        s_log[t] = s
        a_log[t] = a
        s2_log[t] = s_next
        e_log[t] = e
        hmf_log[t] = h_mf
        hmb_log[t] = h_mb
        cmf_log[t] = c_mf
        cmb_log[t] = c_mb
        b_log[t] = backups
        sec_log[t] = seconds
        r_log[t] = r
        ph_log[t] = phase
        s = sample_from_cdf(task.start_cdf, env_rng) if r > 0.0 else s_next


def run_online(agent: meta.MetaAgent, task: object, n_decisions: int,
               env_rng: np.random.Generator, agent_rng: np.random.Generator) -> OnlineLog:
    """Run ``n_decisions`` decisions of ``agent`` on the compiled task
    (:class:`~simlab.online.task.OnlineMdp`); the agent learns in place. Returns the
    :class:`OnlineLog`."""
    log = OnlineLog.empty(int(n_decisions))
    _loop(agent, task, int(n_decisions), env_rng, agent_rng, *log.columns().values())
    return log
