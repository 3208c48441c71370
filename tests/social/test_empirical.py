"""The empirical social module (issue 18, item 4): value iteration on a sparse model
against hand-solved values, the observation reward rule, the direction-pooled model,
same seed -> same Q-table, the renewal prediction, and the pipeline's ``module`` option."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.sparse import csr_matrix

from simlab.base.errors import ConfigError
from simlab.data.estimate import sparse_count_model, valid_actions
from simlab.social.actions import SocialAction
from simlab.social.empirical import (
    OPPOSITE,
    observation_reward,
    pooled_model,
    predict_goal_rate,
    sparse_value_iteration,
    train_empirical,
)
from simlab.social.perception import social_obs_index
from simlab.social.pipeline import social_pipeline
from simlab.social.walk import WalkConfig, social_walk


def test_value_iteration_on_a_hand_made_sparse_mdp() -> None:
    # 3 states, 2 actions. s0 -a0-> s1 (0.5) or s0 (0.5), reward 0; s0 a1 untried.
    # s1 -a0-> s1 reward 1 (the engaged human follows); s1 -a1-> s0. s2: no data.
    s = [0, 0, 1, 1, 1]
    a = [0, 0, 0, 0, 1]
    s2 = [1, 0, 1, 1, 0]
    model = sparse_count_model(s, a, s2, 3, 2)
    R = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 0.0]])
    g = 0.9
    Q, V, _ = sparse_value_iteration(model.matrix(), R, g, valid_actions(model.visited),
                                     tol=1e-13)
    v1 = 1.0 / (1.0 - g)  # 10
    q00 = g * 0.5 * v1 / (1.0 - g * 0.5)  # Q = g (0.5 V1 + 0.5 Q)  -> 8.1818...
    np.testing.assert_allclose(V, [q00, v1, 0.0], atol=1e-10)
    np.testing.assert_allclose(Q[0, 0], q00, atol=1e-10)
    assert Q[0, 1] == -np.inf  # untried in a state with data: masked
    np.testing.assert_allclose(Q[1], [v1, g * q00], atol=1e-10)
    np.testing.assert_array_equal(Q[2], [0.0, 0.0])  # no data: all valid, self-loops


def test_value_iteration_checks_its_inputs() -> None:
    P = csr_matrix(np.eye(2).repeat(2, axis=0))
    with pytest.raises(ValueError, match="shape"):
        sparse_value_iteration(P, np.zeros((3, 2)))
    with pytest.raises(ConfigError, match="gamma"):
        sparse_value_iteration(P, np.zeros((2, 2)), gamma=1.0)


def test_observation_reward_is_the_grid_rule_on_observations() -> None:
    # the human walks toward the robot: opposite of the angle (robot -> human bearing)
    for angle in range(8):
        req = int(OPPOSITE[angle])
        s = social_obs_index(7, 2, req, angle)
        s7 = social_obs_index(7, 1, req, angle)
        s5 = social_obs_index(5, 1, req, angle)
        assert observation_reward([s], [0], [s7])[0] == 1.0
        assert observation_reward([s], [0], [s5])[0] == 0.0  # not level 7 after
        assert observation_reward([s], [int(SocialAction.COME)], [s7])[0] == 0.0  # signal
        other = social_obs_index(7, 2, (req + 1) % 8, angle)
        assert observation_reward([other], [0], [s7])[0] == 0.0
    assert sorted(OPPOSITE[OPPOSITE]) == list(range(8))
    np.testing.assert_array_equal(OPPOSITE[OPPOSITE], np.arange(8))


@pytest.fixture(scope="module")
def walks():
    return social_walk(WalkConfig(steps=120, seed=3))


def test_pooled_model_rows_are_distributions_with_the_redraw_kernel(walks) -> None:
    P, visited, R, base = pooled_model(walks, 0.2)
    np.testing.assert_allclose(np.asarray(P.sum(axis=1)).ravel(), 1.0, atol=1e-12)
    assert P.shape == (2560 * 22, 2560)
    # a visited pooled pair is visited under all 8 directions
    assert visited.sum() == 8 * base.visited.sum()
    # the direction is kept with probability 1 - 0.2 + 0.2 / 8 from any visited pair
    s = int(np.flatnonzero(visited.any(axis=1))[0])
    a = int(np.flatnonzero(visited[s])[0])
    row = P[s * 22 + a].toarray().ravel()
    req = (s // 8) % 8
    kept = sum(row[t] for t in range(2560) if (t // 8) % 8 == req)
    assert kept == pytest.approx(0.8 + 0.2 / 8, abs=1e-12)
    assert np.all((R >= 0) & (R <= 1))


def test_same_walk_same_q_table_and_prediction(walks) -> None:
    from simlab.physics.arena import load_arena

    again = social_walk(WalkConfig(steps=120, seed=3))
    for w1, w2 in zip(walks, again, strict=True):
        np.testing.assert_array_equal(w1.s_next, w2.s_next)
    e1, e2 = train_empirical(walks), train_empirical(again)
    assert e1.q.shape == (2560, 22)
    np.testing.assert_array_equal(e1.q, e2.q)
    goals = tuple(load_arena("table").goals)
    p1 = predict_goal_rate(e1.planned_P, e1.q, e1.R, walks, goals)
    p2 = predict_goal_rate(e2.planned_P, e2.q, e2.R, again, goals)
    assert p1.to_json() == p2.to_json()
    assert p1.goals_per_hour >= 0.0 and p1.decision_s > 0.0
    # every state with data has a finite greedy value; untried actions there are masked
    has = e1.planned_visited.any(axis=1)
    assert np.isfinite(e1.q[has].max(axis=1)).all()
    assert np.all(np.isneginf(e1.q[has][~e1.planned_visited[has]]))


def test_prediction_of_a_hand_made_renewal() -> None:
    # a 2560-state chain where the greedy policy engages in one decision from every start,
    # stays engaged (level 7) and is rewarded every decision: goals/h = step/lead/(1+L)...
    from simlab.physics.arena import GoalArea
    from simlab.social.walk import SocialWalk

    start = social_obs_index(3, 2, 0, 1)
    eng = social_obs_index(7, 2, 0, 1)
    n = 4  # start -> eng, eng -> eng, eng -> eng, eng -> start (lost once in 3)
    s = np.array([start, eng, eng, eng])
    s2 = np.array([eng, eng, eng, start])
    a = np.zeros(n, dtype=np.int64)
    human = np.zeros((n, 3))
    human_next = human.copy()
    human_next[:, 0] = 0.1  # rewarded steps move the human 0.1 m
    reward = np.array([0.0, 1.0, 1.0, 0.0])
    walk = SocialWalk(s=s, a=a, s_next=s2, reward=reward, t=np.arange(n, dtype=float),
                      duration=np.full(n, 2.0), blocked=np.zeros(n, bool), robot=human,
                      robot_next=human, human=human, human_next=human_next,
                      episode=np.zeros(n, dtype=np.int64))
    model = sparse_count_model(s, a, s2, 2560, 22)
    R = np.zeros((2560, 22))
    R[eng, 0] = 2.0 / 3.0
    q = np.where(model.visited, 1.0, 0.0)
    goals = (GoalArea("a", 0.0, 0.0, 0.1), GoalArea("b", 1.1, 0.0, 0.1))
    p = predict_goal_rate(model.matrix(), q, R, [walk], goals, visited=model.visited)
    assert p.p_engage == pytest.approx(1.0)
    assert p.decisions_to_engage == pytest.approx(1.0)
    assert p.p_lose_per_decision == pytest.approx(1.0 / 3.0)
    assert p.engaged_decisions == pytest.approx(3.0)
    assert p.rewarded_per_engagement == pytest.approx(2.0)
    assert p.step_m == pytest.approx(0.1) and p.lead_distance_m == pytest.approx(1.0)
    # 2 rewarded decisions x 0.1 m per 1 m lead, per 4-decision cycle of 2 s
    assert p.goals_per_hour == pytest.approx(2 * 0.1 / 1.0 / 4.0 * 3600.0 / 2.0)
    # never lost in the data: always engaged after the first engagement (f = 1)
    never = SocialWalk(**{**walk.__dict__, "s_next": np.array([eng, eng, eng, eng])})
    model = sparse_count_model(s, a, never.s_next, 2560, 22)
    p = predict_goal_rate(model.matrix(), q, R, [never], goals, visited=model.visited)
    assert p.p_lose_per_decision == 0.0 and p.engaged_decisions == np.inf
    assert p.goals_per_hour == pytest.approx(2.0 / 3.0 * 0.1 / 1.0 * 3600.0 / 2.0)


def test_pipeline_both_writes_the_three_rates(tmp_path: Path) -> None:
    out = tmp_path / "social"
    res = social_pipeline(out=out, hours=0.01, runs=1, trials=300, gif_decisions=0,
                          module="both", walk_steps=60)
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["goals_per_hour"]) == {"grid", "empirical", "random"}
    for key, policy in (("combined", "grid"), ("empirical", "empirical"),
                        ("random", "random")):
        assert summary["goals_per_hour"][policy] == summary["pooled"][key]["goals_per_hour"]
    pred = summary["tabular_prediction"]
    assert isinstance(pred["goals_per_hour"], float) and pred["goals_per_hour"] >= 0.0
    assert set(summary["predicted_goals_per_hour"]) == {"empirical", "grid", "random"}
    measured = summary["predicted_goals_per_hour"]["random"]["measured"]
    assert measured["goals_per_hour"] == pytest.approx(summary["goals_per_hour"]["random"],
                                                       abs=1e-3)
    assert summary["empirical_training"]["walk_steps"] == 60
    q = np.load(out / "social_q_empirical.npy", allow_pickle=False)
    assert q.shape == (2560, 22)
    np.testing.assert_array_equal(q, res.q_empirical)
    assert len(res.empirical) == len(res.combined) == len(res.random) == 1
    assert (out / "cumulative_goals.png").is_file() and (out / "social_q.npy").is_file()


def test_pipeline_rejects_a_bad_module(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="module"):
        social_pipeline(out=tmp_path / "x", module="tabular")
    with pytest.raises(ConfigError, match="walk_steps"):
        social_pipeline(out=tmp_path / "x", module="both", walk_steps=0)
    assert not (tmp_path / "x").exists()


def _hand_walk(rows):
    """A SocialWalk of ``rows`` (s, a, s', reward), 2 s decisions, rewarded moves 0.1 m."""
    from simlab.social.walk import SocialWalk

    s, a, s2, r = (np.array(c) for c in zip(*rows, strict=True))
    n = len(rows)
    human = np.zeros((n, 3))
    human_next = human.copy()
    human_next[:, 0] = 0.1 * (r > 0)
    return SocialWalk(s=s, a=a, s_next=s2, reward=r.astype(float),
                      t=np.arange(n, dtype=float) * 2.0, duration=np.full(n, 2.0),
                      blocked=np.zeros(n, bool), robot=human, robot_next=human, human=human,
                      human_next=human_next, episode=np.zeros(n, dtype=np.int64))


def test_prediction_follows_the_policy_not_the_walk() -> None:
    """At the engaged state the walk tried a0 (stays engaged, rewarded) and a1 (loses):
    loss 1/2 per decision in the walk, but the loop's greedy a0 with epsilon 0.1 loses only
    when the uniform draw picks a1 (1/2 of the epsilon)."""
    from simlab.physics.arena import GoalArea

    start, eng = social_obs_index(3, 2, 0, 1), social_obs_index(7, 2, 0, 1)
    rows = [(start, 0, eng, 0), (eng, 0, eng, 1), (eng, 0, eng, 1), (eng, 0, eng, 1),
            (eng, 1, start, 0), (start, 0, eng, 0), (eng, 1, start, 0), (start, 0, eng, 0),
            (eng, 1, start, 0)]
    walk = _hand_walk(rows)
    model = sparse_count_model(walk.s, walk.a, walk.s_next, 2560, 22)
    R = np.zeros((2560, 22))
    R[eng, 0] = 1.0
    q = np.where(model.visited, 0.0, -np.inf)
    q[eng, 0] = 1.0
    q[~model.visited.any(axis=1)] = 0.0
    goals = (GoalArea("a", 0.0, 0.0, 0.1), GoalArea("b", 1.1, 0.0, 0.1))
    p = predict_goal_rate(model.matrix(), q, R, [walk], goals, visited=model.visited,
                          epsilon=0.1)
    assert p.p_engage == pytest.approx(1.0) and p.decisions_to_engage == pytest.approx(1.0)
    assert p.p_lose_per_decision == pytest.approx(0.05)  # the walk's rate was 0.5
    assert p.engaged_decisions == pytest.approx(20.0)
    rho = 0.9 * 1.0 + 0.1 * 0.5  # greedy a0, or uniform: a0 and a1 (untried: their mean)
    assert p.rewarded_per_engagement == pytest.approx(20.0 * rho)
    assert p.decision_s == pytest.approx(2.0)
    assert p.goals_per_hour == pytest.approx(20 / 21 * rho * 0.1 / 1.0 * 3600 / 2.0)
    # the random policy: uniform, i.e. a0 or a1 with 1/2 each at the engaged state
    pr = predict_goal_rate(model.matrix(), None, R, [walk], goals, visited=model.visited)
    assert pr.p_lose_per_decision == pytest.approx(0.5)
    assert pr.rewarded_per_engagement == pytest.approx(2.0 * 0.5)


def test_loop_factors_count_the_levels_of_a_hand_run() -> None:
    from types import SimpleNamespace

    from simlab.physics.arena import GoalArea
    from simlab.social.empirical import loop_factors

    human = np.zeros((6, 3))
    human[:, 0] = [0.1, 0.2, 0.3, 0.3, 0.3, 0.2]  # toward the goal at x = 1, then back
    run = SimpleNamespace(level=np.array([3, 7, 7, 7, 4, 7]), social_reward=2.0,
                          goals_reached=1, time=np.arange(1, 7) * 3.0, human=human,
                          start_human=np.zeros(3), goal=np.zeros(6, dtype=np.int64))
    f = loop_factors([run], (GoalArea("g", 1.0, 0.0, 0.1), GoalArea("h", 2.0, 0.0, 0.1)))
    # moves while at 7 (decisions 2, 3, 4): +0.1, 0, 0
    assert f["progress_m"] == pytest.approx(0.1 / 3)
    # before each decision: 0 3 7 7 7 4 -> 3 decisions below 7, 2 entries, 3 at 7, 1 loss
    assert f["decisions_to_engage"] == pytest.approx(1.5)
    assert f["p_lose_per_decision"] == pytest.approx(1 / 3)
    assert f["engaged_decisions"] == pytest.approx(3.0)
    assert f["engaged_fraction"] == pytest.approx(0.5)
    assert f["rho"] == pytest.approx(2 / 3) and f["goals_per_reward"] == pytest.approx(0.5)
    assert f["decision_s"] == pytest.approx(3.0)
    assert f["goals_per_hour"] == pytest.approx(1 / (18 / 3600))


def test_pooled_progress_projects_the_move_on_each_required_direction() -> None:
    from simlab.social.empirical import direction_vectors, pooled_progress
    from simlab.social.perception import quantise_direction

    east = quantise_direction(0.0)
    s = social_obs_index(7, 1, east, 2)
    walk = _hand_walk([(s, 4, s, 1), (s, 4, s, 1)])  # the human moves 0.1 m along +x
    g = pooled_progress([walk])
    for req in range(8):
        s_req = social_obs_index(7, 1, req, 2)
        assert g[s_req, 4] == pytest.approx(0.1 * direction_vectors()[req, 0])
    assert g[s, 4] == pytest.approx(0.1)
    assert g[social_obs_index(7, 1, int(OPPOSITE[east]), 2), 4] == pytest.approx(-0.1)
    # only the tried pair has data; 6 of its 8 directions are not perpendicular to +x
    assert np.count_nonzero(g[:, :4]) == 0 and (np.abs(g).sum(axis=1) > 1e-12).sum() == 6
    np.testing.assert_allclose(np.hypot(*direction_vectors().T), 1.0)
