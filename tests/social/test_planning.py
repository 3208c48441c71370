"""GO_TO_HUMAN's grid planner against the obstacle arena (issue 18)."""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np
import pytest

from simlab.physics.arena import MapWalls, load_arena
from simlab.social.human import is_free
from simlab.social.planning import free_grid, plan_path


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


def _loop_free_grid(arena, clearance, step, discs=()):
    """The planner's grid as it was computed before the cache: node by node."""
    cx, cy = arena.center
    nx, ny = (max(1, math.floor(arena.size[k] / step)) for k in (0, 1))
    xs = cx - arena.size[0] / 2 + (np.arange(nx) + 0.5) * arena.size[0] / nx
    ys = cy - arena.size[1] / 2 + (np.arange(ny) + 0.5) * arena.size[1] / ny
    free = np.zeros((nx, ny), dtype=bool)
    for i, x in enumerate(xs):
        for j, y in enumerate(ys):
            ok = is_free(arena, (x, y), clearance)
            for centre, r in discs:
                ok = ok and math.hypot(x - centre[0], y - centre[1]) > r + clearance
            free[i, j] = ok
    return free, xs, ys


def _walled_arena():
    """table_obstacles plus a map wall: a short bar of 3 x 12 pixels of 2 cm."""
    mask = np.zeros((40, 40), dtype=bool)
    mask[20:23, 5:17] = True
    walls = MapWalls.from_mask("bar.yaml", mask, 0.02, (-0.4, -0.4), False)
    return dataclasses.replace(load_arena("table_obstacles"), map_walls=walls)


@pytest.mark.parametrize("arena", [load_arena("table"), load_arena("table_obstacles"),
                                   _walled_arena()], ids=["table", "obstacles", "map_walls"])
@pytest.mark.parametrize("clearance,step", [(0.15, 0.05), (0.0, 0.05), (0.08, 0.037)])
def test_cached_grid_equals_the_node_by_node_grid(arena, clearance, step):
    _, xs, ys = _loop_free_grid(arena, clearance, step)
    # discs: the human in the open, on a wall, outside the table, over an obstacle, and
    # two whose bound passes exactly through a node (the tie decides free or not)
    tie = math.hypot(xs[7] - xs[4], ys[9] - ys[5])
    discs_sets = [
        (),
        [(np.array([0.15, 0.25]), 0.06)],
        [(np.array([xs[0], ys[-1]]), 0.1), (np.array([-0.9, 0.0]), 0.3)],
        [(np.array([-0.22, 0.22]), 0.05), (np.array([xs[-1] + 0.03, ys[3]]), 0.02)],
        [(np.array([xs[4], ys[5]]), tie - clearance), ((xs[10], ys[2]), 0.0)],
    ]
    for discs in discs_sets:
        for _ in range(2):  # the first call fills the cache, the second reads it
            new = free_grid(arena, clearance, step, discs)
            old = _loop_free_grid(arena, clearance, step, discs)
            for a, b in zip(new, old, strict=True):
                assert a.dtype == b.dtype and np.array_equal(a, b)


def test_a_disc_through_a_node_blocks_it_exactly_as_the_loop():
    arena = load_arena("table")
    free0, xs, ys = free_grid(arena, 0.0, 0.05)
    assert free0[7, 9]
    r = math.hypot(xs[7] - xs[4], ys[9] - ys[5])  # the bound is the node's distance
    free, _, _ = free_grid(arena, 0.0, 0.05, [(np.array([xs[4], ys[5]]), r)])
    assert not free[7, 9]  # "free" needs a distance strictly above the bound
    assert np.array_equal(free, _loop_free_grid(arena, 0.0, 0.05,
                                                [(np.array([xs[4], ys[5]]), r)])[0])


def test_the_cache_follows_the_arena_and_returns_fresh_arrays():
    arena = load_arena("table_obstacles")
    free, xs, _ = free_grid(arena, 0.15, 0.05)
    free[:] = False  # the caller's copy: the cache stays intact
    xs[:] = 0.0
    again, xs2, _ = free_grid(arena, 0.15, 0.05)
    assert again.any() and np.array_equal(again, _loop_free_grid(arena, 0.15, 0.05)[0])
    assert xs2[0] != 0.0
    # the same name and size without the obstacles is another grid, not a cache hit
    bare = dataclasses.replace(arena, obstacles=())
    assert free_grid(bare, 0.15, 0.05)[0].sum() > again.sum()
    assert np.array_equal(free_grid(bare, 0.15, 0.05)[0],
                          _loop_free_grid(bare, 0.15, 0.05)[0])
