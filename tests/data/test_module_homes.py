"""The count model's names stay importable from :mod:`simlab.data.estimate`, where the
calibration, online and social packages import them, as the same objects."""

from __future__ import annotations

import numpy as np
import pytest

from simlab.data import count_model, estimate


@pytest.mark.parametrize("name", count_model.__all__)
def test_every_count_model_name_is_the_same_object_from_estimate(name) -> None:
    assert getattr(estimate, name) is getattr(count_model, name)


def test_the_model_needs_no_command() -> None:
    # 2 states, 1 action: 0 -> 1 twice, 1 never tried (a self-loop, unvisited)
    m = count_model.empirical_mdp(count_model.count_transitions([0, 0], [0, 0], [1, 1], 2, 1))
    np.testing.assert_array_equal(m.T[:, 0], [[0.0, 1.0], [0.0, 1.0]])
    np.testing.assert_array_equal(m.visited[:, 0], [True, False])
