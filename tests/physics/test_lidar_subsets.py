"""Beam-subset scans (the detector's cone, a particle filter's beams) against the full scan:
the cached subset directions must give exactly the beams a full scan reads."""

from __future__ import annotations

import numpy as np

from simlab.physics.lidar import LidarScan


def test_subset_scans_equal_the_full_scans_beams(table_world):
    table_world.reset((0.3, -0.2, 0.4))
    full = table_world.scan(None)
    cone = np.arange(-66, 67) % 360
    every9 = np.arange(0, 360, 9)
    for beams in (cone, every9, cone, every9.astype(np.int32), cone):  # alternate: cache hits
        sub = table_world.scan(None, beams=beams)
        np.testing.assert_array_equal(sub.angles, full.angles[beams])
        np.testing.assert_array_equal(sub.ranges, full.ranges[beams])
        np.testing.assert_array_equal(sub.hit_ids, full.hit_ids[beams])


def test_subset_angles_are_shared_read_only(table_world):
    beams = np.arange(0, 360, 9)
    a, b = table_world.scan(None, beams=beams), table_world.scan(None, beams=beams.copy())
    assert a.angles is b.angles
    assert not a.angles.flags.writeable


def test_points_base_are_the_polar_returns_in_the_base_frame():
    ranges = np.array([1.0, np.inf, 0.5, 2.0])
    angles = np.array([0.0, 0.3, np.pi / 2, np.pi])
    scan = LidarScan(ranges, angles, 0.12, 3.5, np.array([-0.03, 0.01]), np.zeros(3))
    pts = scan.points_base()
    ok = np.isfinite(ranges)
    expected = np.stack([-0.03 + ranges[ok] * np.cos(angles[ok]),
                         0.01 + ranges[ok] * np.sin(angles[ok])], axis=1)
    assert pts.shape == (3, 2)
    assert pts.tobytes() == expected.tobytes()
    empty = LidarScan(np.full(2, np.inf), angles[:2], 0.12, 3.5, np.zeros(2), np.zeros(3))
    assert empty.points_base().shape == (0, 2)
