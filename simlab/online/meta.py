"""The MB/MF meta-controller: two experts, one arbitration per decision (numba).

Dromnelle, Renaudo, Chetouani, Maragos, Chatila, Girard, Khamassi (2022), "Reducing
computational cost during robot navigation and human-robot interaction with a
human-inspired reinforcement learning architecture", Int. J. Social Robotics, sec. 2-3
(and their Living Machines 2020 paper): a model-free (MF) and a model-based (MB) expert
act on the same transitions; at each decision a meta-controller picks the expert that
plans the action, trading the quality of its decision (the entropy of its action
distribution) against its computation cost.

Experts are :class:`simlab.agents.core.Learner` records (any simlab agent: Q-learning,
model-based, R-max, sliding window); their act / learn / plan steps are those of
:mod:`simlab.agents.core`. Both experts learn from every transition, whichever decided
(the thesis's passive MF observer is criterion ``mb``: MB always decides, MF watches).

Decisions made here (the papers leave them to the implementation):

* **Planning vs learning.** Learning (a Q-learning update; a model count and one
  incremental backup) happens for both experts after every transition. Planning happens
  only for the chosen expert, at the decision: a model-based expert runs value iteration
  on its learned model (its ``max_sweeps`` / ``tol``); a model-free expert's "plan" is
  reading its Q row. The cost of a decision is the chosen expert's planning cost.
* **Deterministic cost** (default, ``use_time=False``): Bellman backups. A value-iteration
  sweep backs up every known pair (``n(s, a) >= max(m_known, 1)``; all ``S * A`` pairs for
  synchronous sweeps), so a plan of ``k`` sweeps costs ``k`` times that; a model-free
  decision costs 1. Seeded runs are then bit-identical. The wall-clock planning time (what
  the paper measured) is recorded beside it, and used instead with ``use_time=True``.
* **Entropies** (Dromnelle et al. 2022, sec. 2.3; Living Machines 2020, sec. 2.2): each
  expert keeps, per state, its action distribution low-pass filtered over its visits
  (``pi_e(s) <- pi_e(s) + alpha_p (softmax_e(Q_e[s]) - pi_e(s))``, alpha_p 0.6, uniform at
  first). The criterion reads the filtered distributions of ``s`` *before* planning (the
  arbitration must not pay for the plan it is deciding about); then the chosen expert
  plans and both experts filter their new softmax at ``s`` into ``pi_e(s)``. ``H_e`` is
  the Shannon entropy of ``pi_e(s)`` over the valid actions; the quality term uses it
  normalised, ``H_e / H_max`` in [0, 1] (``H_max = log n_valid``), the weight of the cost
  term uses MF's entropy in bits, ``exp(-kappa * H_MF)`` with ``H_MF`` in [0, log2
  n_valid] (3 bits for the 8 actions of the published robot): when MF is unsure its
  cheapness counts for little and MB comes in (the published arbitration).
  ``prob_alpha = 1`` reads the last softmax computed at ``s`` instead.
* **A reward ends the episode** (the published protocol: after a reward the robot
  restarts from a start state and the rewarded state's values are reset to 0): with
  ``reward_ends`` both experts learn the rewarded transition and then set the values of
  the state it reached to 0, so a goal is worth its reward and nothing after it. When
  the goal moves, the old goal's state stops being rewarded, its values are learned
  again from the transitions that leave it, and MF's values along the old route fall
  (its entropy there rises) instead of staying propped up by the goal's initial value.
* **MB's reward belongs to the arrival state** (``state_reward``, default; Dromnelle et
  al. 2022, sec. 2, the MB expert's reward model, as their published code
  ``meta-control-decision-making-agent`` implements it): MB keeps,
  per state, the reward last seen on arriving there, and its model's reward of a pair is
  the expectation of that state reward over the pair's outcomes, ``R(s, a) = sum_s'
  T(s, a, s') r(s')``. One unrewarded arrival at the old goal therefore forgets the goal
  for every pair leading there (the next plan no longer values the old route). Without
  ``state_reward`` the model averages the rewards seen per pair over its window (10
  outcomes), and the old goal fades over the next visits of each pair.
* **Both experts plan at a state's first visit** (``plan_both_first``, default; the
  published loop of the same code, ``agentSimulator.py``, gives a state first met both
  experts' plans, so each has a distribution
  there from the start). The criterion still picks the expert whose action is taken;
  at a first visit the other expert plans too, its cost is filtered into its own cost
  table, and the decision's logged cost is the sum of both plans (both were computed).
  Later visits plan only the chosen expert. The single-expert baselines ``mf`` / ``mb``
  (one expert alone) never plan the other one: their cost is that expert's.
* **Costs per state**, low-pass filtered (``C <- C + alpha_c (c - C)``, alpha_c 0.6), start
  at 0 and are updated for the expert that planned only; ``C_e / max_e C_e`` is 0 when both
  are 0.
* **Ties** of the criteria go to the first expert (MF, the cheap one): no random draw.
  ``random`` draws one uniform number per decision from the agent's Generator. With
  ``ties = "random"`` a tie of ``entropy`` or ``entropy_and_cost`` is a fair coin from the
  same Generator (the published arbitration's, ``metaControllerSystem.py``: at a state's
  first visit both distributions are uniform and both costs 0, so the first decision there
  is MB's half of the time).
* **The goal's moves are forgotten at its first reward** (``forget_goal_moves``; the
  published MB expert, ``modelBased.py``, deletes the transitions of a state the first time
  it pays): MB's model of the rewarded state's own moves is emptied once, so its values stay
  0 under planning (a goal ends the episode: nothing follows it). Without it a state that
  was left before it first paid (the new goal after a goal change) keeps its known moves,
  and MB's next plan values the goal again at ``gamma`` times its neighbours.
* **No learning from the rewarded state** (``learn_from_goal = False``, published; both
  published experts skip the transition that starts where a reward was just obtained): with
  the published reset (a decision in the goal whose move goes to a start state,
  :mod:`simlab.online.protocol`) that move is no move of the world and is not learned.
  Under simlab's teleport no transition starts in the goal right after its reward, so the
  rule never fires in its loops; the default (``True``) learns every transition given.
"""

from __future__ import annotations

from collections import namedtuple
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit, objmode
from numba.extending import overload

from simlab.agents import core
from simlab.agents.kernels import ALL_VALID, n_valid
from simlab.agents.sparse_model import CountModel, CountModelType
from simlab.agents.window_model import WindowModel, WindowModelType

__all__ = [
    "AGENT_RULES",
    "CRITERIA",
    "EXPERT_MB",
    "EXPERT_MF",
    "TIES",
    "Arbitration",
    "MetaAgent",
    "MetaParams",
    "choose_expert",
    "criterion_code",
    "decide",
    "distribution_entropy",
    "expert_plan",
    "forget_moves",
    "learn",
    "lowpass",
    "make_expert",
    "make_meta_agent",
    "normalised_entropy",
    "set_arrival_reward",
    "softmax_into",
]

#: Criterion names, their codes are the indices: ``mf`` / ``mb`` (one expert always
#: decides), ``random`` (a fair coin), ``entropy`` (lowest normalised entropy) and
#: ``entropy_and_cost`` (Dromnelle et al. 2022, eq. of sec. 2.3, with ``kappa``).
CRITERIA = ("mf", "mb", "random", "entropy", "entropy_and_cost")
C_MF, C_MB, C_RANDOM, C_ENTROPY, C_ENTROPY_COST = range(5)

#: Expert indices (rows of the cost tables, values of the ``expert`` log column).
EXPERT_MF, EXPERT_MB = 0, 1

#: No link table (``reward_links`` off): every pair's arrivals carry the state's reward.
NO_LINKS = np.zeros((0, 0), dtype=np.int64)

#: Arbitration parameters: ``criterion`` (code of :data:`CRITERIA`), ``kappa`` (weight of
#: MF's certainty on the cost term), ``cost_alpha`` (low-pass rate of the per-state costs),
#: ``use_time`` (decide on wall-clock seconds instead of backups), ``prob_alpha``
#: (low-pass rate of the per-state action distributions), ``reward_ends`` (a reward ends
#: the episode: the rewarded state's values are reset to 0), ``state_reward`` (MB's reward
#: model is the reward last seen on arriving in each state), ``plan_both_first`` (both
#: experts plan at a state's first visit), ``ties_random`` (a tie of the entropy criteria is a
#: coin), ``forget_goal_moves`` (MB forgets the rewarded state's moves at its first reward),
#: ``learn_from_goal`` (the transition starting where a reward was just obtained is learned),
#: ``reward_links`` (MB's arrival reward counts only for the pairs once rewarded into it).
MetaParams = namedtuple("MetaParams", ["criterion", "kappa", "cost_alpha", "use_time",
                                       "prob_alpha", "reward_ends", "state_reward",
                                       "plan_both_first", "ties_random", "forget_goal_moves",
                                       "learn_from_goal", "reward_links"])

#: How ties of ``entropy`` and ``entropy_and_cost`` are broken: ``mf`` (simlab) or a fair
#: ``random`` coin (published).
TIES = ("mf", "random")

#: The agent's side of each protocol (:data:`simlab.online.protocol.PROTOCOLS`): values of
#: :class:`Arbitration` fields that differ from its defaults (simlab's).
AGENT_RULES: dict[str, dict[str, Any]] = {
    "simlab": {},
    "published": {"ties": "random", "forget_goal_moves": True, "learn_from_goal": False,
                  "reward_links": True},
}

#: The meta-controlled pair: ``mf`` and ``mb`` (:class:`simlab.agents.core.Learner`),
#: ``cost`` (2, S) float64 filtered backups per expert and state, ``cost_time`` (2, S)
#: float64 filtered seconds, ``probs`` (2, S, A) float64 filtered action distributions
#: per expert and state, ``params`` (:class:`MetaParams`), ``valid`` (S, A) bool or
#: ``core.NO_MASK``, ``arrival_reward`` (S,) float64 the reward last seen on arriving in
#: each state (MB's reward model under ``state_reward``; 0 before any arrival), ``seen``
#: (S,) bool states where a decision was made, ``paid`` (S,) bool states that were rewarded
#: once, ``after_reward`` (1,) int64 the state a reward was obtained on arriving in by the
#: last transition learned (-1: none), ``link`` (S, A) int64 the goal state each pair was last
#: rewarded into (-1: none; :data:`NO_LINKS` without ``reward_links``). Built by
#: :func:`make_meta_agent`.
MetaAgent = namedtuple("MetaAgent", ["mf", "mb", "cost", "cost_time", "probs", "params",
                                     "valid", "arrival_reward", "seen", "paid", "after_reward",
                                     "link"])


def criterion_code(name: str) -> int:
    """Code of a criterion name of :data:`CRITERIA` (``ValueError`` otherwise)."""
    return CRITERIA.index(name)


@njit(cache=True)
def normalised_entropy(q, vrow, tau):
    """Shannon entropy of the softmax of ``q`` (A,) at temperature ``tau`` over the valid
    actions ``vrow`` (A,) bool (:data:`~simlab.agents.kernels.ALL_VALID`: all), divided by
    its maximum ``log(n_valid)``: a number in [0, 1] (0 with a single valid action).
    ``tau <= 0`` is the greedy limit (uniform over the maximisers). No allocation:
    ``H = log Z - sum_b p_b (q_b - q_max) / tau`` with ``Z = sum_b exp((q_b - q_max) / tau)``.
    """
    A = q.shape[0]
    every = vrow.shape[0] == 0 or n_valid(vrow, A) == 0
    k = A if every else n_valid(vrow, A)
    if k <= 1:
        return 0.0
    qmax = -np.inf
    for b in range(A):
        if (every or vrow[b]) and q[b] > qmax:
            qmax = q[b]
    if tau <= 0.0:
        n_best = 0
        for b in range(A):
            if (every or vrow[b]) and q[b] == qmax:
                n_best += 1
        return np.log(n_best) / np.log(k)
    z = 0.0
    m = 0.0
    for b in range(A):
        if every or vrow[b]:
            x = (q[b] - qmax) / tau
            w = np.exp(x)
            z += w
            m += w * x
    h = np.log(z) - m / z
    return min(max(h / np.log(k), 0.0), 1.0)


@njit(cache=True)
def distribution_entropy(p, vrow):
    """Shannon entropy of the distribution ``p`` (A,) over the valid actions ``vrow`` (A,)
    bool (:data:`~simlab.agents.kernels.ALL_VALID`: all), as ``(normalised, max_bits)``:
    ``H / log(n_valid)`` in [0, 1] (0 with a single valid action) and the largest entropy
    in bits, ``log2(n_valid)``. Zero probabilities contribute 0."""
    A = p.shape[0]
    every = vrow.shape[0] == 0 or n_valid(vrow, A) == 0
    k = A if every else n_valid(vrow, A)
    if k <= 1:
        return 0.0, 0.0
    h = 0.0
    for b in range(A):
        if (every or vrow[b]) and p[b] > 0.0:
            h -= p[b] * np.log(p[b])
    return min(max(h / np.log(k), 0.0), 1.0), np.log(k) / np.log(2.0)


@njit(cache=True)
def softmax_into(q, vrow, tau, out):
    """The softmax of ``q`` (A,) at temperature ``tau`` over the valid actions ``vrow``
    into ``out`` (A,) (0 for the others); ``tau <= 0``: uniform over the maximisers."""
    A = q.shape[0]
    every = vrow.shape[0] == 0 or n_valid(vrow, A) == 0
    qmax = -np.inf
    for b in range(A):
        if (every or vrow[b]) and q[b] > qmax:
            qmax = q[b]
    z = 0.0
    for b in range(A):
        out[b] = 0.0
        if every or vrow[b]:
            if tau <= 0.0:
                out[b] = 1.0 if q[b] == qmax else 0.0
            else:
                out[b] = np.exp((q[b] - qmax) / tau)
            z += out[b]
    for b in range(A):
        out[b] /= z


@njit(cache=True)
def choose_expert(criterion, h_mf, h_mb, c_mf, c_mb, kappa, h_max_bits, rng, ties_random=False):
    """The expert that plans: :data:`EXPERT_MF` (0) or :data:`EXPERT_MB` (1).

    ``h_*`` normalised entropies in [0, 1], ``c_*`` the experts' (filtered) costs at this
    state (any unit, >= 0), ``h_max_bits`` the largest entropy in bits (``log2`` of the
    number of valid actions). ``entropy_and_cost`` (Dromnelle et al. 2022, sec. 2.3):
    value of expert e ``-(h_e + exp(-kappa * H_MF) * c_e / max(c_mf, c_mb))`` with MF's
    entropy in bits ``H_MF = h_mf * h_max_bits``; the larger wins. Ties of ``entropy`` and
    ``entropy_and_cost`` go to MF, or with ``ties_random`` to a fair coin from ``rng``;
    otherwise only ``random`` draws from ``rng``.
    """
    if criterion == C_MF:
        return EXPERT_MF
    if criterion == C_MB:
        return EXPERT_MB
    if criterion == C_RANDOM:
        return EXPERT_MB if rng.random() < 0.5 else EXPERT_MF
    if criterion == C_ENTROPY:
        if h_mb == h_mf and ties_random:
            return EXPERT_MB if rng.random() < 0.5 else EXPERT_MF
        return EXPERT_MB if h_mb < h_mf else EXPERT_MF
    c_max = max(c_mf, c_mb)
    w = np.exp(-kappa * h_mf * h_max_bits)
    v_mf = -h_mf
    v_mb = -h_mb
    if c_max > 0.0:
        v_mf -= w * c_mf / c_max
        v_mb -= w * c_mb / c_max
    if v_mb == v_mf and ties_random:
        return EXPERT_MB if rng.random() < 0.5 else EXPERT_MF
    return EXPERT_MB if v_mb > v_mf else EXPERT_MF


@njit(cache=True, inline="always")
def lowpass(old, new, alpha):
    """First-order low-pass filter: ``old + alpha * (new - old)``."""
    return old + alpha * (new - old)


@njit(cache=True)
def expert_plan(lr, valid):
    """Planning of expert ``lr`` now; returns its cost in Bellman backups.

    Model-free: 1 (reading its Q row). Model-based: :func:`simlab.agents.core.plan` (its
    ``max_sweeps`` / ``tol``), costing sweeps x backups per sweep (every pair for
    synchronous sweeps, else the known pairs ``n(s, a) >= max(m_known, 1)``).
    """
    p = lr.params
    if p.kind == core.KIND_MF:
        return 1
    S, A = lr.Q.shape
    per_sweep = S * A
    if not (p.synchronous or valid.shape[0] > 0):
        floor = max(p.m_known, 1)
        per_sweep = 0
        for s in range(S):
            for a in range(A):
                if lr.model.n_sa[s, a] >= floor:
                    per_sweep += 1
    sweeps = core.plan(lr.model, lr.Q, p, valid, core.NO_TERMINAL)
    return sweeps * per_sweep


@njit(cache=True, inline="always")
def _rewritten(pair, A, s_next, link, only):
    """Whether the arrivals of ``pair`` in ``s_next`` take the new reward: every pair, or
    (``link`` given) the pairs linked to ``s_next``; ``only >= 0``: that pair alone."""
    if only >= 0 and pair != only:
        return False
    if link.shape[0] == 0:
        return True
    s = pair // A
    return link[s, pair - s * A] == s_next


@njit(cache=True)
def _window_arrival_reward(m, s_next, new, link, only):
    for k in range(m.n_slots):
        if not _rewritten(m.slot_pair[k], m.n_actions, s_next, link, only):
            continue
        for i in range(m.win_fill[k]):
            if m.win_state[k, i] == s_next:
                m.win_reward[k, i] = new


@njit(cache=True)
def _count_arrival_reward(m, s_next, old, new, link, only):
    A = m.n_actions
    for j in range(m.n_pairs):
        if not _rewritten(m.pairs[j], A, s_next, link, only):
            continue
        s = m.pairs[j] // A
        a = m.pairs[j] - s * A
        k = m.head[s, a]
        while k != -1:
            if m.succ_state[k] == s_next:
                m.r_sum[s, a] += m.succ_count[k] * (new - old)
            k = m.succ_link[k]


def set_arrival_reward(model, s_next, old, new, link=NO_LINKS, only=-1):
    """Make ``new`` the reward of arriving in ``s_next`` in a count or window model whose
    recorded arrivals there carry ``old``: a window model's rewards of the outcomes ending in
    ``s_next`` become ``new``; a count model's reward sums move by ``n(s, a, s_next) * (new -
    old)``. The model's reward of a pair is then ``sum_s' T(s, a, s') r(s')`` with ``r`` the
    reward last seen on arriving in each state (module docstring, ``state_reward``).
    ``link`` (S, A) int64 (:data:`NO_LINKS`: every pair): only the pairs linked to ``s_next``
    (``reward_links``); ``only``: that pair index ``s * A + a`` alone. O(observed outcomes);
    called only when ``r(s_next)`` changes (a goal found or lost) or a pair is linked."""
    if isinstance(model, WindowModel):
        _window_arrival_reward(model, s_next, new, link, only)
    elif isinstance(model, CountModel):
        _count_arrival_reward(model, s_next, old, new, link, only)
    else:
        raise TypeError(f"expected a CountModel or WindowModel, got {type(model).__name__}")


@overload(set_arrival_reward, jit_options={"cache": True})
def _ov_set_arrival_reward(model, s_next, old, new, link, only):  # compiled: every argument
    if isinstance(model, WindowModelType):
        return lambda model, s_next, old, new, link, only: _window_arrival_reward(
            model, s_next, new, link, only)
    if isinstance(model, CountModelType):
        return lambda model, s_next, old, new, link, only: _count_arrival_reward(
            model, s_next, old, new, link, only)
    return None


@njit(cache=True)
def _mb_reward_model(ag, s, a, r, s_next):
    """MB's reward model learns the arrival ``(s, a) -> s_next`` with reward ``r`` before its
    model counts it (module docstring, ``state_reward`` and ``reward_links``)."""
    old = ag.arrival_reward[s_next]
    if not ag.params.reward_links:
        if r != old:
            set_arrival_reward(ag.mb.model, s_next, old, r, NO_LINKS, -1)
            ag.arrival_reward[s_next] = r
        return
    if r != old:  # the pairs linked to s_next so far
        set_arrival_reward(ag.mb.model, s_next, old, r, ag.link, -1)
        ag.arrival_reward[s_next] = r
    if r != 0.0 and ag.link[s, a] != s_next:  # a new way into a goal: its arrivals pay too
        ag.link[s, a] = s_next
        set_arrival_reward(ag.mb.model, s_next, 0.0, r, ag.link, s * ag.mb.Q.shape[1] + a)


@njit(cache=True)
def _window_forget(m, s):
    A = m.n_actions
    for a in range(A):
        k = m.slot[s, a]
        if k != -1:
            m.win_fill[k] = 0
            m.win_pos[k] = 0
        m.n_sa[s, a] = 0


@njit(cache=True)
def _count_forget(m, s):
    # the pool entries stay linked (a later visit reuses them) with count 0
    for a in range(m.n_actions):
        k = m.head[s, a]
        while k != -1:
            m.succ_count[k] = 0
            k = m.succ_link[k]
        m.n_sa[s, a] = 0
        m.r_sum[s, a] = 0.0


def forget_moves(model, s):
    """Forget every recorded outcome of the moves of state ``s`` in a count or window model
    (module docstring, ``forget_goal_moves``): its pairs become unvisited (no model, planning
    leaves their Q alone) and a later visit starts their model afresh."""
    if isinstance(model, WindowModel):
        _window_forget(model, s)
    elif isinstance(model, CountModel):
        _count_forget(model, s)
    else:
        raise TypeError(f"expected a CountModel or WindowModel, got {type(model).__name__}")


@overload(forget_moves, jit_options={"cache": True})
def _ov_forget_moves(model, s):
    if isinstance(model, WindowModelType):
        return lambda model, s: _window_forget(model, s)
    if isinstance(model, CountModelType):
        return lambda model, s: _count_forget(model, s)
    return None


@njit(cache=True)
def _now():
    with objmode(t="float64"):
        t = _perf_counter()
    return t


def _perf_counter() -> float:
    import time

    return time.perf_counter()


@njit(cache=True)
def _filter_probs(ag, s, vrow):
    """Both experts filter their current softmax at ``s`` into ``ag.probs[:, s]``."""
    new = np.empty(ag.probs.shape[2])
    alpha = ag.params.prob_alpha
    softmax_into(ag.mf.Q[s], vrow, ag.mf.params.tau, new)
    _lowpass_row(ag.probs[EXPERT_MF, s], new, alpha)
    softmax_into(ag.mb.Q[s], vrow, ag.mb.params.tau, new)
    _lowpass_row(ag.probs[EXPERT_MB, s], new, alpha)


@njit(cache=True, inline="always")
def _lowpass_row(old, new, alpha):
    for b in range(old.shape[0]):
        old[b] = lowpass(old[b], new[b], alpha)


@njit(cache=True)
def _plan_and_filter_cost(ag, e, s):
    """Expert ``e`` plans now; its cost at ``s`` is low-pass filtered into its rows of
    ``ag.cost`` / ``ag.cost_time``. Returns ``(backups, seconds)`` of the plan."""
    t0 = _now()
    if e == EXPERT_MB:
        backups = expert_plan(ag.mb, ag.valid)
    else:
        backups = expert_plan(ag.mf, ag.valid)
    seconds = _now() - t0
    alpha = ag.params.cost_alpha
    ag.cost[e, s] = lowpass(ag.cost[e, s], float(backups), alpha)
    ag.cost_time[e, s] = lowpass(ag.cost_time[e, s], seconds, alpha)
    return backups, seconds


@njit(cache=True)
def decide(ag, s, rng):
    """One decision of :class:`MetaAgent` ``ag`` in state ``s``.

    Returns ``(action, expert, h_mf, h_mb, c_mf, c_mb, backups, seconds)``: the
    normalised entropies of the filtered distributions and the filtered costs the
    criterion read, and the chosen expert's planning cost in backups and wall-clock
    seconds (both recorded; the filter of the one the criterion uses decides). At a
    state's first visit under ``plan_both_first`` (arbitrating criteria: ``random``,
    ``entropy``, ``entropy_and_cost``) the other expert plans too and the
    returned cost is the sum of both plans. After the plan(s) both experts filter their
    softmax at ``s`` (module docstring). Draws from
    ``rng``: the criterion's (``random`` only), then the chosen expert's action selection.
    """
    vrow = ALL_VALID if ag.valid.shape[0] == 0 else ag.valid[s]
    h_mf, h_max_bits = distribution_entropy(ag.probs[EXPERT_MF, s], vrow)
    h_mb, _ = distribution_entropy(ag.probs[EXPERT_MB, s], vrow)
    table = ag.cost_time if ag.params.use_time else ag.cost
    c_mf = table[EXPERT_MF, s]
    c_mb = table[EXPERT_MB, s]
    e = choose_expert(ag.params.criterion, h_mf, h_mb, c_mf, c_mb, ag.params.kappa,
                      h_max_bits, rng, ag.params.ties_random)
    both = ag.params.plan_both_first and ag.params.criterion >= C_RANDOM and not ag.seen[s]
    ag.seen[s] = True
    backups, seconds = _plan_and_filter_cost(ag, e, s)
    if both:
        other_backups, other_seconds = _plan_and_filter_cost(ag, 1 - e, s)
        backups += other_backups
        seconds += other_seconds
    _filter_probs(ag, s, vrow)
    if e == EXPERT_MB:
        a = core.act(ag.mb.Q, s, ag.mb.params, ag.valid, rng)
    else:
        a = core.act(ag.mf.Q, s, ag.mf.params, ag.valid, rng)
    return a, e, h_mf, h_mb, c_mf, c_mb, backups, seconds


@njit(cache=True)
def learn(ag, s, a, r, s_next):
    """Both experts learn from ``(s, a, r, s_next)`` (no randomness): MF's Q-learning
    update, MB's model count and incremental backup (:func:`simlab.agents.core.learn`;
    experts never plan here). Under ``state_reward`` a reward on arriving in ``s_next``
    that differs from the last one seen there first rewrites MB's model rewards of every
    outcome ending in ``s_next`` (:func:`set_arrival_reward`). With ``reward_ends`` a
    rewarded transition then resets both experts' values of ``s_next`` to 0; with
    ``forget_goal_moves`` the first reward in ``s_next`` also empties MB's model of its
    moves (:func:`forget_moves`). Without ``learn_from_goal`` a transition that starts
    where the last learned one was rewarded is not learned (module docstring)."""
    p = ag.params
    if not p.learn_from_goal and ag.after_reward[0] == s:
        ag.after_reward[0] = s_next if r > 0.0 else -1
        return
    ag.after_reward[0] = s_next if r > 0.0 else -1
    core.learn(ag.mf.model, ag.mf.Q, s, a, r, s_next, ag.mf.params, ag.valid,
               core.NO_TERMINAL, 0)
    if ag.params.state_reward and ag.mb.params.kind != core.KIND_MF:
        _mb_reward_model(ag, s, a, r, s_next)
    core.learn(ag.mb.model, ag.mb.Q, s, a, r, s_next, ag.mb.params, ag.valid,
               core.NO_TERMINAL, 0)
    if r > 0.0:
        if p.forget_goal_moves and not ag.paid[s_next] and ag.mb.params.kind != core.KIND_MF:
            forget_moves(ag.mb.model, s_next)
        ag.paid[s_next] = True
        if p.reward_ends:
            ag.mf.Q[s_next, :] = 0.0
            ag.mb.Q[s_next, :] = 0.0


# --------------------------------------------------------------------------- builders
def make_expert(config: Any, n_states: int, n_actions: int) -> core.Learner:
    """A fresh expert (:class:`simlab.agents.core.Learner`) of an agent ``config``
    (:mod:`simlab.agents.config`): Q at the config's initial value (R-max: optimistic),
    an empty count model for model-based kinds (a window model for the sliding-window
    agent). Periodic planning is switched off
    (``plan_every = 0``): an expert plans when the meta-controller picks it."""
    from simlab.agents.config import PassiveObserverConfig, SlidingWindowConfig
    from simlab.agents.kernels import count_model_new, rmax_q_init, window_model_new
    from simlab.base.errors import ConfigError

    if isinstance(config, PassiveObserverConfig):
        raise ConfigError("an expert is a single agent; the passive observer is the "
                          "criterion 'mb' (MB decides, MF learns from its transitions)",
                          key="experts")
    p = core.agent_params(config)._replace(plan_every=0)
    if p.kind == core.KIND_RMAX:
        Q = rmax_q_init(n_states, n_actions, float(config.r_max), float(config.gamma))
    else:
        Q = np.full((n_states, n_actions), float(config.initial_value))
    if p.kind == core.KIND_MF:
        model = core.NO_MODEL
    elif isinstance(config, SlidingWindowConfig):
        model = window_model_new(n_states, n_actions, int(config.window),
                                 max(1, min(int(config.capacity), n_states * n_actions)))
    else:
        model = count_model_new(n_states, n_actions, int(config.capacity))
    return core.Learner(Q, model, p, core.Observer(core.NO_OBSERVER_Q, p, -1))


@dataclass(frozen=True)
class Arbitration:
    """How the meta-controller arbitrates (the arguments of :func:`make_meta_agent` that
    travel together from a command to its parallel runs): ``criterion`` one of
    :data:`CRITERIA`, ``kappa`` >= 0, ``cost_alpha`` and ``prob_alpha`` in (0, 1],
    ``use_time`` (decide on seconds), ``reward_ends``, ``state_reward``,
    ``plan_both_first``, ``ties`` (one of :data:`TIES`), ``forget_goal_moves``,
    ``learn_from_goal``, ``reward_links`` (module docstring). Defaults: simlab's; :data:`AGENT_RULES` holds
    the published values."""

    criterion: str = "entropy_and_cost"
    kappa: float = 1.0
    cost_alpha: float = 0.6
    use_time: bool = False
    prob_alpha: float = 0.6
    reward_ends: bool = True
    state_reward: bool = True
    plan_both_first: bool = True
    ties: str = "mf"
    forget_goal_moves: bool = False
    learn_from_goal: bool = True
    reward_links: bool = False

    def __post_init__(self) -> None:
        from simlab.base import validation
        from simlab.base.errors import ConfigError

        if self.criterion not in CRITERIA:
            raise ConfigError(f"unknown criterion {self.criterion!r}", key="criterion",
                              fix=f"choose one of {', '.join(CRITERIA)}")
        if self.ties not in TIES:
            raise ConfigError(f"unknown tie rule {self.ties!r}", key="ties",
                              fix=f"choose one of {', '.join(TIES)}")
        validation.positive(self.kappa, "kappa", allow_zero=True)
        for key, rate in (("cost_alpha", self.cost_alpha), ("prob_alpha", self.prob_alpha)):
            if not (isinstance(rate, int | float) and 0.0 < rate <= 1.0):
                raise ConfigError(f"expected a rate in (0, 1], got {rate!r}", key=key)

    def agent(self, mf_config: Any, mb_config: Any, n_states: int, n_actions: int,
              valid: np.ndarray | None = None) -> MetaAgent:
        """A fresh :class:`MetaAgent` arbitrating this way (:func:`make_meta_agent`)."""
        return make_meta_agent(mf_config, mb_config, n_states, n_actions, self, valid=valid)


def make_meta_agent(mf_config: Any, mb_config: Any, n_states: int, n_actions: int,
                    arbitration: Arbitration | None = None, *,
                    valid: np.ndarray | None = None) -> MetaAgent:
    """A fresh :class:`MetaAgent`: experts of the two agent configs, arbitrating as
    ``arbitration`` says (default :class:`Arbitration`), per-state costs at 0, per-state
    action distributions uniform over the ``valid`` (S, A) bool actions (None: all)."""
    arb = Arbitration() if arbitration is None else arbitration
    mf = make_expert(mf_config, n_states, n_actions)
    mb = make_expert(mb_config, n_states, n_actions)
    mask = core.as_mask(valid, n_states, n_actions)
    probs = np.full((2, n_states, n_actions), 1.0 / n_actions)
    if mask.shape[0] > 0:
        k = np.maximum(mask.sum(axis=1, keepdims=True), 1)
        rows = np.where(mask.any(axis=1, keepdims=True), mask / k, 1.0 / n_actions)
        probs[:] = rows[None]
    return MetaAgent(mf, mb, np.zeros((2, n_states)), np.zeros((2, n_states)), probs,
                     MetaParams(criterion_code(arb.criterion), float(arb.kappa),
                                float(arb.cost_alpha), bool(arb.use_time),
                                float(arb.prob_alpha), bool(arb.reward_ends),
                                bool(arb.state_reward), bool(arb.plan_both_first),
                                arb.ties == "random", bool(arb.forget_goal_moves),
                                bool(arb.learn_from_goal), bool(arb.reward_links)),
                     mask, np.zeros(n_states), np.zeros(n_states, dtype=np.bool_),
                     np.zeros(n_states, dtype=np.bool_), np.full(1, -1, dtype=np.int64),
                     np.full((n_states, n_actions), -1, dtype=np.int64) if arb.reward_links
                     else NO_LINKS)


