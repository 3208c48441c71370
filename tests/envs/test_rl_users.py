"""What RL users meet first: the goal-conditioned TableArena, REP 117 "too close" beams,
the ``simlab:``-prefixed ids in spawned workers, the env cards in ``help()`` and the card's
Q-table recipe acting on tried actions only."""

from __future__ import annotations

import importlib
import math
import pydoc
import re
import textwrap
from functools import partial
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import simlab  # noqa: F401  (registers the environments)
from simlab.agents import greedy, save_q_table
from simlab.base.errors import ConfigError
from simlab.envs import ENV_ENTRY_POINTS
from simlab.envs.table_arena import rep117_scan
from simlab.envs.table_states import TableArenaStatesEnv


def test_goal_conditioned_table_arena_passes_check_env_and_shows_the_goal() -> None:
    env = gym.make("simlab/TableArena-v0", goal_conditioned=True, max_steps=5)
    check_env(env.unwrapped, skip_render_check=True)
    arena = env.unwrapped.arena
    seen = set()
    for seed in range(12):
        obs, info = env.reset(seed=seed)
        goal = arena.goal(info["goal"])
        np.testing.assert_array_equal(obs["desired_goal"], np.float32([goal.x, goal.y]))
        np.testing.assert_array_equal(obs["achieved_goal"], obs["pose"][:2])
        assert env.observation_space.contains(obs)
        seen.add(info["goal"])
    assert len(seen) > 1  # the goal drawn each episode is what the observation shows
    with pytest.raises(ConfigError, match="goal_conditioned"):
        gym.make("simlab/TableArena-v0", goal_conditioned="yes")
    env.close()


def test_compute_reward_equals_the_step_reward_and_is_vectorised() -> None:
    env = gym.make("simlab/TableArena-v0", goal_conditioned=True, goal="C").unwrapped
    centre = env.arena.goal("C")
    # start inside the centre goal, then drive out of it: rewards 1 ... then 0
    obs, _ = env.reset(seed=1, options={"pose": (centre.x, centre.y, 0.0)})
    rewards = []
    for _ in range(6):
        obs, r, *_ = env.step(8)  # fast UP
        assert env.compute_reward(obs["achieved_goal"], obs["desired_goal"], {}) == r
        rewards.append(r)
    assert rewards[0] == 1.0 and rewards[-1] == 0.0
    # hand case: achieved points at 0, r and 2r from a goal centre
    g = env.arena.goals[0]
    d = np.array([[g.x, g.y]] * 3)
    a = d + np.array([[0.0, 0.0], [g.radius, 0.0], [0.0, 2 * g.radius]])
    np.testing.assert_array_equal(env.compute_reward(a, d, None), [1.0, 1.0, 0.0])
    env.close()


def test_rep117_marks_near_surfaces_too_close() -> None:
    raw = rep117_scan(np.array([0.12, 0.5, 0.3]), np.array([False, True, False]), 0.12, 3.5,
                      near=np.array([True, True, False]))
    assert raw.tolist() == [-np.inf, np.float32(0.5), np.inf]  # near only counts without a hit


def test_raw_lidar_against_a_wall_reads_minus_inf_where_it_is_too_close() -> None:
    env = gym.make("simlab/TableArena-v0", lidar_mode="raw").unwrapped
    spec, offset = env.world.lidar_spec, env.world.robot_spec.lidar_offset[0]
    wall = env.arena.bounds[2]  # inner face of the east wall, x (m)
    gap = 0.10  # sensor centre to the wall (m), less than range_min (0.12 m)
    obs, _ = env.reset(seed=0, options={"pose": (wall - gap - offset, 0.0, 0.0)})
    lidar = obs["lidar"]
    theta = spec.angles  # beam 0 faces the wall (+x)
    with np.errstate(divide="ignore"):
        to_wall = np.where(np.cos(theta) > 0, gap / np.cos(theta), np.inf)  # (n,) m
    assert (to_wall < spec.range_min).sum() > 20
    # a wall nearer than range_min: "too close", never "nothing in range"
    assert np.isneginf(lidar[to_wall < spec.range_min - 0.005]).all()
    assert not np.isposinf(lidar).any()  # the table arena is closed: every beam meets a wall
    # beams whose wall lies well beyond range_min read finite ranges
    assert np.isfinite(lidar[(to_wall > spec.range_min + 6 * spec.noise_sigma)
                             & (np.cos(theta) > 0.5)]).all()
    # facing away, the sensor still sees the far wall at 2 * half-width - gap
    assert lidar[180] == pytest.approx(wall - env.arena.bounds[0] - gap, abs=5 * spec.noise_sigma)
    env.close()


def test_raw_lidar_in_the_open_has_no_minus_inf() -> None:
    env = gym.make("simlab/TableArena-v0", lidar_mode="raw").unwrapped
    obs, _ = env.reset(seed=0, options={"pose": (0.0, 0.0, 0.3)})
    assert np.isfinite(obs["lidar"]).all()
    env.close()


def _first_obs(env_id: str, **kwargs: object) -> object:
    env = gym.make(env_id, **kwargs)
    obs, _ = env.reset(seed=5)
    return obs


def test_spawned_vector_env_workers_find_the_prefixed_id() -> None:
    # the spawned workers start a fresh interpreter: "simlab:" makes gym.make import simlab
    env_id = "simlab:simlab/VisitLab-Nav-v0"
    fns = [partial(gym.make, env_id, max_episode_steps=10) for _ in range(2)]
    venv = gym.vector.AsyncVectorEnv(fns, context="spawn")
    try:
        obs, _ = venv.reset(seed=[5, 6])
        for _ in range(3):
            obs, rewards, *_ = venv.step(np.array([0, 1]))
    finally:
        venv.close()
    sync = gym.vector.SyncVectorEnv(fns)
    sobs, _ = sync.reset(seed=[5, 6])
    for _ in range(3):
        sobs, srewards, *_ = sync.step(np.array([0, 1]))
    sync.close()
    np.testing.assert_array_equal(obs, sobs)
    np.testing.assert_array_equal(rewards, srewards)


@pytest.mark.parametrize("env_id", sorted(ENV_ENTRY_POINTS))
def test_help_on_the_unwrapped_env_shows_its_card(env_id: str) -> None:
    module, name = ENV_ENTRY_POINTS[env_id].split(":")
    cls = getattr(importlib.import_module(module), name)
    text = pydoc.render_doc(cls, renderer=pydoc.plaintext)  # what help(env.unwrapped) prints
    for field in ("**Observation", "**Reward", "**Action"):
        assert field in text, (env_id, field)
    if not env_id.startswith("simlab/VisitLab"):  # the physics and empirical envs
        assert f"simlab:{env_id}" in text and "**Episode**" in text


def test_card_recipe_runs_the_masked_greedy_policy(tmp_path: Path) -> None:
    # a 25-state lattice; action 8 (fast UP) was never tried anywhere and keeps the
    # optimistic initial value 10.0, the best real action is 1 (slow DOWN)
    g = np.linspace(-0.6, 0.6, 5)
    centres = np.array([(x, y) for y in g[::-1] for x in g])
    (tmp_path / "states.txt").write_text("".join(f"{x} {y}\n" for x, y in centres))
    Q = np.zeros((25, 16))
    Q[:, 1] = 1.0
    Q[:, 8] = 10.0
    valid = np.ones((25, 16), dtype=bool)
    valid[:, 8] = False
    (tmp_path / "q" / "table").mkdir(parents=True)
    save_q_table(tmp_path / "q" / "table" / "q_NE.npz", Q, arrays={"valid": valid},
                 metadata={"unvisited": "mask"})
    code = re.search(r"::\n\n(.*?)\n\n    Use", TableArenaStatesEnv.__doc__, re.S).group(1)
    code = textwrap.dedent(code).replace('"states.json"', '"states.txt"')
    code = code.replace("gym.make(", "gym.make(max_episode_steps=3, id=")
    actions: list[int] = []
    scope = {"__name__": "recipe"}
    import os

    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        exec(compile(code.replace("env.step(int(policy[s]))",
                                  "env.step(actions.append(int(policy[s])) or actions[-1])"),
                     "recipe", "exec"), {**scope, "actions": actions})
    finally:
        os.chdir(cwd)
    assert actions == [1, 1, 1]  # the masked argmax, never the untried action 8
    assert greedy(Q).tolist() == [8] * 25  # what Q[s].argmax() would have done
    assert math.isclose(float(Q[0, greedy(Q, valid)[0]]), 1.0)
