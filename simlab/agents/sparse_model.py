"""Count-based sparse transition model usable inside numba ``@njit`` code.

The model stores, for every visited state-action pair ``(s, a)``,

* ``n(s, a)`` — number of observed transitions (``n_sa``, dense (S, A) int64);
* ``sum r`` — sum of the observed rewards (``r_sum``, dense (S, A) float64);
* the distinct next states ``s'`` with their counts ``n(s, a, s')`` — a pooled
  linked list, one pool entry per distinct observed triple ``(s, a, s')``.

The empirical model is the thesis's eq. 1.13–1.14::

    T(s, a, s') = n(s, a, s') / n(s, a)        R(s, a) = sum r / n(s, a)

Memory
------
The dense per-pair arrays cost ``3 * 8 * S * A`` bytes plus ``8 * S * A`` for the
list of visited pairs (5,184 x 25: about 4 MB). The pool costs 24 bytes per
distinct observed triple and grows by doubling, so memory grows with the number
of distinct visited ``(s, a, s')`` triples, never with ``S * A * S`` (a dense
float64 table for 5,184 x 25 x 5,184 is 5.4 GB).

Value-iteration sweeps re-lay the pool contiguously in sweep order when it has
become fragmented (:func:`count_model_compact`), so a sweep reads memory
sequentially instead of chasing pointers.

Growth is done **inside** njit code: :func:`count_model_observe` reallocates the
pool (doubling its capacity, copying the used part) when it is full, and
replaces the arrays in the structref. A transition is therefore never dropped,
and callers never have to check capacity. Because the model is a *structref* (a
mutable struct passed by reference), every holder of the model sees the new
arrays; never keep a reference to ``model.succ_state`` etc. across an observe
call in njit code (read the fields through the model each time).

Unknown pairs
-------------
An unvisited pair has no model. Planning functions leave ``Q[s, a]`` of pairs with
fewer than ``m_known`` observations untouched, so the caller decides what an
unknown pair is worth by initialising ``Q``: 0 for a plain model-based agent,
``r_max / (1 - gamma)`` for R-max (optimistic until ``m`` visits).

All functions are ``@njit(cache=True)`` and callable from other njit functions
(see :mod:`simlab.agents.kernels` for the full list and a fused-loop example) and
from Python.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numba.core import types
from numba.experimental import structref

__all__ = [
    "CountModel",
    "CountModelType",
    "count_model_add",
    "count_model_backup",
    "count_model_compact",
    "count_model_load",
    "count_model_memory_bytes",
    "count_model_new",
    "count_model_observe",
    "count_model_reward",
    "count_model_transition_row",
    "count_model_triples",
    "count_model_value_iteration",
]


@structref.register
class CountModelType(types.StructRef):
    """Numba type of :class:`CountModel` (a structref: mutable, passed by reference)."""

    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


_I64_2D = types.int64[:, ::1]
_F64_2D = types.float64[:, ::1]
_I64_1D = types.int64[::1]

#: The concrete numba type of every count model (fields are fixed).
COUNT_MODEL_TYPE = CountModelType(
    fields=[
        ("n_states", types.int64),
        ("n_actions", types.int64),
        ("n_sa", _I64_2D),  # (S, A) visits of (s, a)
        ("r_sum", _F64_2D),  # (S, A) sum of rewards observed at (s, a)
        ("n_succ", _I64_2D),  # (S, A) number of distinct observed s'
        ("head", _I64_2D),  # (S, A) first pool entry of (s, a), -1 if none
        ("succ_state", _I64_1D),  # (capacity,) s' of a pool entry
        ("succ_count", _I64_1D),  # (capacity,) n(s, a, s') of a pool entry
        ("succ_link", _I64_1D),  # (capacity,) next pool entry of the same (s, a), -1 ends
        ("n_entries", types.int64),  # used pool entries = distinct observed triples
        ("n_compact", types.int64),  # entries laid out contiguously in pair order (see compact)
        ("pairs", _I64_1D),  # (S*A,) visited pairs s*A + a, in sweep order
        ("n_pairs", types.int64),  # number of visited pairs
    ]
)


class CountModel(structref.StructRefProxy):
    """Sparse count model of an MDP with ``n_states`` states and ``n_actions`` actions.

    ``CountModel(S, A, capacity)`` in Python is the same object that
    :func:`count_model_new` returns in njit code; pass it to the
    ``count_model_*`` kernels. Read-only NumPy views of the counts are exposed
    as properties (they share memory with the model until the pool grows).
    """

    def __new__(cls, n_states: int, n_actions: int, capacity: int = 1024):
        return count_model_new(n_states, n_actions, capacity)

    @property
    def n_states(self) -> int:
        return int(_get_n_states(self))

    @property
    def n_actions(self) -> int:
        return int(_get_n_actions(self))

    @property
    def n_sa(self) -> np.ndarray:
        """(S, A) int64 number of observed transitions from (s, a)."""
        return _get_n_sa(self)

    @property
    def r_sum(self) -> np.ndarray:
        """(S, A) float64 sum of the rewards observed at (s, a)."""
        return _get_r_sum(self)

    @property
    def n_entries(self) -> int:
        """Number of distinct observed (s, a, s') triples."""
        return int(_get_n_entries(self))

    @property
    def n_pairs(self) -> int:
        """Number of distinct visited (s, a) pairs."""
        return int(_get_n_pairs(self))

    @property
    def capacity(self) -> int:
        """Pool capacity (entries allocated; grows by doubling)."""
        return int(_get_capacity(self))

    @property
    def memory_bytes(self) -> int:
        """Bytes held by the model's arrays."""
        return int(count_model_memory_bytes(self))

    def transition_matrix(self) -> tuple[np.ndarray, np.ndarray]:
        """Dense ``(T (S,A,S), R (S,A))`` for small models (tests, export).

        Unvisited pairs get an all-zero row of T (no model) and R = 0; use
        ``n_sa > 0`` to tell them apart.
        """
        S, A = self.n_states, self.n_actions
        T = np.zeros((S, A, S))
        R = np.zeros((S, A))
        for s in range(S):
            for a in range(A):
                count_model_transition_row(self, s, a, T[s, a])
                R[s, a] = count_model_reward(self, s, a)
        return T, R


structref.define_boxing(CountModelType, CountModel)


@njit(cache=True)
def _get_n_states(m):
    return m.n_states


@njit(cache=True)
def _get_n_actions(m):
    return m.n_actions


@njit(cache=True)
def _get_n_sa(m):
    return m.n_sa


@njit(cache=True)
def _get_r_sum(m):
    return m.r_sum


@njit(cache=True)
def _get_n_entries(m):
    return m.n_entries


@njit(cache=True)
def _get_n_pairs(m):
    return m.n_pairs


@njit(cache=True)
def _get_capacity(m):
    return m.succ_state.shape[0]


@njit(cache=True)
def count_model_new(n_states, n_actions, capacity):
    """Create an empty count model.

    Parameters: ``n_states`` S, ``n_actions`` A, ``capacity`` initial pool size in
    distinct triples (it grows by doubling when needed; any value >= 1 works,
    a good guess avoids copies). Returns a :class:`CountModel`.
    """
    m = structref.new(COUNT_MODEL_TYPE)
    m.n_states = n_states
    m.n_actions = n_actions
    m.n_sa = np.zeros((n_states, n_actions), dtype=np.int64)
    m.r_sum = np.zeros((n_states, n_actions), dtype=np.float64)
    m.n_succ = np.zeros((n_states, n_actions), dtype=np.int64)
    m.head = np.full((n_states, n_actions), -1, dtype=np.int64)
    cap = max(capacity, 1)
    m.succ_state = np.empty(cap, dtype=np.int64)
    m.succ_count = np.empty(cap, dtype=np.int64)
    m.succ_link = np.empty(cap, dtype=np.int64)
    m.n_entries = 0
    m.n_compact = 0
    m.pairs = np.empty(n_states * n_actions, dtype=np.int64)
    m.n_pairs = 0
    return m


@njit(cache=True)
def _grow(m):
    k = m.n_entries
    new_cap = 2 * m.succ_state.shape[0]
    st = np.empty(new_cap, dtype=np.int64)
    ct = np.empty(new_cap, dtype=np.int64)
    ln = np.empty(new_cap, dtype=np.int64)
    st[:k] = m.succ_state[:k]
    ct[:k] = m.succ_count[:k]
    ln[:k] = m.succ_link[:k]
    m.succ_state = st
    m.succ_count = ct
    m.succ_link = ln


@njit(cache=True)
def count_model_add(m, s, a, s_next, count, reward_sum):
    """Add ``count`` observations of ``(s, a) -> s_next`` with total reward ``reward_sum``.

    ``count_model_observe`` is ``count_model_add(m, s, a, s_next, 1, r)``; this
    form rebuilds a model from saved triples. Returns the new ``n(s, a)``.
    """
    if m.n_sa[s, a] == 0 and m.head[s, a] == -1:
        m.pairs[m.n_pairs] = s * m.n_actions + a
        m.n_pairs += 1
    m.n_sa[s, a] += count
    m.r_sum[s, a] += reward_sum
    k = m.head[s, a]
    while k != -1:
        if m.succ_state[k] == s_next:
            m.succ_count[k] += count
            return m.n_sa[s, a]
        k = m.succ_link[k]
    if m.n_entries == m.succ_state.shape[0]:
        _grow(m)
    k = m.n_entries
    m.succ_state[k] = s_next
    m.succ_count[k] = count
    m.succ_link[k] = m.head[s, a]
    m.head[s, a] = k
    m.n_entries = k + 1
    m.n_succ[s, a] += 1
    return m.n_sa[s, a]


@njit(cache=True)
def count_model_observe(m, s, a, r, s_next):
    """Record one transition ``(s, a, r, s_next)``; returns the new visit count ``n(s, a)``.

    The returned count lets R-max callers detect the step at which a pair
    becomes known (``n == m``) and replan then.
    """
    return count_model_add(m, s, a, s_next, 1, r)


@njit(cache=True)
def count_model_reward(m, s, a):
    """Empirical mean reward R(s, a) (eq. 1.14); 0.0 for an unvisited pair."""
    n = m.n_sa[s, a]
    if n == 0:
        return 0.0
    return m.r_sum[s, a] / n


@njit(cache=True)
def count_model_transition_row(m, s, a, out):
    """Write the empirical T(s, a, .) (eq. 1.13) into ``out`` (S,) float64.

    ``out`` is zeroed first; an unvisited pair leaves it all zero. Returns the
    number of distinct successors.
    """
    out[:] = 0.0
    n = m.n_sa[s, a]
    if n == 0:
        return 0
    k = m.head[s, a]
    while k != -1:
        out[m.succ_state[k]] = m.succ_count[k] / n
        k = m.succ_link[k]
    return m.n_succ[s, a]


@njit(cache=True)
def row_max(Q, s):
    best = Q[s, 0]
    for b in range(1, Q.shape[1]):
        if Q[s, b] > best:
            best = Q[s, b]
    return best


@njit(cache=True)
def _expected_next_value(m, s, a, V):
    n = m.n_sa[s, a]
    acc = 0.0
    k = m.head[s, a]
    while k != -1:
        acc += m.succ_count[k] * V[m.succ_state[k]]
        k = m.succ_link[k]
    return acc / n


@njit(cache=True)
def count_model_q_value(m, s, a, V, gamma, floor):
    """``(known, R(s, a) + gamma * sum_s' T(s, a, s') V[s'])``; known when
    ``n(s, a) >= floor`` (else the value is 0.0). O(successors)."""
    n = m.n_sa[s, a]
    if n == 0 or n < floor:
        return False, 0.0
    return True, m.r_sum[s, a] / n + gamma * _expected_next_value(m, s, a, V)


@njit(cache=True)
def count_model_backup(m, Q, s, a, gamma, m_known):
    """One Bellman optimality backup at ``(s, a)`` on the empirical model.

    ``Q[s, a] <- R(s, a) + gamma * sum_s' T(s, a, s') max_a' Q[s', a']``, done only
    when ``n(s, a) >= max(m_known, 1)`` (otherwise ``Q[s, a]`` keeps its value:
    0-initialised for plain model-based agents, optimistic for R-max).
    ``Q`` is (S, A) float64, updated in place. Returns ``|change|`` (0.0 when
    skipped). Cost: O(successors(s, a) * A).
    """
    n = m.n_sa[s, a]
    if n == 0 or n < m_known:
        return 0.0
    acc = 0.0
    k = m.head[s, a]
    while k != -1:
        acc += m.succ_count[k] * row_max(Q, m.succ_state[k])
        k = m.succ_link[k]
    new = m.r_sum[s, a] / n + gamma * acc / n
    delta = abs(new - Q[s, a])
    Q[s, a] = new
    return delta


@njit(cache=True)
def count_model_compact(m):
    """Re-lay the pool so each pair's successors are contiguous, pairs in sweep order.

    Observations append entries wherever the pool ends, so after exploration a
    pair's successors are scattered and a sweep chases pointers through the
    whole pool (a cache miss per entry). Compaction copies the entries in the
    order sweeps visit them, after sorting the visited pairs by index ``s * A + a``
    (so sweeps also read ``Q`` row by row); new pairs are appended to that order
    until the next compaction. Counts and successor lists are unchanged.
    O(entries + pairs log pairs); called by :func:`count_model_value_iteration` when more than an
    eighth of the entries arrived since the last compaction.
    """
    cap = m.succ_state.shape[0]
    st = np.empty(cap, dtype=np.int64)
    ct = np.empty(cap, dtype=np.int64)
    ln = np.empty(cap, dtype=np.int64)
    A = m.n_actions
    m.pairs[: m.n_pairs].sort()
    k = 0
    for i in range(m.n_pairs):
        p = m.pairs[i]
        s = p // A
        a = p - s * A
        j = m.head[s, a]
        if j == -1:
            continue
        m.head[s, a] = k
        while j != -1:
            st[k] = m.succ_state[j]
            ct[k] = m.succ_count[j]
            ln[k] = k + 1
            k += 1
            j = m.succ_link[j]
        ln[k - 1] = -1
    m.succ_state = st
    m.succ_count = ct
    m.succ_link = ln
    m.n_compact = k


@njit(cache=True)
def count_model_value_iteration(m, Q, gamma, max_sweeps, tol, m_known):
    """Value-iteration sweeps over the visited pairs, in place on ``Q`` (S, A).

    Each sweep backs up every pair with ``n(s, a) >= max(m_known, 1)`` in the
    model's pair order (see :func:`count_model_compact`; Gauss-Seidel: a backup sees the values updated earlier in the
    same sweep; ``V(s) = max_a Q[s, a]`` is cached and refreshed after each
    change). Stops after ``max_sweeps`` sweeps or as soon as a sweep changes no
    entry by more than ``tol``. Pairs below ``m_known`` keep their ``Q`` value.
    Returns the number of sweeps done. Cost per sweep: O(distinct triples + pairs * A).
    """
    if 8 * (m.n_entries - m.n_compact) > m.n_entries:
        count_model_compact(m)
    S = m.n_states
    A = m.n_actions
    V = np.empty(S, dtype=np.float64)
    for s in range(S):
        V[s] = row_max(Q, s)
    floor = max(m_known, 1)
    sweeps = 0
    while sweeps < max_sweeps:
        sweeps += 1
        delta = 0.0
        for i in range(m.n_pairs):
            p = m.pairs[i]
            s = p // A
            a = p - s * A
            n = m.n_sa[s, a]
            if n < floor:
                continue
            new = m.r_sum[s, a] / n + gamma * _expected_next_value(m, s, a, V)
            old = Q[s, a]
            if new != old:
                d = abs(new - old)
                if d > delta:
                    delta = d
                Q[s, a] = new
                if new > V[s]:
                    V[s] = new
                elif old == V[s]:
                    V[s] = row_max(Q, s)
        if delta <= tol:
            break
    return sweeps


@njit(cache=True)
def count_model_triples(m):
    """All observed triples as arrays ``(s, a, s_next, count)`` (each (n_entries,) int64).

    Ordered by pair (the model's sweep order); :func:`count_model_load` rebuilds an
    identical model (same pair and successor order) from them.
    """
    n = m.n_entries
    ss = np.empty(n, dtype=np.int64)
    aa = np.empty(n, dtype=np.int64)
    nn = np.empty(n, dtype=np.int64)
    cc = np.empty(n, dtype=np.int64)
    A = m.n_actions
    j = 0
    for i in range(m.n_pairs):
        p = m.pairs[i]
        s = p // A
        a = p - s * A
        # successors are listed newest first; write them oldest first so that
        # re-adding them in file order rebuilds the same list
        j += m.n_succ[s, a]
        t = j - 1
        k = m.head[s, a]
        while k != -1:
            ss[t] = s
            aa[t] = a
            nn[t] = m.succ_state[k]
            cc[t] = m.succ_count[k]
            t -= 1
            k = m.succ_link[k]
    return ss, aa, nn, cc


@njit(cache=True)
def count_model_load(m, ss, aa, nn, cc, r_sum):
    """Fill an empty model from :func:`count_model_triples` output and ``r_sum`` (S, A)."""
    for i in range(ss.shape[0]):
        count_model_add(m, ss[i], aa[i], nn[i], cc[i], 0.0)
    m.r_sum[:, :] = r_sum


@njit(cache=True)
def count_model_memory_bytes(m):
    """Bytes held by the model's arrays (dense per-pair arrays + pool + pair list)."""
    per_pair = m.n_sa.nbytes + m.r_sum.nbytes + m.n_succ.nbytes + m.head.nbytes
    pool = m.succ_state.nbytes + m.succ_count.nbytes + m.succ_link.nbytes
    return per_pair + pool + m.pairs.nbytes
