"""``simlab/EmpiricalMDP-v0``: API compliance, determinism, dynamics, rewards, bad input."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import simlab  # noqa: F401  (registers the environments)
from simlab.base.errors import ConfigError
from simlab.data.mdp import load_mdp
from simlab.envs.empirical_mdp import EmpiricalMDPEnv


def test_passes_the_gymnasium_env_checker(small_mdp_file):
    env = gym.make("simlab/EmpiricalMDP-v0", mdp=str(small_mdp_file), goal="g1")
    check_env(env.unwrapped, skip_render_check=True)
    assert env.observation_space == gym.spaces.Discrete(12)
    assert env.action_space == gym.spaces.Discrete(16)


def _rollout(env, seed, steps=120):
    obs, _ = env.reset(seed=seed)
    out = [obs]
    rng = np.random.default_rng(0)  # same action sequence for both envs
    for _ in range(steps):
        obs, r, term, trunc, _ = env.step(int(rng.integers(16)))
        out += [obs, r, term, trunc]
        if trunc:
            obs, _ = env.reset()
            out.append(obs)
    return out


def test_same_seed_same_rollout_different_seed_different(small_mdp):
    a = _rollout(EmpiricalMDPEnv(small_mdp, "g3"), 7)
    b = _rollout(EmpiricalMDPEnv(small_mdp, "g3"), 7)
    c = _rollout(EmpiricalMDPEnv(small_mdp, "g3"), 8)
    assert a == b
    assert a != c


def test_next_states_follow_T_and_reward_is_arrival_in_goal(arena_mdp):
    env = EmpiricalMDPEnv(arena_mdp, "g5", horizon=10**9)
    s, a, n = 20, 13, 20_000
    counts = np.zeros(arena_mdp.n_states)
    goal = arena_mdp.goal_mask("g5")
    env.reset(seed=0, options={"state": s})
    for _ in range(n):
        env.reset(options={"state": s})
        s2, r, term, trunc, info = env.step(a)
        counts[s2] += 1
        assert r == float(goal[s2]) and info["in_goal"] == goal[s2]
        assert not term and not trunc
    p = arena_mdp.T[s, a]
    assert counts[p == 0].sum() == 0
    se = np.sqrt(p * (1 - p) / n)
    assert np.all(np.abs(counts / n - p) <= 5 * se + 1e-12)


def test_episodes_are_truncated_after_the_horizon_and_start_uniformly(small_mdp):
    env = EmpiricalMDPEnv(small_mdp, "g1", horizon=50)
    starts = []
    env.reset(seed=3)
    for _ in range(600):
        s, _ = env.reset()
        starts.append(s)
        for t in range(50):
            _, _, term, trunc, _ = env.step(0)
            assert not term
            assert trunc == (t == 49)
    counts = np.bincount(starts, minlength=12)
    p = 1 / 12
    assert np.all(np.abs(counts / 600 - p) <= 5 * np.sqrt(p * (1 - p) / 600))


def test_fixed_start_and_goal_switch_by_reset_options(small_mdp):
    env = EmpiricalMDPEnv(small_mdp, "g1", start_state=4)
    assert env.reset(seed=0)[0] == 4
    s, info = env.reset(options={"goal": "g9", "state": 7})
    assert s == 7 and info["goal"] == "g9" and env.goal == "g9"
    np.testing.assert_array_equal(env.goal_mask, small_mdp.goal_mask("g9"))
    assert env.reset()[0] == 4  # the fixed start is back, the new goal stays
    assert env.goal == "g9"


def test_arrays_instead_of_a_file():
    T = np.zeros((3, 2, 3))
    T[:, 0, 1] = 1.0
    T[:, 1, 2] = 1.0
    env = EmpiricalMDPEnv(T=T, goal_mask=np.array([False, False, True]), start_state=0)
    env.reset(seed=0)
    assert env.step(0)[:2] == (1, 0.0)
    assert env.step(1)[:2] == (2, 1.0)


# --------------------------------------------------------------------------- bad input
def test_npz_without_T_is_a_clear_error(tmp_path, small_mdp, write_mdp):
    path = write_mdp(tmp_path / "m.npz", small_mdp, T=None)
    with pytest.raises(ConfigError) as err:
        load_mdp(path)
    assert "m.npz" in str(err.value) and "missing array(s) T" in str(err.value)


def test_rows_not_summing_to_one_name_file_array_and_row(tmp_path, small_mdp, write_mdp):
    T = small_mdp.T.copy()
    T[2, 5] *= 0.5
    path = write_mdp(tmp_path / "m.npz", small_mdp, T=T)
    with pytest.raises(ConfigError) as err:
        EmpiricalMDPEnv(str(path), "g1")
    msg = str(err.value)
    assert "m.npz" in msg and "T[2, 5, :]" in msg and "sums to 0.5" in msg
    assert err.value.key == "T"


def test_unknown_goal_lists_the_valid_goals(small_mdp_file):
    with pytest.raises(ConfigError, match=r"unknown goal 'kitchen'; valid goals: g1, g2, .*g9"):
        EmpiricalMDPEnv(str(small_mdp_file), "kitchen")
    with pytest.raises(ConfigError, match="no goal given; valid goals: g1"):
        EmpiricalMDPEnv(str(small_mdp_file))


def test_goal_name_without_goal_arrays(tmp_path, small_mdp, write_mdp):
    path = write_mdp(tmp_path / "m.npz", small_mdp, goal_names=None, goal_masks=None)
    with pytest.raises(ConfigError, match="has no goal areas"):
        EmpiricalMDPEnv(str(path), "g1")


def test_inconsistent_goal_arrays(tmp_path, small_mdp, write_mdp):
    path = write_mdp(tmp_path / "m.npz", small_mdp, goal_masks=np.ones((9, 5), bool))
    with pytest.raises(ConfigError, match=r"goal_masks: expected shape \(G, S\) = \(9, 12\)"):
        load_mdp(path)


def test_env_exposes_the_action_set_and_the_mask(tmp_path) -> None:
    import json

    from simlab.base.actions import SIMLAB16, parse_action_set
    from simlab.data.mdp import load_mdp
    from simlab.envs.empirical_mdp import EmpiricalMDPEnv

    T = np.zeros((2, 8, 2))
    T[:, :, 0] = 1.0
    visited = np.ones((2, 8), bool)
    visited[0, 3] = False
    meta = {"action_set": parse_action_set(8, "ccw-east").to_json(), "unvisited": "mask"}
    np.savez(tmp_path / "m.npz", T=T, visited=visited, goal_names=np.array(["g"]),
             goal_masks=np.array([[False, True]]), meta_json=np.array(json.dumps(meta)))
    env = EmpiricalMDPEnv(tmp_path / "m.npz", goal="g")
    assert env.action_space.n == 8 and env.action_set.convention == "ccw-east"
    np.testing.assert_array_equal(env.valid_actions, visited)
    meta["unvisited"] = "self-loop"
    np.savez(tmp_path / "s.npz", T=T, visited=visited, meta_json=np.array(json.dumps(meta)))
    assert load_mdp(tmp_path / "s.npz").valid is None
    # Old 16-action files: simlab's primitives; other sizes without a record: unknown.
    np.savez(tmp_path / "o.npz", T=np.full((2, 16, 2), 0.5))
    assert load_mdp(tmp_path / "o.npz").action_set == SIMLAB16
    np.savez(tmp_path / "u.npz", T=T)
    assert load_mdp(tmp_path / "u.npz").action_set is None


def test_text_render_shows_the_step_and_only_a_limit_that_is_the_envs(small_mdp_file,
                                                                       small_mdp):
    # the registered id leaves the limit to Gymnasium's TimeLimit: no "/None"
    registered = gym.make("simlab/EmpiricalMDP-v0", mdp=str(small_mdp_file), goal="g1",
                          render_mode="ansi")
    registered.reset(seed=0, options={"state": 3})
    s, *_ = registered.step(0)
    assert registered.render() == f"t=1 state={s} goal=g1\n"
    own = EmpiricalMDPEnv(small_mdp, "g1", horizon=12, render_mode="ansi")
    own.reset(seed=0, options={"state": 3})
    assert own.render() == "t=0/12 state=3 goal=g1\n"
