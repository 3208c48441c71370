from __future__ import annotations

import pytest

from simlab.physics.world import World


@pytest.fixture
def table_world():
    with World("table") as world:
        yield world


