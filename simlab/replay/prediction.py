"""The reward rate the empirical MDP predicts for the replay (exact, no sampling).

The replay is a Markov chain on pairs ``(g, s)`` (current goal, current state). With
``pi_g(a | s)`` the policy for goal ``g`` (greedy: uniform over the argmax set, as the
replay breaks ties at random; random: uniform over the actions) and ``T`` the empirical
transition matrix, the state moves with ``P_g(s, s') = sum_a pi_g(a | s) T(s, a, s')``.
Arriving in ``s'`` inside goal ``g`` (``goal_masks[g, s']``) earns a reward of 1 and
switches the goal to one of the other ``G - 1`` goals drawn uniformly (the goal stays
when ``G = 1``)::

    (g, s) -> (g, s')   with probability P_g(s, s')                 if s' not in goal g
    (g, s) -> (h, s')   with probability P_g(s, s') / (G - 1), h != g  if s' in goal g

The expected reward of a transition from ``(g, s)`` is
``r(g, s) = sum_{s' in goal g} P_g(s, s')``.

**Long-run reward per transition.** ``rho = lim_n (1/n) E[sum_{t<n} r(X_t)]`` from the
start distribution ``mu0`` (the replay's start state with the first goal drawn
uniformly). It is computed exactly: the closed communicating classes ``C`` of the chain
(strongly connected components with no edge leaving them) each have a stationary
distribution ``pi_C`` (``pi_C P_C = pi_C``, ``sum pi_C = 1``) and a gain
``g_C = pi_C . r_C``; a transient pair reaches them with the absorption probabilities
``h = (I - P_TT)^-1 P_T,C``; so ``rho = mu0 . v`` with ``v = g_C`` on class ``C`` and
``v_T = (I - P_TT)^-1 P_T,rec v_rec`` on the transient pairs. With a single closed
class (the usual case) ``rho`` is the stationary expected reward.

**Rate per hour.** ``rate = 3600 * rho / tau`` with ``tau`` the expected robot time per
transition (primitive duration plus decision latency, s). The chain does not model
time, so ``tau`` is an input: by default the pace of the dataset the MDP was estimated
from (its simulated hours over its transitions); the replay reports the prediction at
its own measured pace too, which isolates the error of the transition model.

:func:`expected_cumulative_reward` gives the finite-horizon expectation
``sum_{t<n} mu0 P^t r`` (the transient from the start included); the replay reports it
for its own number of transitions next to the long-run rate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.sparse.csgraph import connected_components

from simlab.base.errors import ConfigError


def greedy_policy_matrix(Q: NDArray[np.float64], tie_tolerance: float = 1e-9
                         ) -> NDArray[np.float64]:
    """``(S, A)`` action probabilities, uniform over ``argmax_a Q[s, a]`` (ties within
    ``tie_tolerance * max(1, |max|)``, the rule of :func:`greedy_actions`)."""
    Q = np.asarray(Q, dtype=np.float64)
    ties = greedy_ties(Q, tie_tolerance)
    return ties / ties.sum(axis=1, keepdims=True)


def greedy_ties(Q: NDArray[np.float64], tie_tolerance: float = 1e-9) -> NDArray[np.bool_]:
    """``(S, A)`` bool: the actions within the tie tolerance of each row's maximum."""
    Q = np.asarray(Q, dtype=np.float64)
    best = Q.max(axis=1, keepdims=True)
    return Q >= best - tie_tolerance * np.maximum(1.0, np.abs(best))


def uniform_policy_matrix(n_states: int, n_actions: int) -> NDArray[np.float64]:
    """``(S, A)`` uniform action probabilities (the random policy)."""
    return np.full((n_states, n_actions), 1.0 / n_actions)


@dataclass(frozen=True)
class GoalSwitchChain:
    """The joint chain over pairs ``(g, s)``, index ``g * S + s``.

    ``P`` ``(G*S, G*S)`` row-stochastic; ``r`` ``(G*S,)`` expected reward of a transition
    from each pair; ``n_goals`` G, ``n_states`` S.
    """

    P: NDArray[np.float64]
    r: NDArray[np.float64]
    n_goals: int
    n_states: int


def goal_switch_chain(T: NDArray[np.float64], goal_masks: NDArray[np.bool_],
                      policies: NDArray[np.float64]) -> GoalSwitchChain:
    """Build the joint chain from ``T`` (S, A, S), ``goal_masks`` (G, S) and the per-goal
    policies ``(G, S, A)`` (see the module docstring)."""
    T = np.asarray(T, dtype=np.float64)
    masks = np.asarray(goal_masks, dtype=bool)
    pol = np.asarray(policies, dtype=np.float64)
    if T.ndim != 3 or T.shape[0] != T.shape[2]:
        raise ConfigError(f"expected an (S, A, S) array, got shape {T.shape}", key="T")
    S, A = T.shape[:2]
    if masks.ndim != 2 or masks.shape[1] != S or masks.shape[0] < 1:
        raise ConfigError(f"expected (G, {S}) goal masks, got shape {masks.shape}",
                          key="goal_masks")
    G = masks.shape[0]
    if pol.shape != (G, S, A):
        raise ConfigError(f"expected policies of shape ({G}, {S}, {A}), got {pol.shape}",
                          key="policies")
    P = np.zeros((G * S, G * S))
    r = np.zeros(G * S)
    for g in range(G):
        Pg = np.einsum("sa,sat->st", pol[g], T)
        rows = slice(g * S, (g + 1) * S)
        inside = masks[g]
        stay = np.where(inside[None, :], 0.0, Pg)
        arrive = np.where(inside[None, :], Pg, 0.0)
        r[rows] = arrive.sum(axis=1)
        P[rows, rows] += stay
        if G == 1:
            P[rows, rows] += arrive
            continue
        share = arrive / (G - 1)
        for h in range(G):
            if h != g:
                P[rows, h * S:(h + 1) * S] += share
    return GoalSwitchChain(P=P, r=r, n_goals=G, n_states=S)


def _stationary(P: NDArray[np.float64]) -> NDArray[np.float64]:
    """Stationary distribution ``(n,)`` of an irreducible stochastic matrix ``P`` ``(n, n)``.

    Solves ``pi (P - I) = 0`` with the normalisation ``sum(pi) = 1`` replacing the last
    balance equation (one of them is redundant: the rows of ``P.T - I`` sum to zero) by one
    LU ``solve``: about 10x faster than the former least-squares fit of the overdetermined
    system at a few hundred states, and equal to it within float rounding (~1e-15).
    """
    n = P.shape[0]
    M = P.T - np.eye(n)
    M[-1, :] = 1.0
    b = np.zeros(n)
    b[-1] = 1.0
    pi = np.linalg.solve(M, b)
    pi = np.clip(pi, 0.0, None)
    return pi / pi.sum()


def long_run_gain(P: NDArray[np.float64], r: NDArray[np.float64]) -> NDArray[np.float64]:
    """``v`` ``(n,)``: the long-run average reward per transition from each chain state
    (exact, through the closed classes; see the module docstring)."""
    P = np.asarray(P, dtype=np.float64)
    r = np.asarray(r, dtype=np.float64)
    n = P.shape[0]
    n_comp, labels = connected_components(P > 0, directed=True, connection="strong")
    v = np.zeros(n)
    recurrent = np.zeros(n, dtype=bool)
    for c in range(n_comp):
        members = np.flatnonzero(labels == c)
        outside = np.ones(n, dtype=bool)
        outside[members] = False
        if np.any(P[np.ix_(members, np.flatnonzero(outside))] > 0):
            continue  # transient class: probability leaks out of it
        pi = _stationary(P[np.ix_(members, members)])
        v[members] = float(pi @ r[members])
        recurrent[members] = True
    trans = np.flatnonzero(~recurrent)
    if trans.size:
        rec = np.flatnonzero(recurrent)
        A = np.eye(trans.size) - P[np.ix_(trans, trans)]
        v[trans] = np.linalg.solve(A, P[np.ix_(trans, rec)] @ v[rec])
    return v


def expected_cumulative_reward(P: NDArray[np.float64], r: NDArray[np.float64],
                               mu0: NDArray[np.float64], n: int) -> NDArray[np.float64]:
    """``(n + 1,)`` expected cumulative reward after ``0..n`` transitions from ``mu0``."""
    mu = np.asarray(mu0, dtype=np.float64).copy()
    out = np.zeros(n + 1)
    total = 0.0
    for t in range(n):
        total += float(mu @ r)
        out[t + 1] = total
        mu = mu @ P
    return out


@dataclass(frozen=True)
class RatePrediction:
    """What the MDP predicts for a policy.

    Attributes:
        reward_per_transition: long-run expected reward per transition (rho).
        seconds_per_transition: robot time per transition (s) used for the rate.
        rate_per_hour: ``3600 * rho / seconds_per_transition``.
        n_closed_classes: closed classes of the joint chain reachable from the start
            (1 for a well-connected MDP; more means the long-run rate depends on luck).
        transitions_per_goal: expected transitions between two goals reached (1 / rho).
        horizon: transitions of the finite-horizon expectation (None if not asked).
        expected_rewards: expected cumulative reward over the first ``horizon``
            transitions from the start (:func:`expected_cumulative_reward`); differs from
            ``horizon * rho`` by the transient from the start, and a lot when the chain
            can fall into a rewardless closed class (e.g. states whose actions were never
            tried in the dataset, self-loops by the estimator's rule).
    """

    reward_per_transition: float
    seconds_per_transition: float
    rate_per_hour: float
    n_closed_classes: int
    transitions_per_goal: float
    horizon: int | None = None
    expected_rewards: float | None = None

    def as_dict(self) -> dict[str, float | int | None]:
        out: dict[str, float | int | None] = {
            "reward_per_transition": self.reward_per_transition,
            "seconds_per_transition": self.seconds_per_transition,
            "rate_per_hour": self.rate_per_hour,
            "n_closed_classes": self.n_closed_classes,
            "transitions_per_goal": None if not np.isfinite(self.transitions_per_goal)
            else self.transitions_per_goal,
        }
        if self.horizon is not None:
            out["horizon_transitions"] = self.horizon
            out["expected_rewards_over_horizon"] = self.expected_rewards
        return out


def start_distribution(n_goals: int, n_states: int, start_state: int,
                       first_goal: int | None = None) -> NDArray[np.float64]:
    """``mu0`` over pairs: ``start_state`` with the first goal uniform (or ``first_goal``)."""
    mu0 = np.zeros(n_goals * n_states)
    if first_goal is None:
        mu0[np.arange(n_goals) * n_states + int(start_state)] = 1.0 / n_goals
    else:
        mu0[int(first_goal) * n_states + int(start_state)] = 1.0
    return mu0


def predict_reward_rate(T: NDArray[np.float64], goal_masks: NDArray[np.bool_],
                        policies: NDArray[np.float64], start_state: int,
                        seconds_per_transition: float,
                        horizon: int | None = None) -> RatePrediction:
    """Long-run reward per transition and per hour (see the module docstring).

    ``policies`` ``(G, S, A)``: e.g. ``greedy_policy_matrix`` of each goal's Q-table, or
    :func:`uniform_policy_matrix` repeated for the random policy. With ``horizon``, also
    the expected cumulative reward of the first ``horizon`` transitions.
    """
    if not (np.isfinite(seconds_per_transition) and seconds_per_transition > 0):
        raise ConfigError(f"expected a time > 0 s, got {seconds_per_transition!r}",
                          key="seconds_per_transition")
    chain = goal_switch_chain(T, goal_masks, policies)
    v = long_run_gain(chain.P, chain.r)
    mu0 = start_distribution(chain.n_goals, chain.n_states, start_state)
    rho = float(mu0 @ v)
    # Closed classes reachable from the start.
    _, labels = connected_components(chain.P > 0, directed=True, connection="strong")
    reach = mu0 > 0
    frontier = reach.copy()
    while frontier.any():
        nxt = (chain.P[frontier] > 0).any(axis=0) & ~reach
        reach |= nxt
        frontier = nxt
    closed = 0
    for c in set(labels[reach].tolist()):
        members = labels == c
        if not np.any(chain.P[np.ix_(members, ~members)] > 0):
            closed += 1
    expected = None
    if horizon is not None:
        expected = float(expected_cumulative_reward(chain.P, chain.r, mu0, int(horizon))[-1])
    return RatePrediction(
        reward_per_transition=rho,
        seconds_per_transition=float(seconds_per_transition),
        rate_per_hour=3600.0 * rho / float(seconds_per_transition),
        n_closed_classes=closed,
        transitions_per_goal=1.0 / rho if rho > 0 else float("inf"),
        horizon=None if horizon is None else int(horizon),
        expected_rewards=expected,
    )


def simulate_goal_switching(T: NDArray[np.float64], goal_masks: NDArray[np.bool_],
                            policies: NDArray[np.float64], start_state: int, n: int,
                            rng: np.random.Generator) -> NDArray[np.int64]:
    """Sample ``n`` transitions of the replay in the MDP itself (no physics).

    The first goal is uniform; each step draws ``a ~ policies[g, s]`` and
    ``s' ~ T[s, a]``; arriving in goal ``g`` earns 1 and switches the goal uniformly to
    another one. Returns the rewards ``(n,)`` (0/1). Its mean converges to the
    ``reward_per_transition`` of :func:`predict_reward_rate` (a check of the exact
    computation, and of a model against itself).
    """
    T = np.asarray(T, dtype=np.float64)
    masks = np.asarray(goal_masks, dtype=bool)
    pol_cdf = np.cumsum(np.asarray(policies, dtype=np.float64), axis=2)
    t_cdf = np.cumsum(T, axis=2)
    G = masks.shape[0]
    g = int(rng.integers(0, G))
    s = int(start_state)
    u = rng.random((n, 3))
    out = np.zeros(n, dtype=np.int64)
    for i in range(n):
        a = min(int(np.searchsorted(pol_cdf[g, s], u[i, 0], side="right")), T.shape[1] - 1)
        s = min(int(np.searchsorted(t_cdf[s, a], u[i, 1], side="right")), T.shape[0] - 1)
        if masks[g, s]:
            out[i] = 1
            if G > 1:
                g = int((g + 1 + min(int(u[i, 2] * (G - 1)), G - 2)) % G)
    return out
