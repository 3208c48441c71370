"""Layouts and the movement rule (SPEC B1): walls, multi-cell stop, diagonal rule."""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.visitlab.actions import ACTION_DIR, ACTION_SPEED, DIR_DELTA, Action, move_action
from simlab.visitlab.grid import (
    Layout,
    gridworld,
    lab_layout,
    make_layout,
    move,
    move_action_cell,
    paper_layout,
    unit_step,
)


def open_grid(h: int = 6, w: int = 6) -> Layout:
    return gridworld(h, w, (1, 1))


def with_walls(h: int, w: int, hwalls=(), vwalls=()) -> Layout:
    """A grid with extra walls: hwalls (r, c) on the line above row r, vwalls (r, c) left of col c."""
    base = open_grid(h, w)
    wh = base.walls_h.copy()
    wv = base.walls_v.copy()
    for r, c in hwalls:
        wh[r, c] = True
    for r, c in vwalls:
        wv[r, c] = True
    return Layout("test", wh, wv, base.labels, base.room_names, base.goal_labels)


def bfs_reachable(layout: Layout, start: int) -> set[int]:
    seen = {start}
    queue = deque([start])
    while queue:
        cell = queue.popleft()
        for d in range(4):
            nxt = unit_step(layout.walls_h, layout.walls_v, cell, d)
            if nxt >= 0 and nxt not in seen:
                seen.add(nxt)
                queue.append(nxt)
    return seen


def test_action_tables_follow_thesis_table_2_1():
    assert Action.UP == 0 and Action.RIGHT3 == 11 and Action.UP_LEFT == 12
    assert Action.DOWN_RIGHT3 == 23 and Action.STAY == 24 and Action.GO_TO_HUMAN == 29
    # action 18 is DOWN-LEFT at speed 2 (thesis Fig. 2.6)
    assert ACTION_DIR[18] == 6 and ACTION_SPEED[18] == 2
    for a in range(24):
        assert move_action(int(ACTION_DIR[a]), int(ACTION_SPEED[a])) == a


def test_open_grid_moves_are_exact():
    lay = open_grid(10, 10)
    c = lay.cell(5, 5)
    for a in range(24):
        dr, dc = DIR_DELTA[ACTION_DIR[a]] * ACTION_SPEED[a]
        assert lay.next_cell(c, a) == lay.cell(5 + dr, 5 + dc)
    assert lay.next_cell(c, Action.STAY) == c


def test_border_stops_multi_cell_move_at_last_free_cell():
    lay = open_grid(6, 6)
    assert lay.next_cell(lay.cell(0, 0), Action.LEFT) == lay.cell(0, 0)
    assert lay.next_cell(lay.cell(0, 0), Action.UP3) == lay.cell(0, 0)
    assert lay.next_cell(lay.cell(1, 4), Action.RIGHT3) == lay.cell(1, 5)
    assert lay.next_cell(lay.cell(4, 1), Action.DOWN_LEFT3) == lay.cell(5, 0)
    # the thesis example: p(1 | 0, RIGHT) = 1 and p(0 | 0, LEFT) = 1
    assert lay.next_cell(0, Action.RIGHT) == 1 and lay.next_cell(0, Action.LEFT) == 0


def test_inner_wall_stops_multi_cell_move():
    # wall between columns 2 and 3 on row 1
    lay = with_walls(5, 6, vwalls=[(1, 3)])
    assert lay.next_cell(lay.cell(1, 0), Action.RIGHT3) == lay.cell(1, 2)
    assert lay.next_cell(lay.cell(1, 2), Action.RIGHT) == lay.cell(1, 2)
    assert lay.next_cell(lay.cell(1, 3), Action.LEFT2) == lay.cell(1, 3)
    # other rows are unaffected
    assert lay.next_cell(lay.cell(2, 0), Action.RIGHT3) == lay.cell(2, 3)


@pytest.mark.parametrize("wall", ["h_left", "h_right", "v_top", "v_bottom"])
def test_diagonal_blocked_if_either_l_path_crosses_a_wall(wall):
    # diagonal DOWN_RIGHT from (1, 1) to (2, 2); the four walls around the corner (2, 2)
    walls = {
        "h_left": dict(hwalls=[(2, 1)]),  # below (1, 1): blocks the vertical-first path
        "h_right": dict(hwalls=[(2, 2)]),  # above (2, 2): blocks the horizontal-first path
        "v_top": dict(vwalls=[(1, 2)]),  # right of (1, 1): blocks the horizontal-first path
        "v_bottom": dict(vwalls=[(2, 2)]),  # left of (2, 2): blocks the vertical-first path
    }[wall]
    lay = with_walls(5, 5, **walls)
    start = lay.cell(1, 1)
    assert lay.next_cell(start, Action.DOWN_RIGHT) == start
    assert lay.next_cell(start, Action.DOWN_RIGHT3) == start


def test_diagonal_multi_cell_stops_before_blocked_corner():
    lay = with_walls(6, 6, hwalls=[(3, 3)])  # wall above (3, 3)
    # (0, 0) -> (1, 1) -> (2, 2) -> (3, 3) blocked at the last step
    assert lay.next_cell(lay.cell(0, 0), Action.DOWN_RIGHT3) == lay.cell(2, 2)


def test_other_agent_blocks_like_a_wall():
    lay = open_grid(6, 6)
    wh, wv = lay.walls_h, lay.walls_v
    start = lay.cell(2, 0)
    assert move(wh, wv, start, 3, 3, lay.cell(2, 2)) == lay.cell(2, 1)
    assert move(wh, wv, start, 3, 3, lay.cell(2, 1)) == start
    assert move(wh, wv, start, 3, 3, -1) == lay.cell(2, 3)
    assert move_action_cell(wh, wv, start, int(Action.RIGHT3), lay.cell(2, 3)) == lay.cell(2, 2)


def test_transition_table_is_deterministic_and_in_range():
    lay = paper_layout()
    table = lay.transition_table()
    assert table.shape == (576, 25)
    assert table.min() >= 0 and table.max() < 576
    np.testing.assert_array_equal(table[:, 24], np.arange(576))


def test_paper_layout_has_nine_connected_8x8_rooms():
    lay = paper_layout()
    assert (lay.height, lay.width) == (24, 24)
    counts = np.bincount(lay.cell_labels)
    np.testing.assert_array_equal(counts, [64] * 9)
    assert lay.labels[0, 0] == 0 and lay.labels[23, 23] == 8 and lay.labels[8, 8] == 4
    assert lay.has_inner_walls
    assert bfs_reachable(lay, 0) == set(range(576))
    # the only way from room 0 to room 1 is the door: a cross-room move elsewhere is blocked
    assert lay.next_cell(lay.cell(0, 7), Action.RIGHT) == lay.cell(0, 7)
    assert lay.next_cell(lay.cell(3, 7), Action.RIGHT) == lay.cell(3, 8)


def test_gridworld_has_no_inner_walls_and_block_labels():
    lay = gridworld()
    assert not lay.has_inner_walls
    assert lay.n_labels == 9
    np.testing.assert_array_equal(np.bincount(lay.cell_labels), [64] * 9)
    assert lay.labels[23, 23] == 8


def test_lab_layout_is_seeded_and_connected():
    a = lab_layout(np.random.default_rng(7))
    b = lab_layout(np.random.default_rng(7))
    np.testing.assert_array_equal(a.walls_h, b.walls_h)
    np.testing.assert_array_equal(a.walls_v, b.walls_v)
    np.testing.assert_array_equal(a.labels, b.labels)
    differs = False
    for seed in range(8):
        lay = lab_layout(np.random.default_rng(seed))
        assert bfs_reachable(lay, lay.start_cell) == set(range(lay.n_cells))
        assert lay.room_names[0] == "corridor"
        assert lay.cell_labels[lay.start_cell] == 0
        assert 0 not in lay.goal_labels
        assert 4 <= len(lay.goal_labels) <= 8
        corridor_rows = np.flatnonzero((lay.labels == 0).all(axis=1))
        assert 2 <= corridor_rows.size <= 4
        differs |= not np.array_equal(lay.labels, a.labels)
    assert differs


def test_layout_validation_names_the_field():
    base = open_grid(3, 3)
    with pytest.raises(ConfigError, match="walls_h"):
        Layout("x", base.walls_h[:-1], base.walls_v, base.labels, ("a",), (0,))
    open_border = base.walls_h.copy()
    open_border[0, 1] = False
    with pytest.raises(ConfigError, match="border"):
        Layout("x", open_border, base.walls_v, base.labels, ("a",), (0,))
    with pytest.raises(ConfigError, match="labels"):
        Layout("x", base.walls_h, base.walls_v, base.labels + 1, ("a",), (0,))
    with pytest.raises(ConfigError, match="rooms_per_side"):
        lab_layout(np.random.default_rng(0), width=8, rooms_per_side=(2, 4))
    with pytest.raises(ConfigError, match="layout"):
        make_layout("castle")
    assert make_layout("gridworld-5x7").width == 7
