"""Deep-RL readiness of the envs (issue 15): finite bounded observations, safe copies,
closed envs, registered episode limits, rgb_array rendering, the Voronoi-state physics env."""

from __future__ import annotations

import copy
import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.error import ClosedEnvironmentError
from gymnasium.utils.env_checker import check_env

import simlab  # noqa: F401  (registers the environments)
from discretize.voronoi import Discretizer
from simlab.base.errors import ConfigError
from simlab.envs.table_arena import finite_scan, rep117_scan


def test_finite_and_rep117_scan_conversions() -> None:
    ranges = np.array([0.5, np.inf, 3.4, np.inf])
    r, valid = finite_scan(ranges, 3.5)
    assert r.dtype == np.float32 and r.tolist() == [np.float32(0.5), 3.5, np.float32(3.4), 3.5]
    assert valid.tolist() == [1, 0, 1, 0]
    raw = rep117_scan(np.array([0.11, 0.5, 3.6, 3.5]), np.array([True, True, True, False]),
                      0.12, 3.5)
    assert raw.tolist() == [-np.inf, np.float32(0.5), np.inf, np.inf]


@pytest.mark.slow
def test_observations_finite_and_inside_the_space_over_2000_random_steps() -> None:
    env = gym.make("simlab/TableArena-v0", arena="table_obstacles",
                   max_episode_steps=500).unwrapped
    space = env.observation_space
    assert all(np.isfinite(b.low).all() and np.isfinite(b.high).all()
               for b in (space["pose"], space["lidar"]))
    obs, _ = env.reset(seed=0)
    env.action_space.seed(0)
    invalid = 0
    for _ in range(2000):
        obs, *_ = env.step(env.action_space.sample())
        assert space.contains(obs)
        assert np.isfinite(obs["lidar"]).all()
        invalid += int((obs["lidar_valid"] == 0).sum())
    env.close()
    # the obstacle arena is closed: beams that miss are rare, and read range_max
    assert invalid < 2000 * 360 * 0.05


def test_raw_lidar_mode_keeps_rep117_infinities() -> None:
    env = gym.make("simlab/TableArena-v0", lidar_mode="raw").unwrapped
    obs, _ = env.reset(seed=0, options={"pose": (0.0, 0.0, 0.0)})
    assert env.observation_space.contains(obs) and "lidar_valid" not in obs
    finite = gym.make("simlab/TableArena-v0").unwrapped
    fobs, _ = finite.reset(seed=0, options={"pose": (0.0, 0.0, 0.0)})
    # the same noise stream: finite readings agree beam by beam
    ok = np.isfinite(obs["lidar"])
    assert ok.sum() > 300
    np.testing.assert_array_equal(obs["lidar"][ok], fobs["lidar"][ok])
    assert (fobs["lidar_valid"].astype(bool) == ok).all()
    with pytest.raises(ConfigError, match="lidar_mode"):
        gym.make("simlab/TableArena-v0", lidar_mode="clipped")
    env.close()
    finite.close()


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_copies_are_independent_worlds(how: str) -> None:
    env = gym.make("simlab/TableArena-v0").unwrapped
    env.reset(seed=3, options={"pose": (0.0, 0.0, np.pi / 2)})
    other = copy.deepcopy(env) if how == "deepcopy" else pickle.loads(pickle.dumps(env))
    assert other.world.client is not env.world.client
    before = env.world.pose()
    np.testing.assert_allclose(other.world.pose(), before, atol=1e-9)
    other.step(9)  # fast DOWN: the copy moves ...
    assert np.linalg.norm(other.world.pose()[:2] - before[:2]) > 0.05
    np.testing.assert_array_equal(env.world.pose(), before)  # ... the original does not
    del other  # collecting the copy must not disconnect the original
    obs, *_ = env.step(9)
    assert np.linalg.norm(obs["pose"][:2] - before[:2]) > 0.05
    env.close()


def test_copy_after_reset_continues_the_same_rollout() -> None:
    # a fresh world at the same pose, same goal and same RNG state: identical physics (a copy
    # taken mid-episode starts at rest, so the robot's residual motion is not copied)
    env = gym.make("simlab/TableArena-v0").unwrapped
    env.reset(seed=5)
    twin = copy.deepcopy(env)
    assert twin.goal == env.goal
    for a in (11, 4, 8):
        o1, r1, *_ = env.step(a)
        o2, r2, *_ = twin.step(a)
        np.testing.assert_array_equal(o1["lidar"], o2["lidar"])
        np.testing.assert_array_equal(o1["pose"], o2["pose"])
        assert r1 == r2
    env.close()
    twin.close()


def test_use_after_close_raises_a_clear_error() -> None:
    env = gym.make("simlab/TableArena-v0").unwrapped
    env.reset(seed=0)
    env.close()
    env.close()  # idempotent
    for call in (lambda: env.step(0), lambda: env.reset(seed=0), env.render):
        with pytest.raises(ClosedEnvironmentError, match="closed"):
            call()


def test_registered_episode_limits_are_honoured(small_mdp) -> None:
    assert gym.spec("simlab/TableArena-v0").max_episode_steps == 50
    assert gym.spec("simlab/EmpiricalMDP-v0").max_episode_steps == 50
    env = gym.make("simlab/EmpiricalMDP-v0", mdp=small_mdp, goal="g1",
                   max_episode_steps=7)
    for n in (7, 7):
        env.reset(seed=0)
        steps, trunc = 0, False
        while not trunc:
            *_, trunc, _ = env.step(0)
            steps += 1
        assert steps == n
    long = gym.make("simlab/EmpiricalMDP-v0", mdp=small_mdp, goal="g1",
                    max_episode_steps=120)
    long.reset(seed=0)
    truncs = [long.step(0)[3] for _ in range(120)]
    assert truncs == [False] * 119 + [True]  # no hidden 50-step limit inside
    arena = gym.make("simlab/TableArena-v0", max_episode_steps=3)
    arena.reset(seed=0)
    assert [arena.step(0)[3] for _ in range(3)] == [False, False, True]
    arena.close()


def test_empirical_mdp_rgb_array_render(small_mdp) -> None:
    env = gym.make("simlab/EmpiricalMDP-v0", mdp=small_mdp, goal="g1",
                   render_mode="rgb_array")
    assert env.metadata["render_fps"] > 0
    env.reset(seed=0)
    image = env.render()
    assert image.dtype == np.uint8 and image.shape == (256, 256, 3)
    red = (image == np.array([220, 40, 40], dtype=np.uint8)).all(axis=2)
    assert red.any()  # the current state is drawn
    env.step(1)
    assert env.render().shape == (256, 256, 3)


def _lattice() -> Discretizer:
    g = np.linspace(-0.6, 0.6, 5)
    return Discretizer(centres=np.array([(x, y) for y in g[::-1] for x in g]))


def test_states_env_observes_voronoi_states_with_the_goal_reward() -> None:
    disc = _lattice()
    env = gym.make("simlab/TableArenaStates-v0", states=disc, goal="C")
    check_env(env.unwrapped, skip_render_check=True)
    s, info = env.reset(seed=0, options={"pose": (0.0, 0.0, np.pi / 2)})
    assert env.observation_space == gym.spaces.Discrete(25)
    assert s == 12 and s == int(disc.state_of(info["pose"][:2]))
    assert env.unwrapped.goal_masks[env.unwrapped.goal_names.index("C"), 12]
    s2, r, term, trunc, info = env.step(0)  # slow UP
    assert s2 == int(disc.state_of(info["pose"][:2]))
    assert r == float(env.unwrapped.goal_masks[env.unwrapped.goal_names.index("C"), s2])
    assert not term and not trunc
    clone = pickle.loads(pickle.dumps(env.unwrapped))
    assert clone.discretizer.n_states == 25 and clone.observation_space.n == 25
    clone.close()
    env.close()


def test_states_env_takes_the_action_set_of_a_q_table(tmp_path) -> None:
    from simlab.agents.storage import save_q_table
    from simlab.base.actions import parse_action_set

    aset = parse_action_set(8, "ccw-east")
    path = tmp_path / "q.npz"
    save_q_table(path, np.zeros((25, 8)), metadata={"action_set": aset.to_json()})
    env = gym.make("simlab/TableArenaStates-v0", states=_lattice(), q_table=path, goal="C")
    assert env.action_space.n == 8 and env.unwrapped.action_set == aset
    env.close()
    with pytest.raises(ConfigError, match="states"):
        gym.make("simlab/TableArenaStates-v0")
