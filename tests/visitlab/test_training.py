"""Fused training loops: determinism, agreement with the Python loop, learning shapes."""

from __future__ import annotations

import numpy as np
import pytest

from simlab.agents.registry import make_agent
from simlab.base.errors import ConfigError
from simlab.visitlab.curves import smooth_curve, summarize_curve
from simlab.visitlab.reference import train_python
from simlab.visitlab.training import loop_agent_config, make_env, seed_generators, train


def test_same_seed_same_curves_and_q():
    a = train("social", "mb-egreedy", trials=60, seeds=2, seed=3, human="H2", progress=False)
    b = train("social", "mb-egreedy", trials=60, seeds=2, seed=3, human="H2", progress=False)
    np.testing.assert_array_equal(a.returns, b.returns)
    np.testing.assert_array_equal(a.q, b.q)
    c = train("social", "mb-egreedy", trials=60, seeds=2, seed=4, human="H2", progress=False)
    assert not np.array_equal(a.q, c.q)
    # seeded runs are independent: two seeds of one call differ
    assert not np.array_equal(a.q[0], a.q[1])


@pytest.fixture(scope="module")
def social_easy_mb():
    """A model-based learner trained on the easy human (shared: it takes a second)."""
    return train("social", "mb-egreedy", trials=10_000, seeds=1, seed=1, human="easy",
                 progress=False)


@pytest.mark.parametrize(("task", "kwargs"), [
    ("social", {"human": "medium"}),
    ("nav", {"variant": "paper"}),
    ("gotohuman", {"human": "H3"}),
])
def test_fused_loop_equals_python_gymnasium_loop(task, kwargs, social_easy_mb):
    """The numba loop and env.step + Python Q-learning compute the same thing."""
    trials = 40
    # the social task starts from a trained Q so that rewarded transitions occur
    q0 = social_easy_mb.q[0] if task == "social" else None
    fused = train(task, "q-learning", trials=trials, seeds=1, seed=9, progress=False,
                  agent_overrides={"epsilon": 0.3}, initial_q=q0, **kwargs)
    env = make_env(task, **kwargs)
    cfg = loop_agent_config("q-learning", task, kwargs.get("variant", "thesis"),
                            {"epsilon": 0.3})
    env_rng, agent_rng = seed_generators(9, 1)[0]
    returns, Q = train_python(env, cfg, trials, env_rng, agent_rng,
                              None if q0 is None else q0.copy())
    np.testing.assert_array_equal(fused.returns[0], returns)
    np.testing.assert_array_equal(fused.q[0], Q)
    assert returns.sum() > 0  # the comparison covered rewarded transitions


@pytest.mark.parametrize(("agent", "task", "kwargs"), [
    ("mb-egreedy", "social", {"human": "H2"}),
    ("vi-softmax", "nav", {"variant": "paper"}),
    ("rmax", "gotohuman", {}),
    ("sliding-window", "social", {"human": "medium"}),
    ("passive-observer", "nav", {}),
])
def test_fused_loop_equals_agent_classes_on_the_env(agent, task, kwargs):
    """The fused loop does what simlab.agents' agent classes do on the Gymnasium env."""
    trials, seed = 30, 4
    overrides = {"plan_every": 200} if agent != "passive-observer" else {"actor.plan_every": 200}
    if agent == "rmax":
        overrides = {"plan_every": 200}
    fused = train(task, agent, trials=trials, seeds=1, seed=seed, progress=False,
                  agent_overrides=overrides, **kwargs)
    env = make_env(task, **kwargs)
    cfg = loop_agent_config(agent, task, kwargs.get("variant", "thesis"), overrides)
    env_rng, agent_rng = seed_generators(seed, 1)[0]
    env.np_random = env_rng
    learner = make_agent(agent, env.observation_space.n, env.action_space.n, agent_rng,
                         config=cfg)
    returns = np.zeros(trials)
    for k in range(trials):
        if agent == "passive-observer" and k == round(cfg.takeover_fraction * trials):
            learner.take_over()
        returns[k] = learner.fit(env, 1)[0]
    np.testing.assert_array_equal(fused.returns[0], returns)
    np.testing.assert_array_equal(fused.q[0], learner.Q)


def test_navigation_model_based_learns_fast_and_before_model_free():
    """Thesis Fig. 4.1 shape: MB reaches >= 40/50 within ~300 trials, earlier than MF."""
    mb = train("nav", "mb-egreedy", trials=600, seeds=3, seed=0, progress=False)
    mf = train("nav", "q-learning", trials=600, seeds=3, seed=0, progress=False)
    x, mb_curve, _ = smooth_curve(mb.returns, 30)  # bins of 20 trials
    _, mf_curve, _ = smooth_curve(mf.returns, 30)
    mb_hit = x[np.flatnonzero(mb_curve >= 40)[0]]
    assert mb_hit <= 300
    mf_hits = np.flatnonzero(mf_curve >= 40)
    assert mf_hits.size == 0 or x[mf_hits[0]] > mb_hit
    # 45 is the optimum of this trial (6 steps to the goal room, then 45 rewarded steps)
    assert mb.returns[:, -100:].max() <= 45
    assert mb.returns[:, -100:].mean() > 40


def test_social_easy_human_improves_far_above_random_policy(social_easy_mb):
    random_policy = train("social", "q-learning", trials=2000, seeds=1, seed=1, human="easy",
                          progress=False, agent_overrides={"epsilon": 1.0})
    random_level = random_policy.returns.mean()
    late = social_easy_mb.returns[0, -1000:].mean()
    early = social_easy_mb.returns[0, :1000].mean()
    assert random_level < 0.05 and early < 0.05
    assert late > 1.0
    assert late > 20 * max(random_level, 0.01)


def test_continued_learning_starts_from_the_given_q(social_easy_mb):
    """A learner handed a trained Q performs at once (the adaptability setting)."""
    res = train("social", "mb-egreedy", trials=300, seeds=2, seed=5, human="easy",
                initial_q=social_easy_mb.q[0], progress=False)
    assert res.returns.mean() > 1.0
    assert res.config["initial_q"] is True
    with pytest.raises(ConfigError, match="initial_q"):
        train("social", trials=3, seeds=1, initial_q=np.zeros((3, 3)), progress=False)


def test_parallel_workers_give_the_same_result():
    a = train("gotohuman", "q-learning", trials=50, seeds=3, seed=2, progress=False)
    b = train("gotohuman", "q-learning", trials=50, seeds=3, seed=2, progress=False, workers=2)
    np.testing.assert_array_equal(a.returns, b.returns)
    np.testing.assert_array_equal(a.q, b.q)


def test_go_to_human_learns_fixed_episode():
    res = train("gotohuman", "mb-egreedy", trials=400, seeds=2, seed=0, episode="fixed",
                progress=False)
    early = res.returns[:, :20].mean()
    late = res.returns[:, -50:].mean()
    # robot (2, 2) to the human's facing field in front of (12, 12) takes a few steps
    assert late > 30 and late > early + 10


def test_smoothing_and_summary_are_exact_on_a_known_curve():
    returns = np.vstack([np.arange(200.0), np.arange(200.0) + 2])
    x, mean, std = smooth_curve(returns, 100)
    np.testing.assert_array_equal(x, np.arange(2, 201, 2))
    np.testing.assert_allclose(mean, np.arange(100) * 2 + 0.5 + 1)
    np.testing.assert_allclose(std, np.std([0, 1, 2, 3]))
    s = summarize_curve(returns)
    assert s["plateau"] == pytest.approx(np.mean(np.arange(180, 200)) + 1)
    assert s["plateau_std"] == pytest.approx(1.0)
    assert s["n_seeds"] == 2 and s["n_trials"] == 200


def test_variant_settings_and_validation():
    assert loop_agent_config("mb-egreedy").plan_every == 10_000
    assert loop_agent_config("mb-egreedy", variant="paper").plan_every == 1000
    assert loop_agent_config("vi-softmax", variant="paper").max_sweeps == 1
    assert loop_agent_config("rmax", "social", "paper").m == 5
    assert loop_agent_config("rmax", "nav", "paper").m == 1
    assert loop_agent_config("q-learning", variant="paper").alpha == 0.5
    assert loop_agent_config("passive-observer", variant="paper").observer.alpha == 0.5
    assert loop_agent_config("mb-egreedy", overrides={"plan_every": 7}).plan_every == 7
    assert loop_agent_config("mb-egreedy").initial_value == 0.0
    assert loop_agent_config("passive-observer").actor.initial_value == 0.0
    assert loop_agent_config("mb-egreedy", overrides={"q_init": None}).initial_value == pytest.approx(10)
    with pytest.raises(ConfigError, match="agent"):
        loop_agent_config("dqn")
    with pytest.raises(ConfigError, match="gamma"):
        loop_agent_config("q-learning", overrides={"gamma": 1.0})
    with pytest.raises(ConfigError, match="task"):
        train("dance", progress=False)
    with pytest.raises(ConfigError, match="trials"):
        train("nav", trials=0, progress=False)


@pytest.mark.parametrize(("agent", "task"), [
    ("q-softmax", "social"),
    ("vi-softmax", "gotohuman"),
    ("rmax", "nav"),
    ("rmax", "social"),
    ("passive-observer", "social"),
])
def test_other_agents_run_and_keep_q_finite(agent, task):
    res = train(task, agent, trials=30, seeds=1, progress=False)
    assert np.isfinite(res.q).all()
    assert res.returns.shape == (1, 30)
    assert (res.returns >= 0).all() and (res.returns <= res.config["max_steps"]).all()
