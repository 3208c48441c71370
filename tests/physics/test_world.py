"""Worlds own their physics client: two arenas in one process are independent."""

from __future__ import annotations

import numpy as np

from simlab.physics.motion import execute_primitive
from simlab.physics.world import World


def _walk(world: World, seed: int, n: int = 15) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.array([execute_primitive(world, int(rng.integers(16)), rng).pose_after
                     for _ in range(n)])


def test_two_arenas_in_one_process_do_not_affect_each_other():
    with World("table") as solo:
        reference = _walk(solo, 1)
    with World("table") as a, World("table_obstacles") as b:
        assert a.client._client != b.client._client
        b_start = b.pose()
        interleaved = []
        rng_a, rng_b = np.random.default_rng(1), np.random.default_rng(2)
        for _ in range(15):
            interleaved.append(execute_primitive(a, int(rng_a.integers(16)), rng_a).pose_after)
            execute_primitive(b, int(rng_b.integers(16)), rng_b)
        np.testing.assert_array_equal(np.array(interleaved), reference)
        assert not np.allclose(b.pose(), b_start)
        assert len(b.static_bodies) == len(a.static_bodies) + 2  # b's obstacles are b's alone


def test_close_is_idempotent():
    world = World("table")
    world.close()
    world.close()
