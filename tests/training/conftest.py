"""Shared fixtures: a small synthetic empirical MDP written as an ``mdp.npz``."""

from __future__ import annotations

import numpy as np
import pytest

from simlab.training.synthetic import synthetic_arena_mdp


@pytest.fixture(scope="session")
def arena_mdp():
    """The 41-state, 16-action synthetic stand-in for the table arena's empirical MDP."""
    return synthetic_arena_mdp(np.random.default_rng(0))


@pytest.fixture(scope="session")
def small_mdp():
    """A 12-state synthetic arena MDP (fast end-to-end runs)."""
    return synthetic_arena_mdp(np.random.default_rng(1), n_states=12, samples_per_pair=40,
                               goal_cells=1)  # fmt: skip


def write_mdp_npz(path, mdp, **drop_or_replace):
    """Write ``mdp`` in the ``simlab estimate`` layout; ``key=None`` drops an array."""
    arrays = {
        "T": mdp.T,
        "counts": mdp.counts,
        "visited": mdp.visited,
        "entropy": mdp.entropy,
        "centres": mdp.centres,
        "goal_names": np.array(mdp.goal_names),
        "goal_masks": mdp.goal_masks,
    }
    for key, value in drop_or_replace.items():
        if value is None:
            arrays.pop(key, None)
        else:
            arrays[key] = value
    np.savez_compressed(path, **arrays)
    return path


@pytest.fixture(scope="session")
def write_mdp():
    """The :func:`write_mdp_npz` helper (conftest modules are not importable)."""
    return write_mdp_npz


@pytest.fixture
def small_mdp_file(tmp_path, small_mdp):
    return write_mdp_npz(tmp_path / "mdp.npz", small_mdp)
