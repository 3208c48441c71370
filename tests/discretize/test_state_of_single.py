"""Issue 17: ``state_of`` of one pose (brute force in floats) is the cKDTree's answer,
ties on cell boundaries included (there the tree decides)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from discretize.voronoi import Discretizer


def _one_by_one(disc: Discretizer, pts: np.ndarray) -> np.ndarray:
    return np.array([int(disc.state_of(p)) for p in pts])


def _tree(disc: Discretizer, pts: np.ndarray) -> np.ndarray:
    return disc._tree.query(pts)[1]  # the reference: what state_of always returned


@pytest.mark.parametrize("kind", ["lattice", "random"])
def test_single_pose_is_the_tree_answer(kind: str) -> None:
    rng = np.random.default_rng(11)
    if kind == "lattice":  # exact bisectors and 4-way vertices everywhere
        g = np.arange(-3, 4) * 0.2
        centres = np.array(list(itertools.product(g, g)))[:41]
    else:
        centres = rng.uniform(-0.7, 0.7, (41, 2))
    disc = Discretizer(centres)
    pairs = np.array(list(itertools.combinations(range(len(centres)), 2)))
    mids = (centres[pairs[:, 0]] + centres[pairs[:, 1]]) / 2  # equidistant from two
    pts = np.concatenate([rng.uniform(-1.5, 1.5, (20_000, 2)), centres, mids,
                          np.round(rng.uniform(-0.8, 0.8, (5_000, 2)), 1)])
    assert np.array_equal(_one_by_one(disc, pts), _tree(disc, pts))


def test_single_pose_shapes_and_errors() -> None:
    disc = Discretizer(np.array([[0.0, 0.0], [1.0, 0.0]]))
    assert disc.state_of(np.array([0.9, 0.1, 3.0])).shape == ()
    assert disc.state_of(np.array([[0.9, 0.1]])).tolist() == [1]
    assert disc.state_of(np.array([[[0.2, 5.0]]])).shape == (1, 1)
    assert int(disc.state_of(np.array([0.5, 0.3]))) == _tree(disc, np.array([[0.5, 0.3]]))[0]
    with pytest.raises(ValueError, match="finite"):
        disc.state_of(np.array([np.nan, 0.0]))
