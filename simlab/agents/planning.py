"""Pure dynamic-programming planners on dense MDP arrays (thesis section 1.2).

Conventions: ``P`` is (S, A, S) float64 with ``P[s, a, s']`` the probability of
``s'`` after action ``a`` in ``s`` (rows sum to 1); ``R`` is (S, A) float64, the
expected immediate reward of taking ``a`` in ``s``; ``gamma`` in [0, 1). Q-values
and values are in reward units. Functions are vectorised NumPy (``P @ V``
contracts the last axis), fine for the small MDPs they are meant for (a few
thousand states at most; the dense ``P`` costs ``8 * S * A * S`` bytes).
Nothing here is random and nothing is modified in place.
"""

from __future__ import annotations

import numpy as np

from simlab.base.errors import ConfigError

__all__ = [
    "bellman_expectation_operator",
    "bellman_optimality_operator",
    "expected_return",
    "greedy_policy",
    "optimal_finite_horizon_return",
    "policy_evaluation",
    "policy_iteration",
    "policy_matrix",
    "reward_on_arrival",
    "validate_mdp",
    "value_iteration",
]


def validate_mdp(
    P: np.ndarray,
    R: np.ndarray | None = None,
    gamma: float | None = None,
    *,
    atol: float = 1e-6,
    path: str | None = None,
    p_name: str = "P",
    r_name: str = "R",
) -> None:
    """Check shapes and values; raise :class:`ConfigError` naming the bad array.

    ``P`` must be (S, A, S), finite, non-negative, with every row summing to 1
    within ``atol``; ``R`` (if given) (S, A) and finite; ``gamma`` (if given) in
    [0, 1). ``path`` names the file the arrays came from, for the message.
    """
    P = np.asarray(P)
    if P.ndim != 3 or P.shape[0] != P.shape[2] or P.shape[0] == 0 or P.shape[1] == 0:
        raise ConfigError(
            f"expected an (S, A, S) array with S, A >= 1, got shape {P.shape}",
            path=path,
            key=p_name,
        )
    if not np.issubdtype(P.dtype, np.number):
        raise ConfigError(f"expected numbers, got dtype {P.dtype}", path=path, key=p_name)
    if not np.all(np.isfinite(P)):
        raise ConfigError("contains NaN or infinite values", path=path, key=p_name)
    if np.any(P < 0):
        s, a, s2 = np.argwhere(P < 0)[0]
        raise ConfigError(
            f"negative probability {P[s, a, s2]:g} at [{s}, {a}, {s2}]", path=path, key=p_name
        )
    sums = P.sum(axis=2)
    bad = np.abs(sums - 1.0) > atol
    if np.any(bad):
        s, a = np.argwhere(bad)[0]
        raise ConfigError(
            f"row {p_name}[{s}, {a}, :] sums to {sums[s, a]:.6g}, not 1 "
            f"({int(bad.sum())} of {bad.size} rows are not distributions)",
            path=path,
            key=p_name,
            fix="every (s, a) row must be a probability distribution; unvisited pairs "
            "need a rule such as a self-loop",
        )
    S, A = P.shape[:2]
    if R is not None:
        R = np.asarray(R)
        if R.shape != (S, A):
            raise ConfigError(
                f"expected shape (S, A) = ({S}, {A}) to match {p_name}, got {R.shape}",
                path=path,
                key=r_name,
            )
        if not np.all(np.isfinite(R)):
            raise ConfigError("contains NaN or infinite values", path=path, key=r_name)
    if gamma is not None and not (0.0 <= float(gamma) < 1.0):
        raise ConfigError(f"expected a discount in [0, 1), got {gamma}", key="gamma")


def reward_on_arrival(P: np.ndarray, reward_next: np.ndarray) -> np.ndarray:
    """Expected reward ``R[s, a] = sum_s' P[s, a, s'] reward_next[s']`` (S, A).

    For tasks rewarded by the state reached (e.g. +1 per step inside a goal area).
    """
    return np.asarray(P) @ np.asarray(reward_next, dtype=float)


def bellman_optimality_operator(
    Q: np.ndarray, P: np.ndarray, R: np.ndarray, gamma: float
) -> np.ndarray:
    """``(T* Q)[s, a] = R[s, a] + gamma * sum_s' P[s, a, s'] max_a' Q[s', a']`` (eq. 1.8).

    A ``gamma``-contraction in the sup norm. Returns a new (S, A) array.
    """
    return R + gamma * (P @ Q.max(axis=1))


def policy_matrix(policy: np.ndarray, n_actions: int) -> np.ndarray:
    """(S, A) action probabilities from a deterministic (S,) int policy or an (S, A) one."""
    policy = np.asarray(policy)
    if policy.ndim == 1:
        pi = np.zeros((policy.shape[0], n_actions))
        pi[np.arange(policy.shape[0]), policy.astype(np.int64)] = 1.0
        return pi
    return policy.astype(float)


def bellman_expectation_operator(
    Q: np.ndarray, P: np.ndarray, R: np.ndarray, gamma: float, policy: np.ndarray
) -> np.ndarray:
    """``(T^pi Q)[s, a] = R[s, a] + gamma * sum_s' P[s, a, s'] sum_a' pi(a'|s') Q[s', a']``."""
    pi = policy_matrix(policy, Q.shape[1])
    return R + gamma * (P @ (pi * Q).sum(axis=1))


def greedy_policy(Q: np.ndarray) -> np.ndarray:
    """(S,) int64 ``argmax_a Q[s, a]`` (lowest index among ties; deterministic)."""
    return np.argmax(Q, axis=1).astype(np.int64)


def value_iteration(
    P: np.ndarray,
    R: np.ndarray,
    gamma: float = 0.9,
    *,
    tol: float = 1e-10,
    max_iter: int = 100_000,
    Q0: np.ndarray | None = None,
    validate: bool = True,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Value iteration (thesis Algorithm 2) by repeated :func:`bellman_optimality_operator`.

    Iterates from ``Q0`` (default zeros) until the sup-norm change of one
    application is at most ``tol`` (then ``|Q - Q*| <= tol * gamma / (1 - gamma)``)
    or ``max_iter`` applications. Returns ``(Q (S, A), V (S,), n_iter)``; ``V =
    max_a Q``. ``n_iter == max_iter`` means the tolerance was not reached.
    """
    if validate:
        validate_mdp(P, R, gamma)
    Q = np.zeros(R.shape) if Q0 is None else np.array(Q0, dtype=float)
    n_iter = 0
    while n_iter < max_iter:
        Q_new = bellman_optimality_operator(Q, P, R, gamma)
        n_iter += 1
        delta = np.max(np.abs(Q_new - Q))
        Q = Q_new
        if delta <= tol:
            break
    return Q, Q.max(axis=1), n_iter


def policy_evaluation(
    P: np.ndarray, R: np.ndarray, gamma: float, policy: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Exact ``(Q^pi (S, A), V^pi (S,))`` by solving ``(I - gamma P_pi) V = R_pi``.

    ``policy`` is (S,) int (deterministic) or (S, A) probabilities.
    """
    S, A = R.shape
    pi = policy_matrix(policy, A)
    P_pi = np.einsum("sa,sat->st", pi, P)
    R_pi = (pi * R).sum(axis=1)
    V = np.linalg.solve(np.eye(S) - gamma * P_pi, R_pi)
    Q = R + gamma * (P @ V)
    return Q, V


def policy_iteration(
    P: np.ndarray,
    R: np.ndarray,
    gamma: float = 0.9,
    *,
    max_iter: int = 1000,
    policy0: np.ndarray | None = None,
    atol: float = 1e-12,
    validate: bool = True,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Policy iteration (thesis Algorithm 1) with exact policy evaluation.

    Alternates :func:`policy_evaluation` and greedy improvement until the policy
    is stable. Improvement keeps the current action when it is within ``atol`` of
    the best (so ties cannot make it cycle). Starts from ``policy0`` (default all
    zeros). Returns ``(Q (S, A), V (S,), n_iter)`` with ``n_iter`` the number of
    evaluations.
    """
    if validate:
        validate_mdp(P, R, gamma)
    S = R.shape[0]
    policy = np.zeros(S, dtype=np.int64) if policy0 is None else np.array(policy0, np.int64)
    rows = np.arange(S)
    for n_iter in range(1, max_iter + 1):
        Q, V = policy_evaluation(P, R, gamma, policy)
        best = Q.argmax(axis=1)
        keep = Q[rows, policy] >= Q[rows, best] - atol
        new_policy = np.where(keep, policy, best)
        if np.array_equal(new_policy, policy):
            return Q, V, n_iter
        policy = new_policy
    return Q, V, max_iter


def expected_return(
    P: np.ndarray,
    R: np.ndarray,
    policy: np.ndarray,
    horizon: int,
    start: np.ndarray,
    gamma: float = 1.0,
) -> float:
    """Expected sum of ``horizon`` rewards (discounted by ``gamma``, default 1) from ``start``.

    ``policy`` (S,) int or (S, A) probabilities (stationary); ``start`` (S,) the
    start-state distribution. This is the per-episode return a learning curve
    shows (e.g. 50-step episodes, +1 per step in the goal).
    """
    pi = policy_matrix(policy, R.shape[1])
    P_pi = np.einsum("sa,sat->st", pi, P)
    R_pi = (pi * R).sum(axis=1)
    v = np.zeros(R.shape[0])
    for _ in range(horizon):
        v = R_pi + gamma * (P_pi @ v)
    return float(np.asarray(start, dtype=float) @ v)


def optimal_finite_horizon_return(
    P: np.ndarray, R: np.ndarray, horizon: int, start: np.ndarray
) -> float:
    """Best achievable expected undiscounted ``horizon``-step return from ``start``.

    Backward induction with a time-dependent policy: an upper bound for any
    stationary policy's :func:`expected_return`.
    """
    v = np.zeros(R.shape[0])
    for _ in range(horizon):
        v = (R + P @ v).max(axis=1)
    return float(np.asarray(start, dtype=float) @ v)
