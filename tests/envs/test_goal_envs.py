"""Only goal-conditioned envs look like goal envs: Stable-Baselines3 (and HER) take any env
with a ``compute_reward`` method for a ``GoalEnv``, so a plain env must not have one.

Every registered env is checked twice: the property itself (no ``compute_reward`` unless
goal-conditioned), which needs nothing extra, and Stable-Baselines3's own ``check_env``
when SB3 is installed (it pulls in PyTorch, so the suite does not require it).
"""

from __future__ import annotations

import copy
import pickle
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import simlab  # noqa: F401  (registers the environments)
from simlab.envs import ENV_ENTRY_POINTS
from simlab.envs.table_arena import GoalTableArenaEnv, TableArenaEnv

_CENTRES = [[x, y] for y in (0.4, 0.0, -0.4) for x in (-0.4, 0.0, 0.4)]


def _kwargs(env_id: str, tmp_path: Path) -> dict[str, object]:
    """The fewest arguments that build ``env_id``."""
    if env_id == "simlab/TableArenaStates-v0":
        return {"states": _CENTRES}
    if env_id == "simlab/EmpiricalMDP-v0":
        from simlab.training.synthetic import synthetic_arena_mdp

        return {"mdp": synthetic_arena_mdp(np.random.default_rng(1), n_states=12,
                                           samples_per_pair=40, goal_cells=1), "goal": "g1"}
    return {}


@pytest.mark.parametrize("env_id", sorted(ENV_ENTRY_POINTS))
def test_only_goal_conditioned_envs_have_compute_reward(env_id: str, tmp_path: Path) -> None:
    env = gym.make(env_id, **_kwargs(env_id, tmp_path))
    try:
        assert not hasattr(env.unwrapped, "compute_reward"), env_id
        assert "desired_goal" not in getattr(env.observation_space, "spaces", {})
    finally:
        env.close()


def test_goal_conditioned_table_arena_is_the_goal_env_and_stays_one_through_copies() -> None:
    env = gym.make("simlab/TableArena-v0", goal_conditioned=True)
    goal_env = env.unwrapped
    assert isinstance(goal_env, GoalTableArenaEnv) and hasattr(goal_env, "compute_reward")
    for clone in (copy.deepcopy(goal_env), pickle.loads(pickle.dumps(goal_env))):
        assert isinstance(clone, GoalTableArenaEnv) and clone.goal_conditioned
        clone.close()
    env.close()
    direct = GoalTableArenaEnv()
    assert {"achieved_goal", "desired_goal"} <= set(direct.observation_space.spaces)
    direct.close()
    plain = TableArenaEnv()
    assert type(plain) is TableArenaEnv and not plain.goal_conditioned
    plain.close()


def test_the_goal_env_steps_at_the_default_rate_like_the_plain_one() -> None:
    """Built directly, with gym.make or asked for a rate, the goal env's world steps where the
    plain env's does (its own default once said 200 Hz when every world went to 50 Hz)."""
    from simlab.physics.rate import DEFAULT_HZ

    for env in (GoalTableArenaEnv(), TableArenaEnv(goal_conditioned=True), TableArenaEnv()):
        assert env.world is not None and env.world.physics_hz == DEFAULT_HZ
        env.close()
    asked = GoalTableArenaEnv(physics_hz=100)
    assert asked.world is not None and asked.world.physics_hz == 100
    asked.close()


def test_the_goal_env_takes_every_option_of_the_plain_one_with_its_default() -> None:
    """The goal env spells out the plain env's signature (typed options for its users), so a
    default changed on one side only would drift silently, as the rate once did: every
    parameter must agree but goal_conditioned's default."""
    import inspect

    plain = inspect.signature(TableArenaEnv.__init__).parameters
    goal = inspect.signature(GoalTableArenaEnv.__init__).parameters
    assert list(plain) == list(goal)
    for name in plain:
        a, b = plain[name], goal[name]
        assert (a.kind, a.annotation) == (b.kind, b.annotation), name
        if name != "goal_conditioned":
            assert a.default == b.default, name
    assert plain["goal_conditioned"].default is False and goal["goal_conditioned"].default


@pytest.mark.parametrize("env_id", sorted(ENV_ENTRY_POINTS))
def test_every_registered_env_passes_stable_baselines3_check_env(env_id: str,
                                                                 tmp_path: Path) -> None:
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = gym.make(env_id, **_kwargs(env_id, tmp_path))
    try:
        sb3_checker.check_env(env.unwrapped, warn=False, skip_render_check=True)
    finally:
        env.close()


def test_the_goal_conditioned_table_arena_passes_stable_baselines3_check_env() -> None:
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = gym.make("simlab/TableArena-v0", goal_conditioned=True)
    try:
        sb3_checker.check_env(env.unwrapped, warn=False, skip_render_check=True)
    finally:
        env.close()
