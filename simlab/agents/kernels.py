"""Numba kernels of the agent library, for fused env + agent loops.

Every kernel here is ``@numba.njit(cache=True)`` (the generic ``model_*``
functions are numba overloads in njit code and plain dispatchers in Python): call
it from your own njit loop (fast path) or from Python (each call then pays
numba's dispatch cost, a few microseconds). Every stochastic kernel takes a
``numpy.random.Generator`` (numba supports Generator objects in nopython mode and
advances the *same* bit-generator state, so a seeded Generator gives the same
stream whether it is used from Python or njit code).

The names below are a stable public API (simlab's Visit-the-lab simulation
builds on them); new kernels may be added, these will not change meaning.

Action selection (``q`` is one row ``Q[s]``, (A,) float64; ties broken at random)
    ``greedy_action(q, rng)``, ``epsilon_greedy_action(q, epsilon, rng)``,
    ``softmax_action(q, tau, rng)`` (Boltzmann, temperature ``tau`` > 0,
    numerically stable: subtracts ``max q``; ``tau <= 0`` means greedy),
    ``softmax_probabilities(q, tau, out)``, and
    ``select_action(q, method, epsilon, tau, rng)`` with ``method`` one of
    ``SELECT_GREEDY``, ``SELECT_EPSILON_GREEDY``, ``SELECT_SOFTMAX``.

Model-free update
    ``q_learning_update(Q, s, a, r, s_next, alpha, gamma) -> td_error`` (eq. 1.12,
    in place on ``Q`` (S, A)). For a terminal transition pass ``gamma=0``.

Sampling
    ``sample_categorical(p, rng)`` (p (n,) probabilities) and
    ``sample_from_cdf(cdf, rng)`` (cdf (n,) cumulative, e.g. ``np.cumsum(T[s, a])``;
    O(log n)), used to draw ``s'`` from a dense transition matrix.

Count-based sparse model (:mod:`simlab.agents.sparse_model`, eq. 1.13–1.14)
    ``count_model_new(S, A, capacity)``, ``count_model_observe(m, s, a, r, s_next)
    -> n(s, a)``, ``count_model_backup(m, Q, s, a, gamma, m_known) -> |dQ|``,
    ``count_model_value_iteration(m, Q, gamma, max_sweeps, tol, m_known) ->
    sweeps``, ``count_model_reward``, ``count_model_transition_row``,
    ``count_model_triples``, ``count_model_load``, ``count_model_memory_bytes``,
    ``count_model_compact`` (sweeps call it themselves when the pool is fragmented).
    Memory grows with distinct observed (s, a, s') triples; the pool grows by
    doubling inside njit, so no transition is ever dropped.

Sliding-window model (:mod:`simlab.agents.window_model`, last ``H`` outcomes)
    ``window_model_new(S, A, H, capacity)`` and ``window_model_*`` with the same
    signatures as the count model (plus ``window_model_visits``,
    ``window_model_export`` / ``window_model_load``).

Generic model API (works on either model type; used by the harness)
    ``model_observe``, ``model_backup``, ``model_value_iteration``,
    ``model_reward``, ``model_transition_row``, and the one-call
    ``model_based_update(model, Q, s, a, r, s_next, gamma, m_known, incremental,
    replan_when_known, max_sweeps, tol) -> n(s, a)``.

R-max
    Initialise ``Q`` with ``rmax_q_init(S, A, r_max, gamma)`` (every entry
    ``r_max / (1 - gamma)``), act greedily, and update with
    ``model_based_update(..., m_known=m, incremental=True, replan_when_known, ...)``:
    a pair's value stays optimistic until it has been visited ``m`` times (paper:
    m=1 navigation, m=5 social). Either plan periodically (the paper, and
    :class:`~simlab.agents.config.RMaxConfig`'s default: one sweep every 1,000
    steps) or pass ``replan_when_known=True`` (classic R-max: value iteration the
    step a pair becomes known; exact, but one planning per pair). Counts keep
    accumulating after ``m`` visits (a better model in stochastic worlds).

How a foreign fused loop uses these kernels
-------------------------------------------
Agent state is plain data you create once and pass in: ``Q`` an (S, A) float64
array, a model from ``count_model_new`` / ``window_model_new`` (in Python or inside
njit), and a ``numpy.random.Generator``. Per step: select an action on ``Q[s]``,
step your environment, then update. Planning every ``k`` steps is a call to
``model_value_iteration`` guarded by a step counter. A passive model-free observer
is just a second ``Q`` array updated with ``q_learning_update`` on the acting
agent's transitions; to hand over control, select actions on the observer's
``Q`` instead (and stop updating the model)::

    import numpy as np
    from numba import njit
    from simlab.agents.kernels import (
        count_model_new, model_based_update, model_value_iteration,
        q_learning_update, softmax_action)

    @njit(cache=True)
    def chain_step(s, a, n_states):        # your environment (here: a chain)
        s_next = min(s + 1, n_states - 1) if a == 1 else max(s - 1, 0)
        return s_next, 1.0 if s_next == n_states - 1 else 0.0

    @njit(cache=True)
    def train(Q, Q_obs, model, rng, n_trials, n_steps, gamma, tau, alpha, plan_every):
        S = Q.shape[0]
        t = 0
        returns = np.zeros(n_trials)
        for trial in range(n_trials):
            s = 0
            for _ in range(n_steps):
                a = softmax_action(Q[s], tau, rng)
                s_next, r = chain_step(s, a, S)
                # MB agent: count + one backup at (s, a); nothing is replanned
                # when a pair becomes known (that is R-max's switch)
                model_based_update(model, Q, s, a, r, s_next, gamma, 1, True, False, 0, 0.0)
                q_learning_update(Q_obs, s, a, r, s_next, alpha, gamma)  # observer
                t += 1
                if t % plan_every == 0:                   # periodic planning
                    model_value_iteration(model, Q, gamma, 50, 1e-6, 1)
                returns[trial] += r
                s = s_next
        return returns

    S, A = 10, 2
    model = count_model_new(S, A, 64)
    Q, Q_obs = np.zeros((S, A)), np.zeros((S, A))
    returns = train(Q, Q_obs, model, np.random.default_rng(0), 200, 30, 0.9, 0.1, 0.5, 100)

``tests/agents/test_kernels.py`` runs this example. Note on ``cache=True``: numba
does not track dependencies between cached functions in different files; simlab's own
kernels are cached per version of the whole source (:mod:`simlab.base._numba_cache`), so an
edit here recompiles its callers. Your own cached loops calling these kernels need the
same care (their cache files do not notice a new simlab).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numba.extending import overload

from simlab.agents.sparse_model import (
    CountModel,
    CountModelType,
    count_model_add,
    count_model_backup,
    count_model_compact,
    count_model_load,
    count_model_memory_bytes,
    count_model_new,
    count_model_observe,
    count_model_q_value,
    count_model_reward,
    count_model_transition_row,
    count_model_triples,
    count_model_value_iteration,
)
from simlab.agents.window_model import (
    WindowModel,
    WindowModelType,
    window_model_backup,
    window_model_export,
    window_model_load,
    window_model_memory_bytes,
    window_model_new,
    window_model_observe,
    window_model_q_value,
    window_model_reward,
    window_model_transition_row,
    window_model_value_iteration,
    window_model_visits,
)

__all__ = [
    "SELECT_EPSILON_GREEDY",
    "SELECT_GREEDY",
    "SELECT_SOFTMAX",
    "CountModel",
    "WindowModel",
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
    "epsilon_greedy_action",
    "greedy_action",
    "model_backup",
    "model_based_update",
    "model_observe",
    "model_q_value",
    "model_reward",
    "model_transition_row",
    "model_value_iteration",
    "q_learning_update",
    "rmax_q_init",
    "sample_categorical",
    "sample_from_cdf",
    "select_action",
    "softmax_action",
    "softmax_probabilities",
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

#: ``method`` codes of :func:`select_action`.
SELECT_GREEDY = 0
SELECT_EPSILON_GREEDY = 1
SELECT_SOFTMAX = 2


# --------------------------------------------------------------------------- selection
#: The ``vrow`` of "every action valid" (a zero-length bool row).
ALL_VALID = np.zeros(0, dtype=np.bool_)


@njit(cache=True, inline="always")
def _ok(vrow, b):
    return vrow.shape[0] == 0 or vrow[b]


@njit(cache=True)
def n_valid(vrow, n_actions):
    """Number of valid actions in ``vrow`` (A,) bool (``n_actions`` for :data:`ALL_VALID`)."""
    if vrow.shape[0] == 0:
        return n_actions
    k = 0
    for b in range(vrow.shape[0]):
        if vrow[b]:
            k += 1
    return k


@njit(cache=True)
def _kth_valid(vrow, k):
    if vrow.shape[0] == 0:
        return k
    for b in range(vrow.shape[0]):
        if vrow[b]:
            if k == 0:
                return b
            k -= 1
    return vrow.shape[0] - 1


@njit(cache=True)
def masked_greedy(q, vrow, rng):
    """Index of the largest ``q`` (A,) among the valid actions ``vrow`` (A,) bool, or all
    actions for :data:`ALL_VALID`; among exact ties one drawn uniformly with ``rng``
    (one draw, only when there is a tie). ``vrow`` must have a valid action."""
    # "every action valid" decided once, outside the loops: the compiler then unswitches
    # them and the unmasked case runs the plain loop (as fast as a mask-free kernel)
    every = vrow.shape[0] == 0
    best = -np.inf
    n_best = 0
    for b in range(q.shape[0]):
        if every or vrow[b]:
            if n_best == 0 or q[b] > best:
                best = q[b]
                n_best = 1
            elif q[b] == best:
                n_best += 1
    k = 0 if n_best == 1 else rng.integers(0, n_best)
    for b in range(q.shape[0]):
        if (every or vrow[b]) and q[b] == best:
            if k == 0:
                return b
            k -= 1
    return q.shape[0] - 1  # unreachable (NaN-free q)


@njit(cache=True)
def masked_softmax(q, vrow, tau, rng):
    """Boltzmann draw at temperature ``tau`` among the valid actions (see
    :func:`softmax_action`); ``tau <= 0`` is :func:`masked_greedy`."""
    if tau <= 0.0:
        return masked_greedy(q, vrow, rng)
    every = vrow.shape[0] == 0  # hoisted: see masked_greedy
    qmax = -np.inf
    for b in range(q.shape[0]):
        if (every or vrow[b]) and q[b] > qmax:
            qmax = q[b]
    total = 0.0
    for b in range(q.shape[0]):
        if every or vrow[b]:
            total += np.exp((q[b] - qmax) / tau)
    target = rng.random() * total
    acc = 0.0
    last = 0
    for b in range(q.shape[0]):
        if every or vrow[b]:
            w = np.exp((q[b] - qmax) / tau)
            if w > 0.0:
                last = b
                acc += w
                if target < acc:
                    return b
    return last  # rounding: target == total


@njit(cache=True)
def masked_select(q, vrow, method, epsilon, tau, rng):
    """Action selection ``method`` on ``q`` (A,) among the valid actions ``vrow`` (A,) bool
    (:data:`ALL_VALID`: every action; a row without a valid action: every action).

    An epsilon draw picks the ``k``-th valid action with ``k`` uniform among the ``n``
    valid ones, exactly as an unmasked draw among ``A``: an all-True row gives the same
    draws and actions as :data:`ALL_VALID`.
    """
    if vrow.shape[0] > 0 and n_valid(vrow, q.shape[0]) == 0:
        return _select(q, ALL_VALID, method, epsilon, tau, rng)
    return _select(q, vrow, method, epsilon, tau, rng)


@njit(cache=True, inline="always")
def _select(q, vrow, method, epsilon, tau, rng):
    if method == SELECT_SOFTMAX:
        return masked_softmax(q, vrow, tau, rng)
    if method == SELECT_EPSILON_GREEDY and epsilon > 0.0 and rng.random() < epsilon:
        return _kth_valid(vrow, rng.integers(0, n_valid(vrow, q.shape[0])))
    return masked_greedy(q, vrow, rng)


@njit(cache=True)
def greedy_action(q, rng):
    """Index of ``max(q)``; among exact ties, one chosen uniformly with ``rng``.

    ``q`` is (A,) float64. Draws one random number only when there is a tie.
    """
    return masked_greedy(q, ALL_VALID, rng)


@njit(cache=True)
def epsilon_greedy_action(q, epsilon, rng):
    """With probability ``epsilon`` a uniform action, else :func:`greedy_action`."""
    return masked_select(q, ALL_VALID, SELECT_EPSILON_GREEDY, epsilon, 0.0, rng)


@njit(cache=True)
def softmax_probabilities(q, tau, out):
    """Write ``exp((q - max q) / tau) / sum(...)`` (eq. 1.9) into ``out`` (A,).

    ``tau <= 0`` gives the greedy limit (uniform over the maximisers). Returns ``out``.
    """
    A = q.shape[0]
    qmax = q[0]
    for b in range(1, A):
        if q[b] > qmax:
            qmax = q[b]
    total = 0.0
    if tau <= 0.0:
        for b in range(A):
            out[b] = 1.0 if q[b] == qmax else 0.0
            total += out[b]
    else:
        for b in range(A):
            out[b] = np.exp((q[b] - qmax) / tau)
            total += out[b]
    for b in range(A):
        out[b] /= total
    return out


@njit(cache=True)
def softmax_action(q, tau, rng):
    """Sample from the Boltzmann distribution of ``q`` (A,) at temperature ``tau``.

    Numerically stable (weights ``exp((q - max q) / tau)`` lie in (0, 1], the max
    has weight 1). Equal values get equal probability, so ties are random by
    construction. ``tau <= 0`` falls back to :func:`greedy_action`. No allocation.
    """
    return masked_softmax(q, ALL_VALID, tau, rng)


@njit(cache=True)
def select_action(q, method, epsilon, tau, rng):
    """Dispatch on ``method`` (``SELECT_GREEDY`` / ``SELECT_EPSILON_GREEDY`` / ``SELECT_SOFTMAX``)."""
    return masked_select(q, ALL_VALID, method, epsilon, tau, rng)


# --------------------------------------------------------------------------- learning
@njit(cache=True)
def q_learning_update(Q, s, a, r, s_next, alpha, gamma):
    """Q-learning (eq. 1.12): ``Q[s,a] += alpha * (r + gamma * max Q[s_next] - Q[s,a])``.

    ``Q`` (S, A) float64 in place. Returns the TD error. ``gamma=0`` for a
    terminal transition (no bootstrap).
    """
    best = Q[s_next, 0]
    for b in range(1, Q.shape[1]):
        if Q[s_next, b] > best:
            best = Q[s_next, b]
    td = r + gamma * best - Q[s, a]
    Q[s, a] += alpha * td
    return td


@njit(cache=True)
def rmax_q_init(n_states, n_actions, r_max, gamma):
    """(S, A) array filled with the optimistic value ``r_max / (1 - gamma)``."""
    return np.full((n_states, n_actions), r_max / (1.0 - gamma))


# --------------------------------------------------------------------------- sampling
@njit(cache=True)
def sample_categorical(p, rng):
    """Draw an index with probabilities ``p`` (n,) (non-negative; normalised by its sum)."""
    total = 0.0
    for i in range(p.shape[0]):
        total += p[i]
    target = rng.random() * total
    acc = 0.0
    last = 0
    for i in range(p.shape[0]):
        if p[i] > 0.0:
            last = i
            acc += p[i]
            if target < acc:
                return i
    return last


@njit(cache=True)
def sample_from_cdf(cdf, rng):
    """Draw an index from a cumulative distribution ``cdf`` (n,) non-decreasing.

    Returns the smallest ``i`` with ``cdf[i] > u * cdf[-1]``, ``u`` uniform in [0, 1)
    (zero-probability entries are never returned). O(log n).
    """
    target = rng.random() * cdf[cdf.shape[0] - 1]
    lo = 0
    hi = cdf.shape[0] - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if cdf[mid] > target:
            hi = mid
        else:
            lo = mid + 1
    return lo


# --------------------------------------------------------------------------- generic model API
# In njit code these names resolve to the overloads below (compiled per model
# type); called from Python they dispatch on the proxy class.
def _python_dispatch(model, count_fn, window_fn, *args):
    if isinstance(model, CountModel):
        return count_fn(model, *args)
    if isinstance(model, WindowModel):
        return window_fn(model, *args)
    raise TypeError(f"expected a CountModel or WindowModel, got {type(model).__name__}")


def model_observe(model, s, a, r, s_next):
    """Record a transition in a count or window model; returns the lifetime ``n(s, a)``."""
    return _python_dispatch(model, count_model_observe, window_model_observe, s, a, r, s_next)


def model_backup(model, Q, s, a, gamma, m_known):
    """Bellman backup at ``(s, a)`` on a count or window model; returns ``|dQ|``."""
    return _python_dispatch(model, count_model_backup, window_model_backup, Q, s, a, gamma, m_known)


def model_value_iteration(model, Q, gamma, max_sweeps, tol, m_known):
    """Value-iteration sweeps on a count or window model; returns the sweeps done."""
    return _python_dispatch(
        model, count_model_value_iteration, window_model_value_iteration,
        Q, gamma, max_sweeps, tol, m_known,
    )  # fmt: skip


def model_reward(model, s, a):
    """Model reward R(s, a) of a count or window model."""
    return _python_dispatch(model, count_model_reward, window_model_reward, s, a)


def model_transition_row(model, s, a, out):
    """Model row T(s, a, .) of a count or window model into ``out`` (S,)."""
    return _python_dispatch(
        model, count_model_transition_row, window_model_transition_row, s, a, out
    )


def model_q_value(model, s, a, V, gamma, floor):
    """``(known, R(s, a) + gamma * E[V(s')])`` of a count or window model."""
    return _python_dispatch(model, count_model_q_value, window_model_q_value, s, a, V, gamma,
                            floor)


_CACHE = {"cache": True}


@overload(model_observe, jit_options=_CACHE)
def _ov_observe(model, s, a, r, s_next):
    if isinstance(model, CountModelType):
        return lambda model, s, a, r, s_next: count_model_observe(model, s, a, r, s_next)
    if isinstance(model, WindowModelType):
        return lambda model, s, a, r, s_next: window_model_observe(model, s, a, r, s_next)
    return None


@overload(model_backup, jit_options=_CACHE)
def _ov_backup(model, Q, s, a, gamma, m_known):
    if isinstance(model, CountModelType):
        return lambda model, Q, s, a, gamma, m_known: count_model_backup(
            model, Q, s, a, gamma, m_known
        )
    if isinstance(model, WindowModelType):
        return lambda model, Q, s, a, gamma, m_known: window_model_backup(
            model, Q, s, a, gamma, m_known
        )
    return None


@overload(model_value_iteration, jit_options=_CACHE)
def _ov_vi(model, Q, gamma, max_sweeps, tol, m_known):
    if isinstance(model, CountModelType):
        return lambda model, Q, gamma, max_sweeps, tol, m_known: count_model_value_iteration(
            model, Q, gamma, max_sweeps, tol, m_known
        )
    if isinstance(model, WindowModelType):
        return lambda model, Q, gamma, max_sweeps, tol, m_known: window_model_value_iteration(
            model, Q, gamma, max_sweeps, tol, m_known
        )
    return None


@overload(model_q_value, jit_options=_CACHE)
def _ov_q_value(model, s, a, V, gamma, floor):
    if isinstance(model, CountModelType):
        return lambda model, s, a, V, gamma, floor: count_model_q_value(
            model, s, a, V, gamma, floor
        )
    if isinstance(model, WindowModelType):
        return lambda model, s, a, V, gamma, floor: window_model_q_value(
            model, s, a, V, gamma, floor
        )
    return None


@overload(model_reward, jit_options=_CACHE)
def _ov_reward(model, s, a):
    if isinstance(model, CountModelType):
        return lambda model, s, a: count_model_reward(model, s, a)
    if isinstance(model, WindowModelType):
        return lambda model, s, a: window_model_reward(model, s, a)
    return None


@overload(model_transition_row, jit_options=_CACHE)
def _ov_row(model, s, a, out):
    if isinstance(model, CountModelType):
        return lambda model, s, a, out: count_model_transition_row(model, s, a, out)
    if isinstance(model, WindowModelType):
        return lambda model, s, a, out: window_model_transition_row(model, s, a, out)
    return None


@njit(cache=True)
def model_based_update(
    model, Q, s, a, r, s_next, gamma, m_known, incremental, replan_when_known, max_sweeps, tol
):
    """Observe ``(s, a, r, s_next)`` and update ``Q`` (S, A) in place; returns ``n(s, a)``.

    * ``replan_when_known`` and this visit makes ``n(s, a) == m_known``: run
      value iteration (``max_sweeps``, ``tol``) — R-max's replanning when a pair
      becomes known;
    * otherwise, if ``incremental``: one backup at ``(s, a)`` (skipped below
      ``m_known`` visits).

    Periodic planning ("a VI sweep every k steps") is the caller's step counter
    plus :func:`model_value_iteration`.
    """
    n = model_observe(model, s, a, r, s_next)
    if replan_when_known and n == m_known:
        model_value_iteration(model, Q, gamma, max_sweeps, tol, m_known)
    elif incremental:
        model_backup(model, Q, s, a, gamma, m_known)
    return n
