"""Walks that cover the lab (one walk per start state) and walks in a real robot's own
action set, on the kinematic simulator."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from simlab.base.actions import parse_action_set
from simlab.base.errors import ConfigError
from simlab.data.collect import CollectResult
from simlab.data.dataset import open_dataset, read_dataset
from simlab.data.walkers import KinematicParams

Collect = Callable[..., CollectResult]


def test_one_walk_per_start_state_starts_at_its_centre(tmp_path: Path,
                                                       collect_kinematic: Collect,
                                                       grid_discretizer) -> None:
    res = collect_kinematic(tmp_path / "d", start_states="all", transitions=250)
    table = open_dataset(tmp_path / "d").table
    worker = table.column("worker").to_numpy()
    step = table.column("step").to_numpy()
    centres = np.asarray(grid_discretizer.centres)
    assert sorted(set(worker.tolist())) == list(range(25))
    for w in range(25):
        first = np.flatnonzero((worker == w) & (step == 0))
        assert first.size == 1
        i = int(first[0])
        xy = (table.column("x").to_numpy()[i], table.column("y").to_numpy()[i])
        assert xy == pytest.approx(tuple(centres[w]))
        assert table.column("s").to_numpy()[i] == w
    # 250 transitions split evenly over 25 walks
    assert np.bincount(worker).tolist() == [10] * 25
    assert res.states_visited == 25 and res.n_states == 25
    manifest = json.loads((tmp_path / "d" / "_manifest.json").read_text())
    assert manifest["parameters"]["start_states"] == list(range(25))
    assert manifest["workers"] == 25


def test_start_states_give_the_same_rows_for_any_number_of_processes(
        tmp_path: Path, collect_kinematic: Collect) -> None:
    collect_kinematic(tmp_path / "one", start_states="0,12,24", transitions=90, workers=1)
    collect_kinematic(tmp_path / "two", start_states="0,12,24", transitions=90, workers=2)
    a, b = read_dataset(tmp_path / "one"), read_dataset(tmp_path / "two")
    for name in ("worker", "s", "a", "s_next", "x_next", "y_next"):
        assert np.array_equal(a.column(name).to_numpy(), b.column(name).to_numpy()), name


def test_start_state_out_of_range_is_refused_before_anything_is_written(
        tmp_path: Path, collect_kinematic: Collect) -> None:
    with pytest.raises(ConfigError, match="state 25 is not one of the 25 states"):
        collect_kinematic(tmp_path / "x", start_states="3,25")
    assert not (tmp_path / "x").exists() or not any((tmp_path / "x").iterdir())


def test_an_eight_action_walk_moves_along_its_own_headings(tmp_path: Path,
                                                           collect_kinematic: Collect) -> None:
    params = KinematicParams(distance_noise=0.0, heading_noise=0.0)
    collect_kinematic(tmp_path / "d", n_actions=8, convention="ccw-east", speed="fast",
                      params=params, transitions=400)
    ds = open_dataset(tmp_path / "d")
    aset = parse_action_set(8, "ccw-east", "fast")
    assert ds.action_set == aset
    a = ds.column("a")
    assert a.min() >= 0 and a.max() == 7
    dx = ds.column("x_next") - ds.column("x")
    dy = ds.column("y_next") - ds.column("y")
    moved = np.hypot(dx, dy) > 1e-6
    # every unclipped move has the fast length and action a's heading (0 E, 2 N, 4 W, ...)
    full = moved & np.isclose(np.hypot(dx, dy), 0.22 * 0.5)
    assert full.sum() > 100
    heading = np.arctan2(dy[full], dx[full])
    expected = np.array([aset.heading(int(x)) for x in a[full]])
    err = np.angle(np.exp(1j * (heading - expected)))
    assert np.abs(err).max() < 1e-9
    assert aset.heading(0) == 0.0 and aset.heading(2) == pytest.approx(math.pi / 2)
