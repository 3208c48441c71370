"""Pure planners: value iteration, policy iteration, Bellman operators, exact returns."""

from __future__ import annotations

import numpy as np
import pytest

from simlab.agents.planning import (
    bellman_expectation_operator,
    bellman_optimality_operator,
    expected_return,
    greedy_policy,
    optimal_finite_horizon_return,
    policy_evaluation,
    policy_iteration,
    reward_on_arrival,
    validate_mdp,
    value_iteration,
)
from simlab.base.errors import ConfigError


def hand_mdp():
    """Three states, two actions, gamma 0.5, solved by hand.

    s0: a0 -> s1 (R 0);  a1 -> s0 (R 0.8)
    s1: a0 -> s2 w.p. 0.75, s0 w.p. 0.25 (R 4);  a1 -> s0 (R 2)
    s2: absorbing, R 0.

    Guess the policy (a0, a0): V0 = 0.5 V1 and V1 = 4 + 0.5 * 0.25 V0, so
    V0 = 2 + V0 / 16  ->  V0 = 32/15,  V1 = 4 + 4/15 = 64/15,  V2 = 0.
    Check the alternatives: Q(0,1) = 0.8 + 0.5 * 32/15 = 28/15 < 32/15 and
    Q(1,1) = 2 + 0.5 * 32/15 = 46/15 < 64/15, so the guess is optimal:
    Q* = [[32/15, 28/15], [64/15, 46/15], [0, 0]].
    """
    P = np.zeros((3, 2, 3))
    P[0, 0, 1] = 1
    P[0, 1, 0] = 1
    P[1, 0, 2] = 0.75
    P[1, 0, 0] = 0.25
    P[1, 1, 0] = 1
    P[2, :, 2] = 1
    R = np.array([[0.0, 0.8], [4.0, 2.0], [0.0, 0.0]])
    Q_star = np.array([[32, 28], [64, 46], [0, 0]]) / 15
    return P, R, 0.5, Q_star


def random_mdp(rng, S=12, A=4, branching=3):
    P = np.zeros((S, A, S))
    for s in range(S):
        for a in range(A):
            succ = rng.choice(S, branching, replace=False)
            P[s, a, succ] = rng.dirichlet(np.ones(branching))
    R = rng.normal(size=(S, A))
    return P, R


def test_value_and_policy_iteration_solve_the_hand_mdp():
    P, R, gamma, Q_star = hand_mdp()
    Q, V, n = value_iteration(P, R, gamma, tol=1e-13)
    np.testing.assert_allclose(Q, Q_star, atol=1e-11)
    np.testing.assert_allclose(V, [32 / 15, 64 / 15, 0], atol=1e-11)
    assert n > 10  # it iterated, it did not stop at once
    Qp, _Vp, k = policy_iteration(P, R, gamma)
    np.testing.assert_allclose(Qp, Q_star, atol=1e-12)
    np.testing.assert_array_equal(greedy_policy(Qp), [0, 0, 0])
    assert k == 1  # the all-zeros start policy is already optimal
    # from (a1, a1): evaluation gives V = (1.6, 2.8); s1 switches to a0 (4.2 > 2.8);
    # then V = (1.6, 4.2) and s0 switches to a0 (2.1 > 1.6); the third is stable
    Qp, _, k = policy_iteration(P, R, gamma, policy0=np.array([1, 1, 0]))
    np.testing.assert_allclose(Qp, Q_star, atol=1e-12)
    assert k == 3


@pytest.mark.parametrize("seed", range(5))
def test_vi_and_pi_agree_on_random_mdps(seed):
    rng = np.random.default_rng(seed)
    P, R = random_mdp(rng)
    gamma = 0.9
    Qv, _Vv, _ = value_iteration(P, R, gamma, tol=1e-12)
    Qp, _Vp, _ = policy_iteration(P, R, gamma)
    np.testing.assert_allclose(Qv, Qp, atol=1e-9)
    # fixed point of the Bellman optimality operator
    np.testing.assert_allclose(bellman_optimality_operator(Qp, P, R, gamma), Qp, atol=1e-10)


@pytest.mark.parametrize("seed", range(10))
def test_bellman_operator_is_a_gamma_contraction(seed):
    rng = np.random.default_rng(100 + seed)
    P, R = random_mdp(rng, S=8, A=3)
    gamma = rng.uniform(0.1, 0.99)
    Q1 = rng.normal(scale=5, size=(8, 3))
    Q2 = Q1 + rng.normal(scale=rng.uniform(0.1, 10), size=(8, 3))
    d_before = np.max(np.abs(Q1 - Q2))
    d_after = np.max(np.abs(bellman_optimality_operator(Q1, P, R, gamma)
                            - bellman_optimality_operator(Q2, P, R, gamma)))  # fmt: skip
    assert d_after <= gamma * d_before + 1e-12
    # the expectation operator of any policy contracts too
    pi = rng.dirichlet(np.ones(3), size=8)
    d_pi = np.max(np.abs(bellman_expectation_operator(Q1, P, R, gamma, pi)
                         - bellman_expectation_operator(Q2, P, R, gamma, pi)))  # fmt: skip
    assert d_pi <= gamma * d_before + 1e-12


def test_policy_evaluation_is_the_fixed_point_of_the_expectation_operator():
    rng = np.random.default_rng(7)
    P, R = random_mdp(rng)
    pi = rng.dirichlet(np.ones(4), size=12)
    Q, V = policy_evaluation(P, R, 0.8, pi)
    np.testing.assert_allclose(bellman_expectation_operator(Q, P, R, 0.8, pi), Q, atol=1e-12)
    np.testing.assert_allclose((pi * Q).sum(1), V, atol=1e-12)


def test_value_iteration_stops_at_max_iter():
    P, R, gamma, _ = hand_mdp()
    _, _, n = value_iteration(P, R, gamma, tol=0.0, max_iter=7)
    assert n == 7


def test_expected_return_on_a_deterministic_chain():
    # 4-state chain, action 0 moves right (absorbing at 3), reward on arrival at 3
    S = 4
    P = np.zeros((S, 1, S))
    for s in range(S):
        P[s, 0, min(s + 1, S - 1)] = 1
    R = reward_on_arrival(P, np.array([0, 0, 0, 1.0]))
    np.testing.assert_array_equal(R[:, 0], [0, 0, 1, 1])
    start = np.array([1.0, 0, 0, 0])
    # from s0 with 10 steps: arrive at 3 on step 3, then 8 more steps inside: 8 rewards
    assert expected_return(P, R, np.zeros(S, int), 10, start) == pytest.approx(8.0)
    uniform = np.full(S, 0.25)
    # starts 0,1,2,3 give 8, 9, 10, 10 rewards
    assert expected_return(P, R, np.zeros(S, int), 10, uniform) == pytest.approx(37 / 4)
    assert optimal_finite_horizon_return(P, R, 10, uniform) == pytest.approx(37 / 4)


def test_finite_horizon_optimum_bounds_every_stationary_policy():
    rng = np.random.default_rng(3)
    P, R = random_mdp(rng)
    start = np.full(12, 1 / 12)
    best = optimal_finite_horizon_return(P, R, 20, start)
    Q, _, _ = value_iteration(P, R, 0.9)
    assert expected_return(P, R, greedy_policy(Q), 20, start) <= best + 1e-12
    for _ in range(20):
        pi = rng.integers(0, 4, 12)
        assert expected_return(P, R, pi, 20, start) <= best + 1e-12


@pytest.mark.parametrize(
    ("mutate", "key", "text"),
    [
        (lambda P, R: (P[:, :, :2], R), "P", "shape"),
        (lambda P, R: (P * 0.9, R), "P", "sums to 0.9"),
        (lambda P, R: (np.where(P > 0.5, -P, P), R), "P", "negative"),
        (lambda P, R: (P, R[:2]), "R", "(S, A)"),
        (lambda P, R: (np.full_like(P, np.nan), R), "P", "NaN"),
    ],
)
def test_validate_mdp_names_the_bad_array(mutate, key, text):
    P, R, gamma, _ = hand_mdp()
    P2, R2 = mutate(P.copy(), R.copy())
    with pytest.raises(ConfigError) as err:
        validate_mdp(P2, R2, gamma)
    assert err.value.key == key
    assert text in str(err.value)


def test_validate_mdp_rejects_bad_gamma():
    P, R, _, _ = hand_mdp()
    with pytest.raises(ConfigError, match="gamma"):
        value_iteration(P, R, 1.0)
