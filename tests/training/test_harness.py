"""Training harness: fused vs Python paths, seeding, learning on the arena stand-in, curves."""

from __future__ import annotations

import numpy as np
import pytest

from simlab.agents import AGENTS, make_agent
from simlab.agents.planning import expected_return, greedy_policy, reward_on_arrival
from simlab.base.errors import ConfigError
from simlab.training.curves import curve_points
from simlab.training.harness import (
    EpisodeTask,
    evaluate_q,
    run_episodes,
    start_distribution,
    train_runs,
)


@pytest.mark.parametrize("name", list(AGENTS))
def test_fused_loop_equals_python_agent_step_for_step(small_mdp, name):
    reward = small_mdp.goal_reward("g2")
    extra = {"plan_every": 37} if name in ("vi-softmax", "mb-egreedy", "sliding-window") else {}
    results = []
    for fused in (True, False):
        agent = make_agent(name, 12, 16, np.random.default_rng(3), **extra)
        rewards = run_episodes(agent, EpisodeTask(small_mdp.T, reward, horizon=20), 30,
                               np.random.default_rng(4), fused_loop=fused)
        results.append((rewards, agent.Q.copy(), getattr(agent, "controlling", None)))
    (r1, q1, c1), (r2, q2, c2) = results
    np.testing.assert_array_equal(r1, r2)
    np.testing.assert_allclose(q1, q2, rtol=0, atol=1e-12)
    assert c1 == c2
    assert r1.sum() > 0  # something was learned / rewarded


def test_same_seed_same_curves_and_runs_are_independent(small_mdp):
    task = EpisodeTask(small_mdp.T, small_mdp.goal_reward("g1"))
    a = train_runs(task, "vi-softmax", episodes=40, runs=3, seed=11)
    b = train_runs(task, "vi-softmax", episodes=40, runs=3, seed=11)
    c = train_runs(task, "vi-softmax", episodes=40, runs=3, seed=12)
    np.testing.assert_array_equal(a.rewards, b.rewards)
    np.testing.assert_array_equal(a.Q_runs, b.Q_runs)
    assert not np.array_equal(a.rewards, c.rewards)
    assert not np.array_equal(a.rewards[0], a.rewards[1])  # runs use different streams


def test_vi_softmax_reaches_90_percent_of_optimal_on_every_goal(arena_mdp):
    """Stand-in for the table arena: 41 states, 16 actions, T estimated from
    simulated noisy moves (100 samples per pair), 9 goal areas, 2000 episodes."""
    for goal in arena_mdp.goal_names:
        task = EpisodeTask(arena_mdp.T, arena_mdp.goal_reward(goal), horizon=50)
        res = train_runs(task, "vi-softmax", episodes=2000, runs=3, seed=5)
        ev = evaluate_q(task, res.Q_runs, res.gamma)
        on_policy = res.rewards[:, -200:].mean()  # softmax exploration included
        assert on_policy >= 0.9 * ev.optimal_return, goal
        assert np.all(ev.greedy_returns >= 0.9 * ev.optimal_return), goal
        assert ev.optimal_return <= ev.upper_bound + 1e-9


def test_model_based_learns_faster_than_model_free(arena_mdp):
    """Thesis Fig. 4.1: same selection rule, MB reaches a good level in fewer episodes."""
    task = EpisodeTask(arena_mdp.T, arena_mdp.goal_reward("g1"))
    mb = train_runs(task, "mb-egreedy", episodes=300, runs=3, seed=2)
    mf = train_runs(task, "q-learning", episodes=300, runs=3, seed=2)
    assert mb.rewards[:, 50:150].mean() > mf.rewards[:, 50:150].mean() + 3


def test_evaluate_q_of_the_optimal_table_is_the_optimum(small_mdp):
    reward = small_mdp.goal_reward("g4")
    task = EpisodeTask(small_mdp.T, reward, horizon=50)
    ev = evaluate_q(task, np.zeros((1, 12, 16)), 0.9)
    ev2 = evaluate_q(task, ev.Q_star[None], 0.9)
    assert ev2.greedy_returns[0] == pytest.approx(ev.optimal_return)
    R = reward_on_arrival(small_mdp.T, reward)
    uniform = np.full(12, 1 / 12)
    # a zero Q-table's greedy policy is "always action 0"
    assert ev.greedy_returns[0] == pytest.approx(
        expected_return(small_mdp.T, R, greedy_policy(np.zeros((12, 16))), 50, uniform)
    )


def test_start_distribution_and_bad_arguments(small_mdp):
    np.testing.assert_allclose(start_distribution(4), 0.25)
    np.testing.assert_array_equal(start_distribution(4, 2), [0, 0, 1, 0])
    with pytest.raises(ConfigError, match="start"):
        start_distribution(4, 9)
    with pytest.raises(ConfigError, match="episodes"):
        train_runs(EpisodeTask(small_mdp.T, small_mdp.goal_reward("g1")), "rmax", episodes=0,
                   runs=1)
    with pytest.raises(ConfigError, match="known agents"):
        train_runs(EpisodeTask(small_mdp.T, small_mdp.goal_reward("g1")), "sarsa", episodes=1,
                   runs=1)


def test_curve_points_are_block_means_and_stds():
    rewards = np.arange(20, dtype=float).reshape(2, 10)  # run 0: 0..9, run 1: 10..19
    x, mean, std = curve_points(rewards, n_points=5)
    np.testing.assert_array_equal(x, [2, 4, 6, 8, 10])
    # block k pools episodes 2k, 2k+1 of both runs: {2k, 2k+1, 10+2k, 11+2k}
    np.testing.assert_allclose(mean, [5.5, 7.5, 9.5, 11.5, 13.5])
    np.testing.assert_allclose(std, np.std([0, 1, 10, 11]))
    x, mean, _ = curve_points(np.ones(7), n_points=100)  # fewer episodes than points
    assert len(x) == 7 and np.all(mean == 1)
    x, _, _ = curve_points(np.ones((1, 2000)))  # thesis: 100 points, blocks of 20
    assert len(x) == 100 and x[0] == 20 and x[-1] == 2000
