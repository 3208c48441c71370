"""Expected decisions to a goal on a transition model: the optimum and a fixed policy's.

Stochastic shortest paths with unit costs on dense ``P[s, a, s']`` arrays (the decisions
of the :mod:`simlab.calibration.transfer` package docstring).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from simlab.base.errors import ConfigError

#: Relative tolerance of "equal expected steps" (ties, real-optimal actions).
TIE_RTOL = 1e-9


def _check_P(P: ArrayLike) -> NDArray[np.float64]:
    from simlab.agents.planning import validate_mdp

    P = np.asarray(P, dtype=np.float64)
    validate_mdp(P)
    return P


def goal_mask(goal: ArrayLike, n_states: int, *, key: str = "goal_states") -> NDArray[np.bool_]:
    """(S,) bool goal mask from a bool mask or a sequence of state ids (checked)."""
    g = np.asarray(goal)
    if g.dtype == bool:
        if g.shape != (n_states,):
            raise ConfigError(f"expected a ({n_states},) bool mask, got shape {g.shape}", key=key)
        mask = g.copy()
    else:
        ids = g.ravel()
        if ids.size and not np.issubdtype(ids.dtype, np.integer):
            raise ConfigError(f"expected state ids, got {g.tolist()!r}", key=key)
        bad = [int(s) for s in ids if not 0 <= int(s) < n_states]
        if bad:
            raise ConfigError(f"states {bad} not in [0, {n_states})", key=key)
        mask = np.zeros(n_states, dtype=bool)
        mask[ids.astype(np.int64)] = True
    if not mask.any():
        raise ConfigError("no goal state", key=key, fix="give at least one state, e.g. 18")
    return mask


def allowed_mask(mask: ArrayLike | None, S: int, A: int) -> NDArray[np.bool_]:
    """(S, A) bool: the pairs a plan may use (None: all), shape-checked."""
    if mask is None:
        return np.ones((S, A), dtype=bool)
    m = np.asarray(mask)
    if m.dtype != bool or m.shape != (S, A):
        raise ConfigError(f"expected an ({S}, {A}) bool mask, got {m.dtype} {m.shape}",
                          key="mask")
    return m


def _sure_reach(P: NDArray[np.float64], goal: NDArray[np.bool_], allowed: NDArray[np.bool_]
                ) -> tuple[NDArray[np.bool_], NDArray[np.bool_], NDArray[np.int64]]:
    """States from which some policy reaches ``goal`` with probability 1.

    The fixed point of Baier & Katoen (2008), sec. 10.6.1: keep the states ``U`` that can
    reach the goal with positive probability using only actions whose successors all stay in
    ``U``; repeat until ``U`` no longer shrinks. Returns ``(U (S,), safe (S, A), layer (S,))``
    with ``safe`` the allowed actions that never leave ``U`` and ``layer[s]`` the number of
    such steps from ``s`` to the goal (-1 outside ``U``).
    """
    S = P.shape[0]
    support = P > 0
    U = np.ones(S, dtype=bool)
    while True:
        safe = allowed & ~(support & ~U[None, None, :]).any(axis=2)
        safe[~U] = False
        layer = np.full(S, -1, dtype=np.int64)
        layer[goal] = 0
        reach = goal.copy()
        k = 0
        while True:
            k += 1
            into = (safe[:, :, None] & support & reach[None, None, :]).any(axis=(1, 2))
            new = into & U & ~reach
            if not new.any():
                break
            layer[new] = k
            reach |= new
        if np.array_equal(reach, U):
            return U, safe, layer
        U = reach


def _evaluate(P_pi: NDArray[np.float64], F: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Hitting times (S,) of the absorbing chain ``P_pi`` (S, S) from the states ``F``,
    every other state counted as arrived (0); ``F`` must be sure to leave itself."""
    h = np.zeros(P_pi.shape[0])
    idx = np.flatnonzero(F)
    if idx.size:
        M = np.eye(idx.size) - P_pi[np.ix_(idx, idx)]
        h[idx] = np.linalg.solve(M, np.ones(idx.size))
    return h


def _q_steps(P: NDArray[np.float64], V: NDArray[np.float64], safe: NDArray[np.bool_]
             ) -> NDArray[np.float64]:
    """(S, A) expected steps of taking ``a`` then acting optimally; inf for unsafe actions."""
    Vf = np.where(np.isfinite(V), V, 0.0)
    Q = 1.0 + P @ Vf
    return np.where(safe, Q, np.inf)


def solve_shortest_path(P: NDArray[np.float64], goal: NDArray[np.bool_],
                        allowed: NDArray[np.bool_]
                        ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """``(V (S,), Q (S, A), policy (S,))`` of the unit-cost shortest path to ``goal``.

    Policy iteration from the proper policy of the reachability layers (each state steps
    with positive probability to a lower layer), so every iterate is proper and evaluated
    exactly; improvement keeps the current action unless another is better by more than the
    tie tolerance (so it terminates). Then the greedy policy with ties to the lowest index.
    """
    S, A = P.shape[:2]
    U, safe, layer = _sure_reach(P, goal, allowed)
    F = U & ~goal
    policy = np.zeros(S, dtype=np.int64)
    lower = layer[None, None, :] < layer[:, None, None]  # (S, 1, S'): s' in a lower layer
    down = safe & ((P > 0) & lower & U[None, None, :]).any(axis=2)
    for s in np.flatnonzero(F):
        policy[s] = int(np.flatnonzero(down[s])[0])
    for s in np.flatnonzero(~F):
        ok = np.flatnonzero(allowed[s])
        policy[s] = int(ok[0]) if ok.size else 0
    rows = np.arange(S)
    V = np.zeros(S)
    for _ in range(S * A + 1):
        V = _evaluate(P[rows, policy], F)
        Q = _q_steps(P, V, safe)
        best = Q.min(axis=1)
        current = Q[rows, policy]
        better = F & (current > best + TIE_RTOL * (1.0 + best))
        if not better.any():
            break
        policy[better] = np.argmin(Q[better], axis=1)
    V = np.where(U, V, np.inf)
    V[goal] = 0.0
    Q = _q_steps(P, V, safe)
    ties = Q <= (V + TIE_RTOL * (1.0 + np.where(np.isfinite(V), V, 0.0)))[:, None]
    greedy = policy.copy()
    for s in np.flatnonzero(F):
        greedy[s] = int(np.flatnonzero(ties[s])[0])
    if not np.array_equal(greedy, policy):
        # a greedy policy of V* is optimal (Bertsekas & Tsitsiklis 1991, prop. 2); within the
        # tie tolerance it could close a loop, so it is checked and the iterate kept if so
        h = evaluate_policy(P, greedy, goal, None)
        if np.all(np.isfinite(h[F])) and np.allclose(h[F], V[F], rtol=1e-7, atol=1e-9):
            policy = greedy
    return V, Q, policy


def optimal_steps(P: ArrayLike, goal: ArrayLike, mask: ArrayLike | None = None
                  ) -> NDArray[np.float64]:
    """Minimum expected number of decisions to reach the goal, (S,) float64.

    Args:
        P: (S, A, S) transition probabilities, rows summing to 1.
        goal: (S,) bool goal mask, or the goal state ids (arrival ends the count: 0 there).
        mask: (S, A) bool actions allowed (None: all). On a real count model, the pairs the
            robot tried: an untried pair has no data, so no plan may use it.

    Returns:
        (S,) expected steps of the best policy; ``inf`` where no policy using allowed
        actions reaches the goal with probability 1 (module docstring).
    """
    P = _check_P(P)
    g = goal_mask(goal, P.shape[0])
    return solve_shortest_path(P, g, allowed_mask(mask, *P.shape[:2]))[0]


def real_optimal_actions(P: ArrayLike, goal: ArrayLike, mask: ArrayLike | None = None
                         ) -> NDArray[np.bool_]:
    """(S, A) bool: the allowed actions that are optimal (within the tie tolerance) from
    each state with a finite optimum; all False at goal states and where the goal is out of
    reach."""
    P = _check_P(P)
    S, A = P.shape[:2]
    g = goal_mask(goal, S)
    V, Q, _ = solve_shortest_path(P, g, allowed_mask(mask, S, A))
    return optimal_action_mask(V, Q, g)


def optimal_action_mask(V: NDArray[np.float64], Q: NDArray[np.float64],
                        goal: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """(S, A) bool: the actions within :data:`TIE_RTOL` of the optimum ``V`` (none at a goal
    or where the goal cannot be reached)."""
    fin = np.isfinite(V) & ~goal
    out = Q <= (V + TIE_RTOL * (1.0 + np.where(np.isfinite(V), V, 0.0)))[:, None]
    out &= np.isfinite(Q)
    out[~fin] = False
    return out


def evaluate_policy(P: NDArray[np.float64], policy: NDArray[np.int64],
                    goal: NDArray[np.bool_], allowed: NDArray[np.bool_] | None
                    ) -> NDArray[np.float64]:
    """(S,) expected steps to ``goal`` under the deterministic ``policy``; a chosen pair
    outside ``allowed`` keeps the robot in place (``inf`` from where it is reached)."""
    S = P.shape[0]
    rows = np.arange(S)
    P_pi = P[rows, policy].copy()
    if allowed is not None:
        stuck = ~allowed[rows, policy]
        P_pi[stuck] = 0.0
        P_pi[stuck, rows[stuck]] = 1.0
    support = P_pi > 0
    support[goal] = False  # the goal absorbs
    reach = goal.copy()
    while True:
        new = (support & reach[None, :]).any(axis=1) & ~reach
        if not new.any():
            break
        reach |= new
    doomed = ~reach
    while True:  # a positive chance of entering a doomed state dooms too
        new = (support & doomed[None, :]).any(axis=1) & ~doomed & ~goal
        if not new.any():
            break
        doomed |= new
    h = _evaluate(P_pi, ~doomed & ~goal)
    h[doomed] = np.inf
    return h


def _check_policy(policy: ArrayLike, S: int, A: int) -> NDArray[np.int64]:
    pi = np.asarray(policy)
    if pi.shape != (S,) or (pi.size and not np.issubdtype(pi.dtype, np.integer)):
        raise ConfigError(f"expected ({S},) action indices, got {pi.dtype} {pi.shape}",
                          key="policy")
    if pi.size and (pi.min() < 0 or pi.max() >= A):
        raise ConfigError(f"actions must lie in 0..{A - 1}", key="policy")
    return pi.astype(np.int64)


def policy_steps(P: ArrayLike, policy: ArrayLike, goal: ArrayLike,
                 mask: ArrayLike | None = None) -> NDArray[np.float64]:
    """Expected number of decisions to reach the goal under a deterministic policy, (S,).

    Args:
        P: (S, A, S) transition probabilities.
        policy: (S,) action of each state.
        goal: (S,) bool goal mask or goal state ids (0 steps there).
        mask: (S, A) bool pairs with data (None: all). A policy choosing an untried pair
            **stays put** there (module docstring), so it never arrives from that state.

    Returns:
        (S,) hitting times of the goal in the policy's absorbing chain (Kemeny & Snell 1960,
        thm. 3.3.5: ``(I - Q)^-1 1``); ``inf`` for states from which the chain reaches the
        goal with probability below 1.
    """
    P = _check_P(P)
    S, A = P.shape[:2]
    pi = _check_policy(policy, S, A)
    g = goal_mask(goal, S)
    return evaluate_policy(P, pi, g, None if mask is None else allowed_mask(mask, S, A))


def twin_policy(P_twin: ArrayLike, goal: ArrayLike, mask: ArrayLike | None = None
                ) -> NDArray[np.int64]:
    """(S,) the twin's shortest-path policy: fewest expected decisions to ``goal`` on
    ``P_twin`` (S, A, S) over the ``mask`` (S, A) actions; ties to the lowest action index, a
    state without a way to the goal its lowest allowed action (module docstring)."""
    P = _check_P(P_twin)
    S, A = P.shape[:2]
    return solve_shortest_path(P, goal_mask(goal, S), allowed_mask(mask, S, A))[2]
