"""The MDP-predicted reward rate: hand-solved chains, properties, and Monte Carlo."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simlab.agents.planning import reward_on_arrival, value_iteration
from simlab.base.errors import ConfigError
from simlab.replay.prediction import (
    expected_cumulative_reward,
    goal_switch_chain,
    greedy_policy_matrix,
    long_run_gain,
    predict_reward_rate,
    simulate_goal_switching,
    start_distribution,
    uniform_policy_matrix,
)


def _two_state(p: float) -> tuple[np.ndarray, np.ndarray]:
    """Action 0 moves to the other state with probability p, action 1 stays."""
    T = np.zeros((2, 2, 2))
    for s in range(2):
        T[s, 0, 1 - s], T[s, 0, s] = p, 1 - p
        T[s, 1, s] = 1.0
    return T, np.array([[True, False], [False, True]])


@pytest.mark.parametrize("p", [1.0, 0.6, 0.25])
def test_two_goals_that_alternate_earn_p_per_transition(p: float) -> None:
    T, masks = _two_state(p)
    policy = np.zeros((2, 2, 2))
    policy[:, :, 0] = 1.0  # always "move"
    pred = predict_reward_rate(T, masks, policy, start_state=0, seconds_per_transition=4.0)
    # From either goal's non-goal state each transition succeeds with probability p, and
    # success lands in the other goal's non-goal state: reward p per transition.
    assert pred.reward_per_transition == pytest.approx(p, abs=1e-12)
    assert pred.rate_per_hour == pytest.approx(3600 * p / 4.0)
    assert pred.transitions_per_goal == pytest.approx(1 / p)
    assert pred.n_closed_classes == 1


def test_random_policy_on_three_goals_earns_one_third() -> None:
    # Three states, action j jumps to state j; goal g = {g}. A random action reaches the
    # goal with probability 1/3, and after a switch the robot is never in the new goal.
    T = np.zeros((3, 3, 3))
    for s in range(3):
        for a in range(3):
            T[s, a, a] = 1.0
    masks = np.eye(3, dtype=bool)
    random = np.repeat(uniform_policy_matrix(3, 3)[None], 3, axis=0)
    pred = predict_reward_rate(T, masks, random, start_state=0, seconds_per_transition=1.0)
    assert pred.reward_per_transition == pytest.approx(1 / 3, abs=1e-12)
    greedy = np.stack([greedy_policy_matrix(reward_on_arrival(T, m.astype(float)))
                       for m in masks])
    assert predict_reward_rate(T, masks, greedy, 0, 1.0).reward_per_transition == \
        pytest.approx(1.0)


def test_a_trap_weights_the_gain_by_the_absorption_probability() -> None:
    # 0 -> 1 (prob q) or -> 2 (trap, prob 1 - q); 1 <-> 3 forever. Goals A = {1}, B = {3}.
    q = 0.3
    T = np.zeros((4, 1, 4))
    T[0, 0, 1], T[0, 0, 2] = q, 1 - q
    T[1, 0, 3] = T[3, 0, 1] = T[2, 0, 2] = 1.0
    masks = np.array([[False, True, False, False], [False, False, False, True]])
    policy = np.ones((2, 4, 1))
    pred = predict_reward_rate(T, masks, policy, start_state=0, seconds_per_transition=1.0)
    # Escaping the trap, the robot then earns 1 per transition whatever the goal.
    assert pred.reward_per_transition == pytest.approx(q, abs=1e-12)
    # Closed classes: the trap under goal A, the trap under goal B, the rewarding cycle.
    assert pred.n_closed_classes == 3
    # Over 10 transitions: the first step rewards only from goal A (prob q / 2); escaping
    # the trap (prob q), each of the 9 later ones rewards.
    finite = predict_reward_rate(T, masks, policy, 0, 1.0, horizon=10)
    assert finite.expected_rewards == pytest.approx(q / 2 + 9 * q)


def _random_mdp(rng: np.random.Generator, S: int = 12, A: int = 4, G: int = 3):
    T = rng.dirichlet(np.full(S, 0.3), size=(S, A))
    masks = np.zeros((G, S), dtype=bool)
    for g, s in enumerate(rng.choice(S, size=G, replace=False)):
        masks[g, s] = True
    return T, masks


def test_chain_is_stochastic_and_rewards_are_probabilities() -> None:
    rng = np.random.default_rng(0)
    T, masks = _random_mdp(rng)
    pol = rng.dirichlet(np.ones(4), size=(3, 12))
    chain = goal_switch_chain(T, masks, pol)
    np.testing.assert_allclose(chain.P.sum(axis=1), 1.0, atol=1e-12)
    assert np.all(chain.P >= 0) and np.all((chain.r >= 0) & (chain.r <= 1))


def test_gain_equals_the_cesaro_limit_of_the_expected_cumulative_reward() -> None:
    rng = np.random.default_rng(1)
    T, masks = _random_mdp(rng)
    pol = np.repeat(uniform_policy_matrix(12, 4)[None], 3, axis=0)
    chain = goal_switch_chain(T, masks, pol)
    mu0 = start_distribution(3, 12, start_state=5)
    rho = float(mu0 @ long_run_gain(chain.P, chain.r))
    n = 4000
    curve = expected_cumulative_reward(chain.P, chain.r, mu0, n)
    # A finite irreducible chain: |E[sum_{t<n} r] - n rho| stays bounded, so the average
    # error shrinks like 1/n.
    assert abs(curve[-1] / n - rho) < 5.0 / n
    assert np.all(np.diff(curve) >= 0)
    pred = predict_reward_rate(T, masks, pol, 5, 1.0, horizon=n)
    assert pred.expected_rewards == pytest.approx(curve[-1])


def test_monte_carlo_replay_in_the_mdp_agrees_with_the_exact_rate() -> None:
    rng = np.random.default_rng(2)
    T, masks = _random_mdp(rng, S=15, A=5, G=3)
    policies = np.stack([greedy_policy_matrix(value_iteration(
        T, reward_on_arrival(T, m.astype(float)), 0.9)[0]) for m in masks])
    pred = predict_reward_rate(T, masks, policies, start_state=0, seconds_per_transition=1.0)
    rewards = simulate_goal_switching(T, masks, policies, 0, 60_000, np.random.default_rng(3))
    batches = rewards.reshape(60, 1000).mean(axis=1)  # batch means for the standard error
    se = batches.std(ddof=1) / math.sqrt(len(batches))
    assert abs(rewards.mean() - pred.reward_per_transition) < 4 * se


def test_greedy_policy_splits_ties_evenly() -> None:
    Q = np.array([[1.0, 3.0, 3.0, 0.0], [2.0, 2.0, 2.0, 2.0]])
    pi = greedy_policy_matrix(Q)
    np.testing.assert_allclose(pi, [[0, 0.5, 0.5, 0], [0.25] * 4])


def test_bad_inputs_raise() -> None:
    T, masks = _two_state(0.5)
    with pytest.raises(ConfigError, match="seconds_per_transition"):
        predict_reward_rate(T, masks, np.ones((2, 2, 2)) / 2, 0, 0.0)
    with pytest.raises(ConfigError, match="policies"):
        goal_switch_chain(T, masks, np.ones((3, 2, 2)) / 2)
    with pytest.raises(ConfigError, match="goal_masks"):
        goal_switch_chain(T, masks[:, :1], np.ones((2, 2, 2)) / 2)
