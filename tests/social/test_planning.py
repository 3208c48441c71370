"""GO_TO_HUMAN's grid planner against the obstacle arena (issue 18)."""

from __future__ import annotations

import itertools
import math

import numpy as np

from simlab.physics.arena import load_arena
from simlab.social.human import is_free
from simlab.social.planning import plan_path


def _segments_free(arena, way, clearance, discs=()):
    for a, b in itertools.pairwise(way):
        for t in np.linspace(0.0, 1.0, 25):
            p = a + t * (b - a)
            if not is_free(arena, p, clearance * 0.99):
                return False
            for c, r in discs:
                if math.hypot(p[0] - c[0], p[1] - c[1]) <= r + clearance * 0.99:
                    return False
    return True


def test_open_table_path_is_one_straight_move():
    arena = load_arena("table")
    way = plan_path(arena, np.array([-0.4, -0.4]), np.array([0.4, 0.4]), 0.15)
    assert way is not None and len(way) == 2  # the start node, then the goal
    assert np.allclose(way[-1], [0.4, 0.4])
    # the path's direction is one of the 8 (here UP_RIGHT, 45 deg)
    d = way[1] - way[0]
    assert math.isclose(math.atan2(d[1], d[0]), math.pi / 4, abs_tol=1e-9)


def test_path_goes_around_the_box_and_the_human():
    arena = load_arena("table_obstacles")  # box x [-0.34, -0.10], y [0.17, 0.27]
    start, goal = np.array([-0.22, -0.05]), np.array([-0.22, 0.5])
    clearance = 0.15
    assert not _segments_free(arena, [start, goal], clearance)  # straight line hits the box
    way = plan_path(arena, start, goal, clearance)
    assert way is not None and len(way) > 2
    assert _segments_free(arena, way, clearance)
    human = [(np.array([0.15, 0.25]), 0.06)]
    way2 = plan_path(arena, start, goal, clearance, discs=human)
    assert way2 is not None and _segments_free(arena, way2, clearance, human)


def test_unreachable_clearance_gives_no_path():
    arena = load_arena("table")
    assert plan_path(arena, np.zeros(2), np.ones(2) * 0.3, clearance=0.8) is None
