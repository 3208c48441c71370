"""Shared helpers of the localization tests: maps and noise-free synthetic scans."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from discretize.gridmap import OccupancyMap
from simlab.localization.maps import arena_map
from simlab.physics.arena import load_arena

#: An arena without symmetry: the table with one box near the east wall.
ASYMMETRIC_TABLE = """
name = "table_asym"
[floor]
size = [1.5, 1.5]
[walls]
height = 0.25
thickness = 0.05
[start]
pose = [0.0, 0.0, 90.0]
[[goals]]
name = "C"
center = [0.0, 0.0]
radius = 0.15
[[obstacles]]
kind = "box"
center = [0.42, 0.24]
size = [0.30, 0.08]
height = 0.3
"""


def raycast(grid: OccupancyMap, sensor_xy: np.ndarray, angles: np.ndarray,
            range_max: float = 3.5, step: float = 0.0005) -> np.ndarray:
    """Ranges (m) from ``sensor_xy`` along world ``angles`` to the first occupied cell
    (``inf`` if none within ``range_max``), by marching in ``step`` increments."""
    r = np.arange(step, range_max, step)
    pts = sensor_xy[None, None, :] + r[None, :, None] * np.stack(
        [np.cos(angles), np.sin(angles)], axis=1)[:, None, :]
    rc = grid.world_to_pixel(pts)
    inside = grid.in_bounds(rc)
    occ = np.zeros(inside.shape, dtype=bool)
    occ[inside] = grid.occupancy[rc[inside][:, 0], rc[inside][:, 1]] >= 65
    hit = occ.argmax(axis=1)
    return np.where(occ.any(axis=1), r[hit], np.inf)


class SyntheticScan:
    """A noise-free scan of ``grid`` from base ``pose`` with the sensor at ``offset``."""

    def __init__(self, grid: OccupancyMap, pose: np.ndarray, n_beams: int = 360,
                 offset: tuple[float, float] = (-0.032, 0.0)) -> None:
        self.pose = np.asarray(pose, dtype=float)
        self.angles = np.arange(n_beams) * (2 * math.pi / n_beams)
        self.sensor_offset = np.asarray(offset, dtype=float)
        x, y, th = self.pose
        c, s = math.cos(th), math.sin(th)
        sensor = np.array([x + c * offset[0] - s * offset[1], y + s * offset[0] + c * offset[1]])
        self.ranges = raycast(grid, sensor, th + self.angles)
        self.stamp = 0.0


@pytest.fixture(scope="session")
def table_grid() -> OccupancyMap:
    return arena_map(load_arena("table"), 0.01)


@pytest.fixture(scope="session")
def asym_arena_path(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("arenas") / "table_asym.toml"
    path.write_text(ASYMMETRIC_TABLE, encoding="utf-8")
    return path


@pytest.fixture(scope="session")
def asym_grid(asym_arena_path: Path) -> OccupancyMap:
    return arena_map(load_arena(asym_arena_path), 0.01)


@pytest.fixture(scope="session")
def scan_factory():
    """``SyntheticScan`` (test modules cannot import conftest)."""
    return SyntheticScan
