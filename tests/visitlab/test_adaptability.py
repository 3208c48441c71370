"""Adaptability (thesis Fig. 4.7): the three humans and continued learning in the
combined architecture with the social agent's Q table and model carried over."""

from __future__ import annotations

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.visitlab.adaptability import BASE_HUMAN, continue_learning, thesis_humans
from simlab.visitlab.combined import CombinedTask, Modules, evaluate
from simlab.visitlab.humans import PRESETS
from simlab.visitlab.passive import nav_optimal_q
from simlab.visitlab.training import EnvSpec, loop_agent_config, run_seed, seed_generators


def test_the_three_humans_differ_from_the_training_human_in_one_parameter():
    h = thesis_humans()
    assert h["same"] == BASE_HUMAN
    assert BASE_HUMAN.speed_probs == (0.0, 1.0, 0.0)
    assert h["slower"].speed_probs == (1.0, 0.0, 0.0)  # 1 cell per step instead of 2
    assert h["slower"].with_(name="easy") == PRESETS["easy"]  # the thesis's easy human
    assert h["pointing"].pointing_need == 1.0
    for name in ("slower", "pointing"):
        for field in ("fail_hello", "lose_attention", "orientation_change", "random_move"):
            assert getattr(h[name], field) == getattr(BASE_HUMAN, field)
    assert h["pointing"].speed_probs == BASE_HUMAN.speed_probs
    with pytest.raises(ConfigError):
        thesis_humans(PRESETS["medium"])


@pytest.fixture(scope="module")
def trained():
    """Small modules: exact navigation values, a short go-to-human and social training
    (the social model kept)."""
    task = CombinedTask(human=BASE_HUMAN, max_steps=30)
    social_cfg = loop_agent_config("mb-egreedy", "social")
    social = run_seed(EnvSpec("social", kwargs={"human": BASE_HUMAN}), social_cfg, 4000,
                      seed_generators(1, 1)[0], keep_model=True)
    assert social.returns.sum() > 0 and social.q.any()  # it learned something to carry
    gth = run_seed(EnvSpec("gotohuman"), loop_agent_config("mb-egreedy", "gotohuman"), 200,
                   seed_generators(1, 1)[0])
    return task, Modules(nav_optimal_q(task.layout), social.q, gth.q), social.model


def test_a_frozen_continuing_agent_acts_like_the_greedy_evaluation(trained):
    """With no exploration and no Q update, continuing means exploiting the given Q:
    the same goals as the greedy evaluation on the same streams."""
    task, modules, model = trained
    frozen = loop_agent_config("mb-egreedy", "social", overrides={
        "epsilon": 0.0, "incremental": False, "plan_every": 0})
    run = continue_learning(task, modules, frozen, 25, seed_generators(4, 1)[0], model=model)
    ref = evaluate(task, modules, 25, seed_generators(4, 1)[0])
    np.testing.assert_array_equal(run.goals, ref.goals)
    np.testing.assert_array_equal(run.q, modules.social_q)


def test_the_carried_model_keeps_its_counts_and_adds_the_new_ones(trained):
    task, modules, model = trained
    cfg = loop_agent_config("mb-egreedy", "social", overrides={"plan_every": 500})
    trials = 12
    steps = trials * task.max_steps
    carried = continue_learning(task, modules, cfg, trials, seed_generators(5, 1)[0],
                                model=model)
    fresh = continue_learning(task, modules, cfg, trials, seed_generators(5, 1)[0])
    old_total = int(model["count"].sum())
    assert int(carried.model["count"].sum()) == old_total + steps
    assert int(fresh.model["count"].sum()) == steps
    # every old triple is still there with at least its old count
    old = {(s, a, n): c for s, a, n, c in zip(model["s"], model["a"], model["s_next"],
                                              model["count"], strict=True)}
    new = {(s, a, n): c for s, a, n, c in zip(carried.model["s"], carried.model["a"],
                                              carried.model["s_next"], carried.model["count"],
                                              strict=True)}
    assert all(new[k] >= c for k, c in old.items())
    np.testing.assert_allclose(carried.model["r_sum"].sum(),
                               model["r_sum"].sum() + carried.social_rewards.sum())
    assert not np.array_equal(carried.q, fresh.q)  # planning used the old experience


def test_continued_learning_is_deterministic_by_seed(trained):
    task, modules, model = trained
    cfg = loop_agent_config("mb-egreedy", "social")
    h = thesis_humans()["pointing"]
    a = continue_learning(task.with_human(h), modules, cfg, 10, seed_generators(8, 1)[0],
                          model=model)
    b = continue_learning(task.with_human(h), modules, cfg, 10, seed_generators(8, 1)[0],
                          model=model)
    np.testing.assert_array_equal(a.goals, b.goals)
    np.testing.assert_array_equal(a.q, b.q)
    with pytest.raises(ConfigError):
        continue_learning(task, modules, cfg, 0, seed_generators(8, 1)[0])
