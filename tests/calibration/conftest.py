"""Shared fixtures: a 16-state lattice on the table and "real" tables made by the simulator."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from discretize.voronoi import Discretizer
from simlab.base.actions import ActionSet
from simlab.calibration.config import RealTable
from simlab.calibration.walks import SimTable, simulate_counts


@pytest.fixture(scope="session")
def lattice16() -> Discretizer:
    """16 states on a 4 x 4 lattice 0.4 m apart over the table."""
    g = np.linspace(-0.6, 0.6, 4)
    return Discretizer(centres=np.array([(x, y) for y in g[::-1] for x in g]))


@pytest.fixture(scope="session")
def lattice9() -> Discretizer:
    """9 states on a 3 x 3 lattice 0.5 m apart over the table."""
    g = np.linspace(-0.5, 0.5, 3)
    return Discretizer(centres=np.array([(x, y) for y in g[::-1] for x in g]))


def hidden_walk(disc: Any, params: Any, aset: ActionSet, hours: float, seed: int,
                simulator: str) -> SimTable:
    """The "real" robot: a walk with hidden parameters, counted in ``aset``."""
    return simulate_counts("table", disc, params, hours=hours, seed=seed, action_set=aset,
                           simulator=simulator)


def write_counts_csv(path: Path, counts: np.ndarray) -> Path:
    s, a, s2 = np.nonzero(counts)
    lines = ["s,a,s_next,count"] + [f"{i},{j},{k},{counts[i, j, k]}" for i, j, k in
                                    zip(s, a, s2, strict=True)]
    path.write_text("\n".join(lines) + "\n")
    return path


def real_table(sim: SimTable, aset: ActionSet) -> RealTable:
    return RealTable(counts=sim.counts, action_set=aset, hours=sim.hours, blocked=sim.blocked,
                     source="hidden walk")
