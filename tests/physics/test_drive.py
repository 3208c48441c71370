"""Commanded vs measured motion of the physically driven wheels."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simlab.physics.world import World


def _run(world: World, seconds: float, sample: int = 4):
    """Step for ``seconds``; return sampled (time, pose, forward speed, yaw rate)."""
    rows = []
    for _ in range(round(seconds * world.physics_hz / sample)):
        world.step(sample)
        v, w = world.velocity()
        rows.append((world.time, *world.pose(), v, w))
    return np.array(rows)


def test_straight_at_v_max_for_3_s():
    with World("table") as world:
        world.reset((0.0, -0.62, math.pi / 2))
        world.drive.command(0.22, 0.0)
        rows = _run(world, 3.0)
        t, x, y, v = rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 4]
        steady = t >= 0.5  # exclude the spin-up
        speed = np.hypot(np.diff(x[steady]), np.diff(y[steady])).sum() / (t[steady][-1] - t[steady][0])
        assert speed == pytest.approx(0.22, rel=0.05)
        assert np.all(np.abs(v) <= 0.22 * 1.05)
        assert abs(x[-1]) < 0.01  # straight: lateral drift under 1 cm over 0.66 m


def test_turn_in_place_at_w_max():
    with World("table") as world:
        world.drive.command(0.0, 2.84)
        rows = _run(world, 2.0)
        t, yaw, w = rows[:, 0], rows[:, 3], rows[:, 5]
        steady = t >= 0.25
        rate = np.diff(np.unwrap(yaw[steady])).sum() / (t[steady][-1] - t[steady][0])
        assert rate == pytest.approx(2.84, rel=0.05)
        assert np.all(np.abs(w) <= 2.84 * 1.05)
        assert np.hypot(rows[-1, 1], rows[-1, 2]) < 0.01  # turning in place


@pytest.mark.parametrize(("v", "w"), [(1.0, 0.0), (-1.0, 0.0), (0.0, 10.0), (0.22, 2.84)])
def test_commands_are_saturated(v, w):
    with World("table") as world:
        world.reset((0.0, -0.5, math.pi / 2))
        applied_v, applied_w = world.drive.command(v, w)
        spec = world.robot_spec
        assert abs(applied_v) <= spec.v_max + 1e-12 and abs(applied_w) <= spec.w_max + 1e-12
        wheel = max(abs(applied_v - applied_w * spec.wheel_separation / 2),
                    abs(applied_v + applied_w * spec.wheel_separation / 2)) / spec.wheel_radius
        assert wheel <= spec.wheel_speed_limit + 1e-9
        if v and w:  # scaled down together: the curvature is kept
            assert applied_w / applied_v == pytest.approx(w / v)
        rows = _run(world, 1.0)
        assert np.all(np.abs(rows[:, 4]) <= spec.v_max * 1.05)
        assert np.all(np.abs(rows[:, 5]) <= spec.w_max * 1.05)


def test_wheel_odometry_drift_is_small_and_mostly_rotational():
    """Straight driving barely drifts; turning in place slips a little (as on the real robot)."""
    with World("table") as world:
        world.reset((0.0, -0.5, math.pi / 2))
        world.drive.command(0.15, 0.0)
        _run(world, 2.0)
        truth, odom = world.pose(), world.odometry()
        travelled = np.hypot(*(truth[:2] - np.array([0.0, -0.5])))
        assert travelled == pytest.approx(0.3, rel=0.05)
        assert np.hypot(*(truth[:2] - odom[:2])) < 0.01 * travelled
        assert abs(truth[2] - odom[2]) < math.radians(0.5)

        yaw0_truth, yaw0_odom = truth[2], odom[2]
        world.drive.command(0.0, 1.5)
        _run(world, 2.0)
        world.drive.command(0.0, 0.0)
        _run(world, 0.3)
        truth, odom = world.pose(), world.odometry()
        turned_truth = math.remainder(truth[2] - yaw0_truth, 2 * math.pi) % (2 * math.pi)
        turned_odom = math.remainder(odom[2] - yaw0_odom, 2 * math.pi) % (2 * math.pi)
        assert turned_truth == pytest.approx(3.0, rel=0.05)
        assert turned_odom == pytest.approx(turned_truth, rel=0.02)
        assert np.hypot(*(truth[:2] - odom[:2])) < 0.01  # the true centre wanders a few mm
        assert world.tilt() < math.radians(1.0)
