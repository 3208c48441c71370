"""The robot's own cell labels against the states file: a moved centre is found where it was
moved, a deleted one is named and not moved, agreeing labels list nothing."""

from __future__ import annotations

import numpy as np
import pytest

from discretize.voronoi import Discretizer
from simlab.base.errors import ConfigError
from simlab.data.cellcheck import check_cell_column

CENTRES = np.array([[x, y] for y in (2.0, 1.0, 0.0) for x in (0.0, 1.0, 2.0, 3.0)])


def _poses(n: int = 6000, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform([-0.4, -0.4], [3.4, 2.4], (n, 2))


def _nearest(xy: np.ndarray, centres: np.ndarray) -> np.ndarray:
    return Discretizer(centres=centres).state_of(xy)


def test_labels_that_agree_list_nothing() -> None:
    xy = _poses()
    chk = check_cell_column(xy, _nearest(xy, CENTRES), CENTRES)
    assert chk.agreement == 1.0 and chk.agreement_fitted == 1.0 and chk.states == ()
    assert chk.samples == len(xy)


def test_moved_centres_are_found_where_they_were_moved() -> None:
    xy = _poses()
    robot = CENTRES.copy()
    robot[5] += (0.10, -0.14)  # a multiple of the grid step: found exactly
    robot[10] += (-0.06, 0.0)
    cell = _nearest(xy, robot)
    chk = check_cell_column(xy, cell, CENTRES)
    assert chk.agreement == pytest.approx(np.mean(cell == _nearest(xy, CENTRES)))
    assert chk.agreement < 1.0
    # the larger move disagrees on more samples: it comes first
    assert [f.state for f in chk.states] == [5, 10]
    for f in chk.states:
        assert f.fitted is not None
        np.testing.assert_allclose(f.fitted, robot[f.state], atol=1e-9)
        np.testing.assert_allclose(f.centre, CENTRES[f.state])
        assert 0 < f.disagree <= f.samples
    np.testing.assert_allclose(chk.states[0].shift, (0.10, -0.14), atol=1e-9)
    assert chk.agreement_fitted == 1.0
    text = "\n".join(chk.lines())
    assert "+0.10 m in x and -0.14 m in y" in text and "centres of 5, 10 moved" in text


def test_a_state_no_centre_explains_is_named_and_not_moved() -> None:
    xy = _poses()
    # the robot never had state 5: its poses carry the nearest other state's label
    others = np.delete(np.arange(len(CENTRES)), 5)
    cell = others[_nearest(xy, CENTRES[others])]
    chk = check_cell_column(xy, cell, CENTRES)
    assert [f.state for f in chk.states] == [5]  # its neighbours are not blamed for it
    assert chk.states[0].fitted is None and chk.states[0].shift is None
    assert chk.agreement_fitted == chk.agreement
    assert "fit no centre within 0.30 m" in "\n".join(chk.lines())


def test_a_state_built_late_is_compared_only_once_it_exists() -> None:
    xy = _poses()
    n = len(CENTRES)
    # state 11 (the last) is built after the first 4,000 samples: before that its area
    # carries its neighbours' labels
    n_at = np.where(np.arange(len(xy)) < 4000, n - 1, n)
    cell = np.where(n_at == n, _nearest(xy, CENTRES), _nearest(xy, CENTRES[:-1]))
    chk = check_cell_column(xy, cell, CENTRES, n_existing=n_at)
    assert chk.agreement == 1.0 and chk.states == ()
    # taken as built from the start, its area before it existed looks mislabelled
    blind = check_cell_column(xy, cell, CENTRES)
    assert blind.agreement < 1.0 and blind.states[0].state == n - 1
    # and a moved centre is still found among states built late
    robot = CENTRES.copy()
    robot[n - 1] += (-0.08, 0.12)
    cell = np.where(n_at == n, _nearest(xy, robot), _nearest(xy, CENTRES[:-1]))
    chk = check_cell_column(xy, cell, CENTRES, n_existing=n_at)
    assert [f.state for f in chk.states] == [n - 1] and chk.agreement_fitted == 1.0
    np.testing.assert_allclose(chk.states[0].fitted, robot[n - 1], atol=1e-9)
    with pytest.raises(ConfigError, match="only 11 states existed"):
        check_cell_column(xy, np.full(len(xy), n - 1), CENTRES, n_existing=n_at)


def test_a_few_stray_labels_are_below_the_thresholds() -> None:
    xy = _poses()
    cell = _nearest(xy, CENTRES)
    cell[:5] = (cell[:5] + 1) % len(CENTRES)  # five samples logged with a wrong cell
    chk = check_cell_column(xy, cell, CENTRES)
    assert chk.states == () and chk.agreement == pytest.approx(1 - 5 / len(xy))


def test_check_is_deterministic_and_to_dict_round_trips_the_figures() -> None:
    xy = _poses(seed=3)
    robot = CENTRES.copy()
    robot[6] += (0.0, 0.08)
    cell = _nearest(xy, robot)
    a, b = check_cell_column(xy, cell, CENTRES), check_cell_column(xy, cell, CENTRES)
    assert a == b
    d = a.to_dict()
    assert d["agreement"] == a.agreement and d["states"][0]["state"] == 6
    np.testing.assert_allclose(d["states"][0]["fitted"], robot[6], atol=1e-9)


@pytest.mark.parametrize(("cell", "match"), [
    (np.full(10, 12), "not states of the states file"),
    (np.full(10, -1), "not states of the states file"),
    (np.zeros(9), "expected xy"),
])
def test_bad_input_is_refused(cell: np.ndarray, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        check_cell_column(_poses(10), cell, CENTRES)
