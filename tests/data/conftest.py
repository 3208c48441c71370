"""Shared fixtures of the dataset / estimator tests.

Most tests run the collection machinery on the physics-free kinematic simulator
(milliseconds per part); the physics-backed tests keep to a few hundred transitions.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from discretize.gridmap import OccupancyMap
from discretize.voronoi import Discretizer
from simlab.data.collect import CollectResult, collect
from simlab.physics.arena import load_arena


@pytest.fixture(scope="session")
def grid_discretizer() -> Discretizer:
    """25 states on a 5 x 5 lattice 0.3 m apart over the table, numbered row-major."""
    g = np.linspace(-0.6, 0.6, 5)
    return Discretizer(centres=np.array([(x, y) for y in g[::-1] for x in g]))


@pytest.fixture(scope="session")
def grid_states_file(tmp_path_factory: pytest.TempPathFactory,
                     grid_discretizer: Discretizer) -> Path:
    path = tmp_path_factory.mktemp("states") / "grid25.json"
    grid_discretizer.save(path)
    return path


@pytest.fixture(scope="session")
def table_states_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """41 Voronoi states of the table arena, placed on its rasterized ground-truth map."""
    arena = load_arena("table")
    res, shape, origin = 0.02, (90, 90), (-0.9, -0.9)
    occ = np.where(arena.rasterize(res, origin, shape), 100, 0).astype(np.int8)
    grid = OccupancyMap(occ, res, (origin[0], origin[1], 0.0))
    path = tmp_path_factory.mktemp("states") / "table.json"
    Discretizer.from_map(grid, 41).save(path)
    return path


@pytest.fixture()
def collect_kinematic(grid_discretizer: Discretizer) -> Callable[..., CollectResult]:
    """``collect`` on the kinematic simulator with the 25-state lattice; kwargs override."""

    def run(out: Path, **kwargs: Any) -> CollectResult:
        options: dict[str, Any] = dict(
            arena="table", states=grid_discretizer, transitions=600, seed=7, workers=1,
            part_size=100, simulator="kinematic", progress=False,
        )
        options.update(kwargs)
        return collect(out=out, **options)

    return run


@pytest.fixture(scope="session")
def kinematic_dataset(tmp_path_factory: pytest.TempPathFactory,
                      grid_discretizer: Discretizer) -> Path:
    """A read-only 2-worker kinematic dataset (1,500 transitions, parts of 200)."""
    out = tmp_path_factory.mktemp("kin") / "walk"
    collect(arena="table", states=grid_discretizer, out=out, transitions=1500, seed=11,
            workers=2, part_size=200, simulator="kinematic", progress=False)
    return out


@pytest.fixture()
def dataset_copy(tmp_path: Path, kinematic_dataset: Path) -> Path:
    """A private copy of :func:`kinematic_dataset` that a test may damage."""
    dst = tmp_path / "copy"
    shutil.copytree(kinematic_dataset, dst)
    return dst
