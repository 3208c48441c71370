"""simlab/TableArena-v0: the Gymnasium contract, determinism, reward and rendering."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import simlab  # noqa: F401  (registers the environments)
from simlab.base.errors import ConfigError


@pytest.mark.filterwarnings("ignore:.*maximum value is infinity")  # inf = no return (REP 117)
def test_check_env_passes():
    env = gym.make("simlab/TableArena-v0", max_steps=5)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


def test_same_seed_same_rollout():
    def rollout(seed):
        env = gym.make("simlab/TableArena-v0", max_steps=12)
        obs, info = env.reset(seed=seed)
        env.action_space.seed(seed)
        out = [obs["pose"], obs["lidar"]]
        rewards, goal = [], info["goal"]
        done = False
        while not done:
            obs, r, term, trunc, info = env.step(env.action_space.sample())
            out += [obs["pose"], obs["lidar"]]
            rewards.append(r)
            done = term or trunc
        env.close()
        return np.concatenate(out), rewards, goal

    a, b, c = rollout(3), rollout(3), rollout(4)
    np.testing.assert_array_equal(a[0], b[0])
    assert a[1:] == b[1:]
    assert not np.array_equal(a[0], c[0])
    assert len(a[1]) == 12


def test_reward_is_one_inside_the_goal_area_only():
    env = gym.make("simlab/TableArena-v0", max_steps=50)
    env.reset(seed=0, options={"goal": "C", "pose": (0.0, 0.0, np.pi / 2)})
    # fast steps UP (0.11 m each) leave the 0.15 m goal circle at the second step
    rewards = [env.step(8)[1] for _ in range(3)]
    assert rewards == [1.0, 0.0, 0.0]
    obs, info = env.reset(seed=0, options={"goal": "NE"})
    assert info["goal"] == "NE"
    assert env.observation_space.contains(obs)
    env.close()


def test_render_and_bad_arguments():
    env = gym.make("simlab/TableArena-v0", render_mode="rgb_array")
    env.reset(seed=1)
    env.step(9)
    image = env.render()
    assert image.dtype == np.uint8 and image.ndim == 3 and image.shape[2] == 3
    assert image.shape[0] > 300 and image.shape[1] > 300
    with pytest.raises(ValueError, match="action"):
        env.step(16)
    env.close()
    with pytest.raises(ConfigError, match="unknown goal 'Z'"):
        gym.make("simlab/TableArena-v0", goal="Z")


def test_action_set_option_renumbers_the_primitives() -> None:
    from simlab.base.actions import parse_action_set

    aset = parse_action_set(8, "ccw-east")
    env = gym.make("simlab/TableArena-v0", max_steps=3, action_set=aset.to_json()).unwrapped
    assert env.action_space.n == 8 and env.action_set == aset
    obs, _ = env.reset(seed=0, options={"pose": (0.0, 0.0, 0.0)})
    x0, y0 = obs["pose"][:2]
    obs, _, _, _, info = env.step(2)  # ccw-east 2 = North = simlab UP, slow
    assert info["primitive"] == 0 and not info["blocked"]
    dx, dy = obs["pose"][0] - x0, obs["pose"][1] - y0
    assert dy > 0.03 and abs(dx) < 0.2 * dy
    with pytest.raises(ValueError):
        env.step(8)
    env.close()
