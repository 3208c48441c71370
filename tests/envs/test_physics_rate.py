"""Every physics env id takes ``physics_hz``: its world steps at the rate given, and a rate
outside the physics' range is refused by every one of them."""

from __future__ import annotations

import copy
import importlib
import inspect

import gymnasium as gym
import numpy as np
import pytest

import simlab  # noqa: F401  (registers the ids)
from simlab.base.errors import ConfigError
from simlab.envs import ENV_ENTRY_POINTS, PHYSICS_ENV_IDS
from simlab.physics.rate import MAX_HZ

#: What each id needs besides the rate.
_NEEDS = {"simlab/TableArenaStates-v0": lambda: {
    "states": [(x, y) for y in np.linspace(-0.6, 0.6, 3) for x in np.linspace(-0.6, 0.6, 3)]}}


def _world(env: gym.Env):
    inner = env.unwrapped
    return inner.world if hasattr(inner, "world") else inner.task.world


def test_the_physics_ids_are_every_env_that_builds_a_world() -> None:
    """An env class whose module builds a PyBullet world (or a social table) is listed."""
    for env_id, entry in ENV_ENTRY_POINTS.items():
        module, name = entry.split(":")
        cls = getattr(importlib.import_module(module), name)
        source = "".join(inspect.getsource(c) for c in cls.__mro__
                         if c.__module__.startswith("simlab"))
        builds = "World(" in source or "SocialTable(" in source
        assert builds == (env_id in PHYSICS_ENV_IDS), env_id


@pytest.mark.parametrize("env_id", PHYSICS_ENV_IDS)
def test_every_physics_env_steps_at_the_rate_given_and_its_copies_too(env_id: str) -> None:
    env = gym.make(env_id, physics_hz=100.0, **_NEEDS.get(env_id, dict)())
    try:
        assert _world(env).physics_hz == 100.0
        env.reset(seed=0)
        twin = copy.deepcopy(env.unwrapped)
        assert _world(twin).physics_hz == 100.0
        twin.close()
    finally:
        env.close()


@pytest.mark.parametrize("env_id", PHYSICS_ENV_IDS)
def test_every_physics_env_refuses_a_rate_outside_the_range(env_id: str) -> None:
    with pytest.raises(ConfigError, match="physics_hz"):
        gym.make(env_id, physics_hz=MAX_HZ * 10, **_NEEDS.get(env_id, dict)())
