"""simlab's warnings point at the caller's line, however deep simlab's own calls go."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from simlab.base.errors import _OURS, warn
from simlab.data.counts import DuplicateRowsWarning, load_counts
from simlab.data.mdp import EmpiricalMDP
from simlab.training.train import train


def test_the_package_folders_are_the_ones_imported() -> None:
    import discretize
    import simlab

    assert simlab.__file__.startswith(_OURS[0]) and discretize.__file__.startswith(_OURS[1])


def test_a_warning_two_simlab_frames_deep_names_this_file(tmp_path: Path) -> None:
    path = tmp_path / "c.csv"
    path.write_text("s,a,s_next,count\n0,1,1,2\n0,1,1,3\n")
    with pytest.warns(DuplicateRowsWarning) as record:
        load_counts(path)
    assert [Path(r.filename) for r in record] == [Path(__file__)]


def test_a_warning_inside_a_command_names_this_file_not_the_wrapper() -> None:
    s, a = 3, 16
    t = np.zeros((s, a, s))
    t[:, :, 0] = t[:, :, 1] = 0.5
    visited = np.ones((s, a), dtype=bool)
    visited[0, :2] = False  # two untried actions of a visited state: masked, with a warning
    mdp = EmpiricalMDP(T=t, goal_names=("g",), goal_masks=np.array([[False, True, False]]),
                       visited=visited)
    with pytest.warns(UserWarning, match="2 unvisited") as record:
        train(mdp, agent="vi-softmax", episodes=2, runs=1, out=None, plots=False,
              progress=False)
    assert {Path(r.filename) for r in record} == {Path(__file__)}


def test_called_from_outside_simlab_it_is_the_caller() -> None:
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        warn("plain", RuntimeWarning)
    assert record[0].filename == __file__ and record[0].category is RuntimeWarning
