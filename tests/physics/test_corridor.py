"""The obstacle detector's corridor test on hand-made scans (analytic geometry)."""

from __future__ import annotations

import math

import numpy as np

from simlab.physics.lidar import LidarScan
from simlab.physics.motion import corridor_blocked

FOOTPRINT = (-0.1, 0.05, -0.09, 0.09)  # x_min, x_max, y_min, y_max (m)


def scan_of(ranges, angles, offset=(-0.03, 0.0)) -> LidarScan:
    return LidarScan(np.asarray(ranges, dtype=float), np.asarray(angles, dtype=float), 0.12, 3.5,
                     np.asarray(offset, dtype=float), np.zeros(3))


def blocked(scan: LidarScan, distance: float = 0.05) -> bool:
    return corridor_blocked(scan, distance, FOOTPRINT, margin=0.05, side_margin=0.02)


def test_no_return_or_no_beam_is_never_blocked():
    assert not blocked(scan_of([np.inf] * 3, [0.0, 0.1, -0.1]))
    assert not blocked(scan_of([], []))


def test_a_return_ahead_within_reach_blocks_and_beyond_does_not():
    # Corridor ends at x = 0.05 + 0.05 + 0.05 = 0.15 m; the sensor sits at x = -0.03.
    assert blocked(scan_of([np.inf, 0.17], [1.0, 0.0]))       # point at x = 0.14
    assert not blocked(scan_of([np.inf, 0.19], [1.0, 0.0]))   # point at x = 0.16
    assert blocked(scan_of([0.19], [0.0]), distance=0.11)     # the fast move reaches it


def test_returns_beside_or_behind_the_corridor_do_not_block():
    side = math.atan2(0.12, 0.13)  # point at (0.10, 0.12): 1 cm outside the 0.11 m half-width
    assert not blocked(scan_of([math.hypot(0.13, 0.12)], [side]))
    assert not blocked(scan_of([0.2], [math.pi]))  # behind the robot
