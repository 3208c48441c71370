"""Perception (SPEC B2): angle sectors, fields of view, line of sight, distance classes."""

from __future__ import annotations

import numpy as np
import pytest

from simlab.base.directions import Direction
from simlab.base.errors import ConfigError
from simlab.visitlab.actions import DIR_DELTA, DIR_OPPOSITE
from simlab.visitlab.grid import Layout, gridworld, lab_layout, paper_layout
from simlab.visitlab.perception import (
    PAPER_PERCEPTION,
    THESIS_PERCEPTION,
    Perception,
    direction_of,
    distance_class,
    line_of_sight,
    percepts,
    sector_gap,
    trace_line_of_sight,
)

U, D, L, R, UL, UR, DL, DR = range(8)


def test_unit_offsets_map_to_their_direction():
    for d in range(8):
        assert direction_of(int(DIR_DELTA[d, 0]), int(DIR_DELTA[d, 1])) == d
        assert DIR_OPPOSITE[DIR_OPPOSITE[d]] == d


@pytest.mark.parametrize(
    ("drow", "dcol", "expected"),
    [
        (-3, 1, U),  # 71.6 deg -> UP (67.5 is the UP/UR boundary)
        (-2, 1, UR),  # 63.4 deg -> UR
        (-1, 2, UR),  # 26.6 deg -> UR
        (-1, 3, R),  # 18.4 deg -> RIGHT
        (5, -2, D),  # -111.8 deg -> DOWN
        (2, -5, L),  # 201.8 deg -> LEFT
        (3, -3, DL),
        (-4, -4, UL),
        (1, 1, DR),
    ],
)
def test_angle_is_quantised_to_nearest_sector(drow, dcol, expected):
    assert direction_of(drow, dcol) == expected


def test_sector_gap_is_circular():
    assert sector_gap(U, U) == 0
    assert sector_gap(U, UR) == 1 and sector_gap(U, UL) == 1
    assert sector_gap(U, R) == 2 and sector_gap(U, L) == 2
    assert sector_gap(U, DR) == 3 and sector_gap(U, D) == 4
    assert sector_gap(R, DR) == 1 and sector_gap(DR, UL) == 4
    for a in range(8):
        for b in range(8):
            assert sector_gap(a, b) == sector_gap(b, a)


@pytest.mark.parametrize(
    ("offset", "thesis", "paper"),
    [
        ((0, 1), 0, 0),
        ((1, 1), 1, 0),  # Manhattan 2, Chebyshev 1
        ((0, 2), 1, 1),
        ((2, 1), 2, 1),  # Manhattan 3, Chebyshev 2
        ((0, 3), 2, 2),
        ((2, 2), 3, 1),  # Manhattan 4, Chebyshev 2
        ((0, 4), 3, 2),
        ((3, 2), 4, 2),  # Manhattan 5, Chebyshev 3
        ((0, 5), 4, 3),
        ((5, 5), 4, 3),
        ((0, 6), 4, 4),
        ((9, 0), 4, 4),
    ],
)
def test_distance_classes_in_both_metrics(offset, thesis, paper):
    width = 20
    a = 0
    b = offset[0] * width + offset[1]
    assert distance_class(THESIS_PERCEPTION.to_array(), width, a, b) == thesis
    assert distance_class(PAPER_PERCEPTION.to_array(), width, a, b) == paper


def test_perception_validation():
    with pytest.raises(ConfigError, match="metric"):
        Perception(metric="euclid")
    with pytest.raises(ConfigError, match="bounds"):
        Perception(bounds=(1, 3, 2, 4))
    with pytest.raises(ConfigError, match="visual"):
        Perception(visual=1, facing=2)


# ----------------------------------------------------------------- line of sight


def _orient(ax, ay, bx, by, cx, cy):
    v = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    return int(v > 0) - int(v < 0)


def _on_segment(ax, ay, bx, by, cx, cy):
    return min(ax, bx) <= cx <= max(ax, bx) and min(ay, by) <= cy <= max(ay, by)


def _segments_touch(p, q, a, b):
    """Closed segments pq and ab intersect (exact integer geometry)."""
    o1 = _orient(*p, *q, *a)
    o2 = _orient(*p, *q, *b)
    o3 = _orient(*a, *b, *p)
    o4 = _orient(*a, *b, *q)
    if o1 != o2 and o3 != o4:
        return True
    return ((o1 == 0 and _on_segment(*p, *q, *a)) or (o2 == 0 and _on_segment(*p, *q, *b))
            or (o3 == 0 and _on_segment(*a, *b, *p)) or (o4 == 0 and _on_segment(*a, *b, *q)))


def brute_force_los(layout: Layout, a: int, b: int) -> bool:
    """Independent check: the centre-to-centre segment touches no wall segment."""
    w = layout.width
    p = (2 * (a % w) + 1, 2 * (a // w) + 1)
    q = (2 * (b % w) + 1, 2 * (b // w) + 1)
    for r, c in zip(*np.nonzero(layout.walls_h), strict=True):
        r, c = int(r), int(c)
        if _segments_touch(p, q, (2 * c, 2 * r), (2 * c + 2, 2 * r)):
            return False
    for r, c in zip(*np.nonzero(layout.walls_v), strict=True):
        r, c = int(r), int(c)
        if _segments_touch(p, q, (2 * c, 2 * r), (2 * c, 2 * r + 2)):
            return False
    return True


def test_line_of_sight_matches_exact_geometry_on_random_labs():
    rng = np.random.default_rng(0)
    for seed in range(3):
        lay = lab_layout(np.random.default_rng(seed), height=14, width=14)
        table = lay.los_table()
        assert table.shape == (lay.n_cells, lay.n_cells)
        np.testing.assert_array_equal(table, table.T)
        pairs = rng.integers(0, lay.n_cells, size=(400, 2))
        for a, b in pairs:
            expected = a == b or brute_force_los(lay, int(a), int(b))
            assert bool(table[a, b]) == expected
            assert trace_line_of_sight(lay.walls_h, lay.walls_v, int(a), int(b)) == expected


def test_line_of_sight_blocked_by_room_walls_open_through_doors():
    lay = paper_layout()
    los = lay.los_table()
    wh, wv = lay.walls_h, lay.walls_v
    # rooms 0 and 1 are separated by a wall at column 8, door at rows 3-4
    assert not line_of_sight(wh, wv, los, lay.cell(0, 7), lay.cell(0, 8))
    assert line_of_sight(wh, wv, los, lay.cell(3, 7), lay.cell(3, 8))
    assert line_of_sight(wh, wv, los, lay.cell(3, 2), lay.cell(4, 14))
    assert line_of_sight(wh, wv, los, lay.cell(0, 0), lay.cell(7, 7))
    # a layout without inner walls sees everything (the (1, 1) table)
    open_lay = gridworld()
    assert open_lay.los_table().shape == (1, 1)
    assert line_of_sight(open_lay.walls_h, open_lay.walls_v, open_lay.los_table(), 0, 575)


def test_sight_line_through_a_wall_end_is_blocked():
    base = gridworld(5, 5, (1, 1))
    wv = base.walls_v.copy()
    wv[0, 2] = True  # wall left of (0, 2), ending at the grid corner (x=2, y=1)
    lay = Layout("t", base.walls_h, wv, base.labels, base.room_names, base.goal_labels)
    # (0, 1) -> (1, 2): the segment passes exactly through that corner
    assert not trace_line_of_sight(lay.walls_h, lay.walls_v, lay.cell(0, 1), lay.cell(1, 2))
    # consistent with movement: the same diagonal step is refused
    assert lay.next_cell(lay.cell(0, 1), 15) == lay.cell(0, 1)
    # (1, 1) -> (1, 2) passes below the wall end
    assert trace_line_of_sight(lay.walls_h, lay.walls_v, lay.cell(1, 1), lay.cell(1, 2))


# ----------------------------------------------------------------- percept levels


def _percepts(robot_rc, robot_ori, human_rc, human_ori, layout=None, perception=THESIS_PERCEPTION):
    lay = layout or gridworld(11, 11, (1, 1))
    return percepts(lay.walls_h, lay.walls_v, lay.los_table(), perception.to_array(),
                    lay.cell(*robot_rc), robot_ori, lay.cell(*human_rc), human_ori)


@pytest.mark.parametrize(
    ("robot_ori", "human_ori", "level", "flags"),
    [
        # robot at (5, 8), human at (5, 5): robot -> human is LEFT, human -> robot RIGHT
        (L, R, 4, (True, True, True)),  # both look at each other
        (L, UR, 4, (True, True, True)),  # 45 deg off is still "looks at"
        (L, U, 3, (True, False, True)),  # human only sees (90 deg), robot looks
        (L, D, 3, (True, False, True)),
        (U, R, 2, (True, True, False)),  # human looks, robot turned away
        (U, UR, 2, (True, True, False)),
        (R, DR, 2, (True, True, False)),
        (D, U, 1, (True, False, False)),  # human sees only
        (L, L, 0, (False, False, True)),  # human turned away, robot looks: level 0
        (L, UL, 0, (False, False, True)),
        (R, L, 0, (False, False, False)),
    ],
)
def test_percept_levels(robot_ori, human_ori, level, flags):
    got = _percepts((5, 8), robot_ori, (5, 5), human_ori)
    assert got[0] == level
    assert got[1] == 2  # Manhattan 3
    assert got[2] == L  # angle robot -> human
    assert got[3:] == flags


def test_walls_hide_everything():
    lay = paper_layout()
    # robot (0, 9) in room 1, human (0, 6) in room 0, facing each other across the wall
    got = _percepts((0, 9), L, (0, 6), R, layout=lay)
    assert got[0] == 0 and got[3:] == (False, False, False)
    # same geometry through the door rows 3-4
    got = _percepts((3, 9), L, (3, 6), R, layout=lay)
    assert got[0] == 4


def test_visual_field_is_plus_minus_two_sectors():
    # human at centre facing UP; robot on a ring at Chebyshev distance 2, robot looking at human
    lay = gridworld(11, 11, (1, 1))
    seen = {}
    for d in range(8):
        dr, dc = DIR_DELTA[d] * 2
        robot_ori = int(DIR_OPPOSITE[d])
        got = _percepts((5 + dr, 5 + dc), robot_ori, (5, 5), int(Direction.UP), layout=lay)
        seen[d] = (got[3], got[4])
    assert {d for d, (s, _) in seen.items() if s} == {U, UL, UR, L, R}
    assert {d for d, (_, looks) in seen.items() if looks} == {U, UL, UR}
