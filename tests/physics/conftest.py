from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from simlab.physics.motion import PrimitiveParams
from simlab.physics.world import World


def ensemble_text(members: list[PrimitiveParams] | tuple[PrimitiveParams, ...]) -> str:
    """A primitives file as calibrate writes it: ``[primitives]`` (the winner), then one
    ``[[ensemble]]`` record per member."""
    tables = ["[[ensemble]]\n" + m.toml_text().split("\n", 1)[1] for m in members]
    return members[0].toml_text() + "\n" + "\n".join(tables)


def ensemble_lab(directory: Path, members: tuple[PrimitiveParams, ...]) -> tuple[Path, Path]:
    """A 5 x 5 lattice of states on the table arena (0.3 m apart) and a primitives file
    with ``members`` as its ensemble: ``(states.json, primitives.toml)``."""
    from discretize.voronoi import Discretizer

    g = np.linspace(-0.6, 0.6, 5)
    states = Discretizer(centres=np.array([(x, y) for y in g[::-1] for x in g])).save(
        directory / "states.json")
    prims = directory / "primitives.toml"
    prims.write_text(ensemble_text(members))
    return states, prims


@pytest.fixture
def table_world():
    with World("table") as world:
        yield world


