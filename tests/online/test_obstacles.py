"""A box added to a live world mid-run: the LIDAR reads it at the analytic distance and
the obstacle detector blocks a primitive into it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.physics.motion import PrimitiveParams, execute_primitive
from simlab.physics.obstacles import add_box, arena_with_box, remove_box
from simlab.physics.world import World

RIGHT_SLOW, RIGHT_FAST, LEFT_FAST = 3, 11, 10  # speed * 8 + direction (UP, DOWN, LEFT, RIGHT)


def test_lidar_reads_the_new_box_at_the_analytic_distance() -> None:
    with World("table") as world:
        world.reset((0.0, 0.0, 0.0))
        before = world.scan(None)
        sx = world.robot_spec.lidar_offset[0]  # the sensor sits this far ahead of the pose
        assert before.ranges[0] == pytest.approx(0.75 - sx, abs=1e-3)  # the east wall
        body = add_box(world, 0.35, 0.0, (0.1, 0.4))  # near face at x = 0.30 m
        after = world.scan(None)
        assert after.ranges[0] == pytest.approx(0.30 - sx, abs=1e-3)
        # beam at angle phi hits the face x = 0.30 at (0.30 - sx) / cos(phi) while
        # |y| = tan(phi) (0.30 - sx) stays within the box's half width 0.2 m
        phi = after.angles
        on_face = np.abs(np.tan(phi) * (0.30 - sx)) < 0.19
        on_face &= np.cos(phi) > 0
        np.testing.assert_allclose(after.ranges[on_face], (0.30 - sx) / np.cos(phi[on_face]),
                                   atol=1e-3)
        behind = np.cos(phi) < -0.5  # the box changes nothing behind the robot
        np.testing.assert_allclose(after.ranges[behind], before.ranges[behind], atol=1e-9)
        remove_box(world, body)
        np.testing.assert_allclose(world.scan(None).ranges, before.ranges, atol=1e-9)


def test_a_primitive_into_the_box_is_blocked_and_the_other_way_is_free() -> None:
    params = PrimitiveParams()
    rng = np.random.default_rng(0)
    with World("table") as world:
        world.reset((0.0, 0.0, 0.0))
        free = execute_primitive(world, RIGHT_FAST, rng, params)
        assert not free.blocked and world.pose()[0] > 0.08  # 0.22 m/s for 0.5 s
        world.reset((0.0, 0.0, 0.0))
        add_box(world, 0.17, 0.0, (0.1, 0.4))  # face 0.12 m ahead, inside 0.11 + margin
        res = execute_primitive(world, RIGHT_FAST, rng, params)
        assert res.blocked
        np.testing.assert_allclose(world.pose()[:2], (0.0, 0.0), atol=0.01)
        res = execute_primitive(world, LEFT_FAST, rng, params)  # turn around and leave
        assert not res.blocked and world.pose()[0] < -0.08


def test_arena_with_box_and_bad_boxes() -> None:
    with World("table") as world:
        arena = arena_with_box(world.arena, 0.35, 0.0, (0.1, 0.4))
        assert arena.obstacles[-1].contains(np.array([0.35, 0.1]))
        assert len(arena.obstacles) == len(world.arena.obstacles) + 1
        with pytest.raises(ConfigError, match="height"):
            add_box(world, 0.3, 0.0, (0.1, 0.1), height=0.05)
        with pytest.raises(ConfigError, match="size"):
            add_box(world, 0.3, 0.0, (0.0, 0.1))
        with pytest.raises(ConfigError, match="x"):
            add_box(world, math.nan, 0.0, (0.1, 0.1))
