"""Sliding-window transition model (last ``H`` outcomes per state-action pair), njit-usable.

For non-stationary dynamics (a human who changes behaviour) the model of
``(s, a)`` is built from the **last ``H`` observed outcomes** of that pair only:

    T_H(s, a, s') = (number of the last H outcomes that ended in s') / h
    R_H(s, a)     = mean of the last h rewards,   h = min(H, n(s, a))

Layout: each visited pair owns one *slot*, a ring buffer of ``H`` next states
(int64) and ``H`` rewards (float64); ``slot[s, a]`` is -1 for an unvisited pair.
Memory is ``16 * H`` bytes per visited pair plus ``2 * 8 * S * A`` bytes of dense
per-pair indices, i.e. it grows with visited pairs, never with ``S * A * S``. The
slot arrays grow by doubling **inside** njit code when full (the structref's
fields are replaced; never keep a reference to ``model.win_state`` across an
observe call). A backup averages over the window directly, O(H * A).

As for :mod:`simlab.agents.sparse_model`, pairs with fewer than ``m_known``
outcomes in their window are left untouched by planning, so ``Q``'s
initialisation decides what unknown pairs are worth.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numba.core import types
from numba.experimental import structref

from simlab.agents.sparse_model import row_max

__all__ = [
    "WindowModel",
    "WindowModelType",
    "window_model_backup",
    "window_model_export",
    "window_model_load",
    "window_model_memory_bytes",
    "window_model_new",
    "window_model_observe",
    "window_model_reward",
    "window_model_transition_row",
    "window_model_value_iteration",
    "window_model_visits",
]


@structref.register
class WindowModelType(types.StructRef):
    """Numba type of :class:`WindowModel`."""

    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


WINDOW_MODEL_TYPE = WindowModelType(
    fields=[
        ("n_states", types.int64),
        ("n_actions", types.int64),
        ("window", types.int64),  # H
        ("n_sa", types.int64[:, ::1]),  # (S, A) lifetime visits of (s, a)
        ("slot", types.int64[:, ::1]),  # (S, A) slot of (s, a), -1 if unvisited
        ("win_state", types.int64[:, ::1]),  # (capacity, H) next states (ring buffer)
        ("win_reward", types.float64[:, ::1]),  # (capacity, H) rewards (ring buffer)
        ("win_fill", types.int64[::1]),  # (capacity,) outcomes held, <= H
        ("win_pos", types.int64[::1]),  # (capacity,) next write position
        ("slot_pair", types.int64[::1]),  # (capacity,) pair s*A + a owning the slot
        ("n_slots", types.int64),  # used slots = visited pairs
    ]
)


class WindowModel(structref.StructRefProxy):
    """Sliding-window model; ``WindowModel(S, A, window, capacity)`` (see module doc)."""

    def __new__(cls, n_states: int, n_actions: int, window: int, capacity: int = 256):
        return window_model_new(n_states, n_actions, window, capacity)

    @property
    def n_states(self) -> int:
        return int(_wm_n_states(self))

    @property
    def n_actions(self) -> int:
        return int(_wm_n_actions(self))

    @property
    def window(self) -> int:
        return int(_wm_window(self))

    @property
    def n_sa(self) -> np.ndarray:
        """(S, A) int64 lifetime visits (the window holds min(H, n) of them)."""
        return _wm_n_sa(self)

    @property
    def n_pairs(self) -> int:
        return int(_wm_n_slots(self))

    @property
    def memory_bytes(self) -> int:
        return int(window_model_memory_bytes(self))

    def transition_matrix(self) -> tuple[np.ndarray, np.ndarray]:
        """Dense ``(T (S,A,S), R (S,A))`` of the current windows (small models only)."""
        S, A = self.n_states, self.n_actions
        T = np.zeros((S, A, S))
        R = np.zeros((S, A))
        for s in range(S):
            for a in range(A):
                window_model_transition_row(self, s, a, T[s, a])
                R[s, a] = window_model_reward(self, s, a)
        return T, R


structref.define_boxing(WindowModelType, WindowModel)


@njit(cache=True)
def _wm_n_states(m):
    return m.n_states


@njit(cache=True)
def _wm_n_actions(m):
    return m.n_actions


@njit(cache=True)
def _wm_window(m):
    return m.window


@njit(cache=True)
def _wm_n_sa(m):
    return m.n_sa


@njit(cache=True)
def _wm_n_slots(m):
    return m.n_slots


@njit(cache=True)
def window_model_new(n_states, n_actions, window, capacity):
    """Create an empty sliding-window model (``window`` H >= 1 outcomes per pair).

    ``capacity`` is the initial number of pair slots (grows by doubling).
    """
    m = structref.new(WINDOW_MODEL_TYPE)
    m.n_states = n_states
    m.n_actions = n_actions
    m.window = max(window, 1)
    m.n_sa = np.zeros((n_states, n_actions), dtype=np.int64)
    m.slot = np.full((n_states, n_actions), -1, dtype=np.int64)
    cap = max(capacity, 1)
    m.win_state = np.empty((cap, m.window), dtype=np.int64)
    m.win_reward = np.empty((cap, m.window), dtype=np.float64)
    m.win_fill = np.zeros(cap, dtype=np.int64)
    m.win_pos = np.zeros(cap, dtype=np.int64)
    m.slot_pair = np.empty(cap, dtype=np.int64)
    m.n_slots = 0
    return m


@njit(cache=True)
def _wm_grow(m):
    k = m.n_slots
    cap = 2 * m.win_fill.shape[0]
    H = m.window
    ws = np.empty((cap, H), dtype=np.int64)
    wr = np.empty((cap, H), dtype=np.float64)
    wf = np.zeros(cap, dtype=np.int64)
    wp = np.zeros(cap, dtype=np.int64)
    sp = np.empty(cap, dtype=np.int64)
    ws[:k] = m.win_state[:k]
    wr[:k] = m.win_reward[:k]
    wf[:k] = m.win_fill[:k]
    wp[:k] = m.win_pos[:k]
    sp[:k] = m.slot_pair[:k]
    m.win_state = ws
    m.win_reward = wr
    m.win_fill = wf
    m.win_pos = wp
    m.slot_pair = sp


@njit(cache=True)
def window_model_observe(m, s, a, r, s_next):
    """Record ``(s, a, r, s_next)``, evicting the oldest outcome when the window is full.

    Returns the lifetime visit count ``n(s, a)`` (the window holds ``min(H, n)``
    outcomes), so "the pair just became known" is ``n == m`` for both model types.
    """
    k = m.slot[s, a]
    if k == -1:
        if m.n_slots == m.win_fill.shape[0]:
            _wm_grow(m)
        k = m.n_slots
        m.slot[s, a] = k
        m.slot_pair[k] = s * m.n_actions + a
        m.win_fill[k] = 0
        m.win_pos[k] = 0
        m.n_slots = k + 1
    pos = m.win_pos[k]
    m.win_state[k, pos] = s_next
    m.win_reward[k, pos] = r
    pos += 1
    if pos == m.window:
        pos = 0
    m.win_pos[k] = pos
    if m.win_fill[k] < m.window:
        m.win_fill[k] += 1
    m.n_sa[s, a] += 1
    return m.n_sa[s, a]


@njit(cache=True)
def window_model_visits(m, s, a):
    """Outcomes currently in the window of ``(s, a)`` (0 if unvisited)."""
    k = m.slot[s, a]
    if k == -1:
        return 0
    return m.win_fill[k]


@njit(cache=True)
def window_model_reward(m, s, a):
    """Mean reward over the window of ``(s, a)``; 0.0 if unvisited or emptied."""
    k = m.slot[s, a]
    if k == -1:
        return 0.0
    h = m.win_fill[k]
    if h == 0:
        return 0.0
    acc = 0.0
    for i in range(h):
        acc += m.win_reward[k, i]
    return acc / h


@njit(cache=True)
def window_model_transition_row(m, s, a, out):
    """Write the window estimate T_H(s, a, .) into ``out`` (S,); returns outcomes used."""
    out[:] = 0.0
    k = m.slot[s, a]
    if k == -1:
        return 0
    h = m.win_fill[k]
    for i in range(h):
        out[m.win_state[k, i]] += 1.0 / h
    return h


@njit(cache=True)
def window_model_q_value(m, s, a, V, gamma, floor):
    """``(known, mean over the window of r + gamma * V[s'])``; known when the window
    holds at least ``floor`` outcomes (else the value is 0.0)."""
    k = m.slot[s, a]
    if k == -1:
        return False, 0.0
    h = m.win_fill[k]
    if h == 0 or h < floor:
        return False, 0.0
    acc = 0.0
    for i in range(h):
        acc += m.win_reward[k, i] + gamma * V[m.win_state[k, i]]
    return True, acc / h


@njit(cache=True)
def window_model_backup(m, Q, s, a, gamma, m_known):
    """Bellman optimality backup at ``(s, a)`` on the window model, in place on ``Q``.

    Skipped (returns 0.0) when the window holds fewer than ``max(m_known, 1)``
    outcomes. Returns ``|change|``.
    """
    k = m.slot[s, a]
    if k == -1:
        return 0.0
    h = m.win_fill[k]
    if h == 0 or h < m_known:
        return 0.0
    acc = 0.0
    for i in range(h):
        acc += m.win_reward[k, i] + gamma * row_max(Q, m.win_state[k, i])
    new = acc / h
    delta = abs(new - Q[s, a])
    Q[s, a] = new
    return delta


@njit(cache=True)
def window_model_value_iteration(m, Q, gamma, max_sweeps, tol, m_known):
    """Value-iteration sweeps over the visited pairs (Gauss-Seidel), in place on ``Q``.

    Same contract as :func:`simlab.agents.sparse_model.count_model_value_iteration`:
    at most ``max_sweeps`` sweeps, stop when no entry changes by more than
    ``tol``; returns the number of sweeps done.
    """
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
        for k in range(m.n_slots):
            h = m.win_fill[k]
            if h < floor:
                continue
            p = m.slot_pair[k]
            s = p // A
            a = p - s * A
            acc = 0.0
            for i in range(h):
                acc += m.win_reward[k, i] + gamma * V[m.win_state[k, i]]
            new = acc / h
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
def window_model_memory_bytes(m):
    """Bytes held by the model's arrays."""
    return (
        m.n_sa.nbytes
        + m.slot.nbytes
        + m.win_state.nbytes
        + m.win_reward.nbytes
        + m.win_fill.nbytes
        + m.win_pos.nbytes
        + m.slot_pair.nbytes
    )


@njit(cache=True)
def window_model_export(m):
    """Copies of the used slots: ``(slot_pair (n,), win_state (n, H), win_reward (n, H),
    win_fill (n,), win_pos (n,))``, for saving without pickle."""
    n = m.n_slots
    return (
        m.slot_pair[:n].copy(),
        m.win_state[:n].copy(),
        m.win_reward[:n].copy(),
        m.win_fill[:n].copy(),
        m.win_pos[:n].copy(),
    )


@njit(cache=True)
def window_model_load(m, n_sa, slot_pair, win_state, win_reward, win_fill, win_pos):
    """Fill an empty model (same S, A, H) from :func:`window_model_export` output."""
    A = m.n_actions
    n = slot_pair.shape[0]
    while m.win_fill.shape[0] < n:
        _wm_grow(m)
    for k in range(n):
        p = slot_pair[k]
        s = p // A
        a = p - s * A
        m.slot[s, a] = k
        m.slot_pair[k] = p
        m.win_state[k, :] = win_state[k]
        m.win_reward[k, :] = win_reward[k]
        m.win_fill[k] = win_fill[k]
        m.win_pos[k] = win_pos[k]
    m.n_slots = n
    m.n_sa[:, :] = n_sa
