"""Synthetic maps shared by the discretize tests."""

from __future__ import annotations

import numpy as np
import pytest

from discretize.gridmap import FREE, OCCUPIED, UNKNOWN, OccupancyMap


def square_room(
    side_px: int = 150, wall_px: int = 5, margin_px: int = 20, resolution: float = 0.01
) -> OccupancyMap:
    """A free square of ``side_px`` pixels, walls ``wall_px`` thick, unknown margin.

    The free square is centred on the world origin, with its edges on pixel edges:
    free x and y in [-side/2, side/2] metres.
    """
    n = side_px + 2 * (wall_px + margin_px)
    occ = np.full((n, n), UNKNOWN, dtype=np.int8)
    a = margin_px
    occ[a : n - a, a : n - a] = OCCUPIED
    b = margin_px + wall_px
    occ[b : n - b, b : n - b] = FREE
    half = side_px * resolution / 2
    off = (wall_px + margin_px) * resolution
    return OccupancyMap(occ, resolution, (-half - off, -half - off, 0.0))


@pytest.fixture(scope="session")
def make_room():
    """The :func:`square_room` factory (test modules cannot import conftest)."""
    return square_room


@pytest.fixture
def room() -> OccupancyMap:
    return square_room()


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
