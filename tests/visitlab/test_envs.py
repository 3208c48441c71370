"""Gymnasium envs: check_env, seeding, kernel/env agreement, info, renders."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import simlab  # noqa: F401  (registers the ids)
from simlab.base.errors import ConfigError
from simlab.visitlab import dynamics as dyn
from simlab.visitlab.actions import DIR_DELTA, Action
from simlab.visitlab.envs import (
    GoToHumanEnv,
    NavEnv,
    SocialEnv,
    StartPoses,
    decode_gth,
    encode_social,
)

ENV_CASES = [
    ("simlab/VisitLab-Nav-v0", {}),
    ("simlab/VisitLab-Nav-v0", {"variant": "paper"}),
    ("simlab/VisitLab-Nav-v0", {"layout": "lab", "layout_seed": 3, "goal": "random"}),
    ("simlab/VisitLab-Social-v0", {}),
    ("simlab/VisitLab-Social-v0", {"variant": "paper", "human": "H3"}),
    ("simlab/VisitLab-Social-v0", {"human": "hard", "layout": "paper", "human_start": "random"}),
    ("simlab/VisitLab-GoToHuman-v0", {}),
    ("simlab/VisitLab-GoToHuman-v0", {"episode": "fixed", "human": "medium"}),
    ("simlab/VisitLab-GoToHuman-v0", {"variant": "paper", "episode": "fixed_positions"}),
]


@pytest.mark.parametrize(("env_id", "kwargs"), ENV_CASES)
def test_check_env(env_id, kwargs):
    env = gym.make(env_id, render_mode="ansi", **kwargs)
    check_env(env.unwrapped)


def rollout(env, seed: int, actions) -> list:
    obs, info = env.reset(seed=seed)
    out = [(obs, info)]
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(int(a))
        out.append((obs, reward, terminated, truncated, info))
    return out


@pytest.mark.parametrize(("env_id", "kwargs"), ENV_CASES)
def test_same_seed_same_rollout(env_id, kwargs):
    env_a = gym.make(env_id, **kwargs)
    env_b = gym.make(env_id, **kwargs)
    actions = np.random.default_rng(0).integers(0, env_a.action_space.n, size=60)
    a = rollout(env_a, 11, actions)
    b = rollout(env_b, 11, actions)
    assert a == b
    c = rollout(env_a, 12, actions)
    # thesis navigation (fixed start and goal, deterministic moves) and the fixed go-to-human
    # episode with a still human have nothing random
    deterministic = kwargs.get("episode") == "fixed" and "human" not in kwargs
    deterministic |= env_id.endswith("Nav-v0") and not kwargs
    assert (c == a) == deterministic


def test_social_kernel_and_env_give_the_same_trajectory():
    env = SocialEnv(human="H3", redraw_p=0.2)
    actions = np.random.default_rng(1).integers(0, 30, size=200)
    obs0, _ = env.reset(seed=5)
    rng = np.random.default_rng(5)  # what reset(seed=5) uses
    st = dyn.new_state()
    lay = env.layout
    dyn.social_reset(st, rng, lay.n_cells, env.robot_start, env.human_start)
    los, pcfg, hp = lay.los_table(), env.perception.to_array(), env.human.to_array()
    assert dyn.social_obs(lay.walls_h, lay.walls_v, los, pcfg, st) == obs0
    for a in actions:
        obs, reward, *_ = env.step(int(a))
        r = dyn.social_step(lay.walls_h, lay.walls_v, los, pcfg, hp, 0.2, st, int(a), rng)
        assert (dyn.social_obs(lay.walls_h, lay.walls_v, los, pcfg, st), r) == (obs, reward)
        np.testing.assert_array_equal(st, env.world_state)


def test_social_obs_encodes_the_info():
    env = SocialEnv(human="medium")
    obs, info = env.reset(seed=3)
    rng = np.random.default_rng(0)
    seen_levels = set()
    for _ in range(300):
        assert obs == encode_social(info["interaction"], info["distance_class"],
                                    info["required_direction"], info["angle"])
        assert info["robot_cell"] != info["human_cell"]
        seen_levels.add(info["interaction"])
        a = int(rng.choice([Action.GO_TO_HUMAN, Action.LOOK_H, Action.HELLO, Action.COME,
                            Action.POINTING, int(rng.integers(0, 24))]))
        obs, reward, terminated, truncated, info = env.step(a)
        assert not terminated
        if reward:
            assert info["interaction"] == 7 and info["human_moved_required"]
        if truncated:
            obs, info = env.reset()
    assert seen_levels >= {0, 5}


def test_social_info_reports_moving_in_required_direction():
    env = SocialEnv(human="easy", robot_start=(20, 24), human_start="center", redraw_p=0.0)
    env.reset(seed=0)
    st = env._st  # put the scene in the level-7 configuration
    st[dyn.S_ROBOT_ORI] = 2
    st[dyn.S_HUMAN_ORI] = 3
    st[dyn.S_ENGAGED] = 7
    st[dyn.S_REQ_DIR] = 3  # RIGHT
    _, reward, _, _, info = env.step(int(Action.RIGHT))
    assert reward == 1.0 and info["human_moved"] == 3 and info["human_moved_required"]
    assert info["human_pos"] == (20, 21) and info["robot_pos"] == (20, 25)


def test_nav_thesis_optimal_trial_scores_45():
    env = NavEnv()
    obs, info = env.reset(seed=0)
    assert info["robot_cell"] == 0 and info["goal_label"] == 8 and obs == 8 * 576
    total, steps = 0.0, 0
    for a in [Action.DOWN_RIGHT3] * 5 + [Action.DOWN_RIGHT] + [Action.STAY] * 44:
        obs, r, terminated, truncated, info = env.step(int(a))
        total += r
        steps += 1
        assert truncated == (steps == 50) and not terminated
    assert info["robot_pos"] == (16, 16) and info["in_goal"]
    assert total == 45.0


def test_nav_paper_random_start_and_goal():
    env = NavEnv(variant="paper")
    goals, starts = set(), set()
    for seed in range(40):
        obs, info = env.reset(seed=seed)
        assert obs == info["robot_cell"] + info["goal_label"] * 576
        goals.add(info["goal_label"])
        starts.add(info["robot_cell"])
    assert len(goals) >= 7 and len(starts) >= 30
    assert env.max_steps == 20


def test_gth_episode_variants():
    fixed = GoToHumanEnv(episode="fixed")
    fixed_pos = GoToHumanEnv(episode="fixed_positions")
    rand = GoToHumanEnv(episode="random")
    first = [fixed.reset(seed=s)[1] for s in range(10)]
    assert all(i["robot_pos"] == (2, 2) and i["human_pos"] == (12, 12) for i in first)
    assert {(i["robot_orientation"], i["human_orientation"]) for i in first} == {(1, 0)}
    infos = [fixed_pos.reset(seed=s)[1] for s in range(20)]
    assert all(i["robot_pos"] == (2, 2) and i["human_pos"] == (12, 12) for i in infos)
    assert len({i["human_orientation"] for i in infos}) > 3
    infos = [rand.reset(seed=s)[1] for s in range(20)]
    assert len({i["human_cell"] for i in infos}) > 15


def test_gth_reward_in_facing_field_at_appropriate_distance():
    # the human faces UP
    env = GoToHumanEnv(episode="fixed", start=StartPoses(robot_cell=(7, 12), human_ori=0))
    obs, info = env.reset(seed=0)
    assert decode_gth(obs) == (0, 4, int(Action.DOWN))  # 5 cells above: too far
    obs, r, *_ , info = env.step(int(Action.DOWN))  # (8, 12): Manhattan 4, class 3
    assert r == 1.0 and info["in_facing_field"]
    obs, r, *_ , info = env.step(int(Action.DOWN2))  # (10, 12): Manhattan 2, class 1
    assert r == 1.0 and decode_gth(obs)[1] == 1
    obs, r, *_ , info = env.step(int(Action.DOWN))  # (11, 12): too close
    assert r == 0.0 and decode_gth(obs)[1] == 0
    obs, r, *_ , info = env.step(int(Action.RIGHT3))  # (11, 15): beside, not in facing field
    assert r == 0.0 and not info["h_looks_at_r"]


def test_renders_show_robot_human_and_walls():
    env = SocialEnv(layout="paper", human_start="random", render_mode="ansi")
    env.reset(seed=2)
    text = env.render()
    assert text.count("R") == 1 and text.count("H") == 1
    assert "+--+" in text and "level=" in text
    env = SocialEnv(render_mode="rgb_array")
    _, info = env.reset(seed=2)
    img = env.render()
    assert img.dtype == np.uint8 and img.shape == (41 * 20 + 1, 41 * 20 + 1, 3)
    for who, colour in (("robot", (220, 40, 40)), ("human", (40, 90, 220))):
        r, c = info[f"{who}_pos"]
        dr, dc = DIR_DELTA[info[f"{who}_orientation"]]
        # inside the disc, on the side opposite to the orientation line
        assert tuple(img[r * 20 + 10 - 4 * dr, c * 20 + 10 - 4 * dc]) == colour
    nav = NavEnv(render_mode="rgb_array")
    nav.reset(seed=0)
    img = nav.render()
    assert tuple(img[23 * 20 + 5, 23 * 20 + 5]) == (173, 216, 245)  # goal room tint


def test_bad_arguments_raise_config_errors():
    with pytest.raises(ConfigError, match="variant"):
        NavEnv(variant="book")
    with pytest.raises(ConfigError, match="human"):
        SocialEnv(human="sleepy")
    with pytest.raises(ConfigError, match="episode"):
        GoToHumanEnv(episode="sometimes")
    with pytest.raises(ConfigError, match="goal"):
        NavEnv(goal=42)
    with pytest.raises(ConfigError, match="human_start"):
        SocialEnv(human_start="corner")
    env = NavEnv()
    env.reset(seed=0)
    with pytest.raises(ConfigError, match="action"):
        env.step(25)


def test_reset_options_place_the_episode_and_only_that_episode() -> None:
    nav = NavEnv(variant="paper")
    goal = nav.layout.goal_labels[0]
    _, info = nav.reset(seed=0, options={"start": 5, "goal": goal})
    assert info["robot_cell"] == 5 and info["goal_label"] == goal
    _, info = nav.reset(seed=0, options={"start": (2, 3)})
    assert info["robot_cell"] == nav.layout.cell(2, 3)
    # without options the constructor's settings hold again (paper: random start)
    starts = {nav.reset(seed=s)[1]["robot_cell"] for s in range(6)}
    assert len(starts) > 1

    social = SocialEnv(variant="paper")
    _, info = social.reset(seed=1, options={"robot_start": 10, "human_start": 11})
    assert (info["robot_cell"], info["human_cell"]) == (10, 11)

    gth = GoToHumanEnv(episode="fixed")
    _, info = gth.reset(seed=2, options={"robot_cell": 30, "human_cell": 33, "robot_ori": 3,
                                         "human_ori": 2})
    assert (info["robot_cell"], info["human_cell"]) == (30, 33)
    assert (info["robot_orientation"], info["human_orientation"]) == (3, 2)


@pytest.mark.parametrize(("make", "options", "match"), [
    (lambda: NavEnv(), {"nosuch": 1}, "unknown reset option"),
    (lambda: NavEnv(), {"start": 10**9}, "options.start"),
    (lambda: SocialEnv(), {"human_start": "nowhere"}, "options.human_start"),
    (lambda: GoToHumanEnv(), {"robot_ori": 9}, "options.robot_ori"),
])
def test_bad_reset_options_name_the_key(make, options, match) -> None:
    with pytest.raises(ConfigError, match=match):
        make().reset(seed=0, options=options)


@pytest.mark.parametrize(("env_id", "limit"), [("simlab/VisitLab-Nav-v0", 50),
                                               ("simlab/VisitLab-Social-v0", 40),
                                               ("simlab/VisitLab-GoToHuman-v0", 40)])
def test_registered_limit_and_max_episode_steps_truncate(env_id, limit):
    env = gym.make(env_id)
    assert env.spec.max_episode_steps == limit
    assert env.unwrapped.max_steps is None  # the env's own limit is off
    for n in (limit, 7, limit + 13):  # the registered one, and overrides below and above
        env = gym.make(env_id, max_episode_steps=n)
        env.reset(seed=0)
        flags = [env.step(0)[3] for _ in range(n)]
        assert flags == [False] * (n - 1) + [True]


def test_env_without_own_limit_never_truncates_and_cannot_train():
    from simlab.visitlab.training import train

    env = NavEnv(max_steps=None)
    env.reset(seed=0)
    assert not any(env.step(24)[3] for _ in range(200))
    assert NavEnv(variant="paper").max_steps == 20 and NavEnv().max_steps == 50
    with pytest.raises(ConfigError, match="max_steps"):
        NavEnv(max_steps=0)
    with pytest.raises(ConfigError, match="trial length"):
        train("nav", "q-learning", trials=2, seeds=1, progress=False, max_steps=None)
