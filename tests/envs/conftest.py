"""Fixtures of the env tests: a small synthetic empirical MDP as an object."""

from __future__ import annotations

import numpy as np
import pytest

from simlab.data.mdp import EmpiricalMDP
from simlab.training.synthetic import synthetic_arena_mdp


@pytest.fixture(scope="session")
def small_mdp() -> EmpiricalMDP:
    """A 12-state synthetic arena MDP with goal areas g0.. (fast)."""
    return synthetic_arena_mdp(np.random.default_rng(1), n_states=12, samples_per_pair=40,
                               goal_cells=1)
