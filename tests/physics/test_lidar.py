"""LIDAR ranges against analytic distances to known walls."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simlab.physics.world import World


def wall_distance(sx: float, sy: float, phi: np.ndarray, half: float) -> np.ndarray:
    """Distance from (sx, sy) along directions phi to the inside of the square [-half, half]^2."""
    c, s = np.cos(phi), np.sin(phi)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 0, (half - sx) / c, np.where(c < 0, (-half - sx) / c, np.inf))
        ty = np.where(s > 0, (half - sy) / s, np.where(s < 0, (-half - sy) / s, np.inf))
    return np.minimum(tx, ty)


@pytest.mark.parametrize("pose", [(0.0, 0.0, math.pi / 2), (0.3, -0.2, 0.4), (-0.5, 0.55, -2.0)])
def test_noiseless_scan_matches_wall_distances(pose):
    with World("table") as world:
        world.reset(pose)
        scan = world.scan(None)
        x, y, yaw = pose
        off = world.robot_spec.lidar_offset
        sx, sy = x + math.cos(yaw) * off[0], y + math.sin(yaw) * off[0]
        expected = wall_distance(sx, sy, yaw + scan.angles, 0.75)
        assert scan.ranges.shape == (360,)
        assert np.all(np.isfinite(scan.ranges))
        np.testing.assert_allclose(scan.ranges, expected, atol=1e-3)


def test_noise_is_gaussian_with_sigma_001_and_seeded():
    with World("table") as world:
        exact = world.scan(None).ranges
        scans = np.array([world.scan(np.random.default_rng(s)).ranges for s in range(40)])
        residual = (scans - exact).ravel()
        assert abs(residual.mean()) < 0.001  # 14,400 samples: standard error 1e-4
        assert residual.std() == pytest.approx(0.01, rel=0.05)
        same = world.scan(np.random.default_rng(7)).ranges
        np.testing.assert_array_equal(same, world.scan(np.random.default_rng(7)).ranges)
        assert not np.array_equal(same, world.scan(np.random.default_rng(8)).ranges)


def test_beams_beyond_range_read_inf(tmp_path):
    path = tmp_path / "hall.toml"
    path.write_text(
        'name = "hall"\n[floor]\nsize = [10.0, 10.0]\n[walls]\nheight = 0.25\nthickness = 0.05\n'
        '[start]\npose = [4.0, 0.0, 0.0]\n[[goals]]\nname = "g"\ncenter = [0.0, 0.0]\n'
        "radius = 0.2\n"
    )
    with World(path) as world:
        scan = world.scan(np.random.default_rng(0))
        sx = 4.0 - 0.032
        expected = wall_distance(sx, 0.0, scan.angles, 5.0)
        far = expected > 3.5 + 0.05
        near = expected < 3.5 - 0.05
        assert far.sum() > 200 and near.sum() > 100
        assert np.all(np.isinf(scan.ranges[far]))
        assert np.all(np.abs(scan.ranges[near] - expected[near]) < 0.05)


def test_range_min_hides_nearby_objects_and_points_are_in_world_frame():
    with World("table") as world:
        world.reset((0.0, 0.0, 0.0))
        scan = world.scan(None)
        assert np.all(scan.ranges[np.isfinite(scan.ranges)] >= scan.range_min)
        pts = scan.points_world()
        # every return lies on the wall square |x| = 0.75 or |y| = 0.75
        on_wall = np.isclose(np.maximum(np.abs(pts[:, 0]), np.abs(pts[:, 1])), 0.75, atol=2e-3)
        assert on_wall.all()


def test_short_reach_reads_inf_beyond_it_and_keeps_the_noise_stream():
    with World("table") as world:
        world.reset((0.45, 0.0, 0.0))  # sensor ~0.27 m from the +x wall, >1 m from -x
        full = world.scan(np.random.default_rng(3))
        short = world.scan(np.random.default_rng(3), reach=0.6)
        exact = world.scan(None).ranges
        near = exact < 0.6 - 0.05
        far = exact > 0.6 + 0.05
        assert near.sum() > 20 and far.sum() > 200
        np.testing.assert_allclose(short.ranges[near], full.ranges[near], atol=1e-9)
        assert np.all(np.isinf(short.ranges[far]))
        with pytest.raises(ValueError, match="reach"):
            world.scan(None, reach=0.1)  # not beyond range_min
