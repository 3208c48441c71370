"""Maps to localize on: the arena raster, and refusing a map made in another arena."""

from __future__ import annotations

import json

import numpy as np
import pytest

from discretize.gridmap import OccupancyMap
from discretize.mapio import write_map
from simlab.base.errors import ConfigError
from simlab.localization.maps import (
    arena_map,
    check_map_matches_arena,
    load_map_for_arena,
    map_agreement,
)
from simlab.physics.arena import load_arena


def test_arena_map_is_the_arena_geometry() -> None:
    arena = load_arena("table_obstacles")
    grid = arena_map(arena, 0.02)
    truth = arena.occupied(grid.pixel_centres()).reshape(grid.shape)
    np.testing.assert_array_equal(grid.occupancy == 100, truth)
    assert set(np.unique(grid.occupancy)) == {0, 100}


def test_own_raster_passes_with_full_scores() -> None:
    arena = load_arena("table_obstacles")
    check = check_map_matches_arena(arena_map(arena), arena)
    assert check.precision == 1.0 and check.recall == 1.0


def test_map_without_the_arenas_obstacles_fails_recall() -> None:
    grid = arena_map(load_arena("table"))
    check = map_agreement(grid, load_arena("table_obstacles"))
    assert check.precision == 1.0 and check.recall < 0.9
    with pytest.raises(ConfigError, match="does not match the arena 'table_obstacles'"):
        check_map_matches_arena(grid, load_arena("table_obstacles"))


def test_map_with_extra_obstacles_fails_precision() -> None:
    grid = arena_map(load_arena("table_obstacles"))
    with pytest.raises(ConfigError, match="occupied cells lie on the arena"):
        check_map_matches_arena(grid, load_arena("table"))


def test_shifted_map_fails() -> None:
    grid = arena_map(load_arena("table"))
    shifted = OccupancyMap(grid.occupancy, grid.resolution,
                           (grid.origin[0] + 0.1, grid.origin[1], 0.0))
    with pytest.raises(ConfigError, match="does not match"):
        check_map_matches_arena(shifted, load_arena("table"))


def test_provenance_naming_another_arena_fails_with_the_file(tmp_path) -> None:
    arena = load_arena("table")
    yaml_path, _ = write_map(tmp_path / "map.yaml", arena_map(arena))
    (tmp_path / "exploration.json").write_text(json.dumps({"arena": "kitchen"}))
    with pytest.raises(ConfigError) as info:
        load_map_for_arena(yaml_path, arena)
    assert str(yaml_path) in str(info.value) and "'kitchen'" in str(info.value)


def test_an_explored_map_matches_its_arena_only(tmp_path) -> None:
    from simlab.orchestration.mapping import build_map

    run = build_map("table", minutes=4.0, seed=3, out=tmp_path / "m", progress=False)
    _, check = load_map_for_arena(run.yaml_path, load_arena("table"))
    assert check is not None and check.precision >= 0.9 and check.recall >= 0.9
    assert check.provenance_arena == "table"
    with pytest.raises(ConfigError, match="made in the arena 'table'"):
        load_map_for_arena(run.yaml_path, load_arena("table_obstacles"))
    (tmp_path / "m" / "exploration.json").unlink()  # content alone still tells them apart
    with pytest.raises(ConfigError, match="does not match"):
        load_map_for_arena(run.yaml_path, load_arena("table_obstacles"))


def test_no_map_means_the_arena_raster() -> None:
    arena = load_arena("table")
    grid, check = load_map_for_arena(None, arena)
    assert check is None and grid.same_as(arena_map(arena))
