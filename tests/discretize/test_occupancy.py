"""Log-odds occupancy grid: exact beam traversal and the update rule."""

from __future__ import annotations

import math

import numpy as np
import pytest

from discretize.gridmap import FREE, OCCUPIED, UNKNOWN
from discretize.occupancy import LogOddsParams, OccupancyGrid, beam_endpoints

RES = 0.01


def _grid(n=200, params=None) -> OccupancyGrid:
    return OccupancyGrid((n, n), RES, (-1.0, -1.0), params)


def _cells_crossed(x0, y0, x1, y1, res=RES, ox=-1.0, oy=-1.0) -> set[tuple[int, int]]:
    """Cells (col, row-from-bottom) whose open square the segment meets (Liang-Barsky)."""
    gx0, gy0, gx1, gy1 = (x0 - ox) / res, (y0 - oy) / res, (x1 - ox) / res, (y1 - oy) / res
    out = set()
    for i in range(int(min(gx0, gx1)) - 1, int(max(gx0, gx1)) + 2):
        for j in range(int(min(gy0, gy1)) - 1, int(max(gy0, gy1)) + 2):
            t0, t1 = 0.0, 1.0
            ok = True
            for p, q in (
                (-(gx1 - gx0), gx0 - i),
                (gx1 - gx0, i + 1 - gx0),
                (-(gy1 - gy0), gy0 - j),
                (gy1 - gy0, j + 1 - gy0),
            ):
                if p == 0:
                    if q <= 0:
                        ok = False
                else:
                    t = q / p
                    if p < 0:
                        t0 = max(t0, t)
                    else:
                        t1 = min(t1, t)
            if ok and t0 < t1:
                out.add((i, j))
    return out


def _changed_cells(grid: OccupancyGrid, sign: int) -> set[tuple[int, int]]:
    rows, cols = np.nonzero(np.sign(grid.log_odds) == sign)
    h = grid.shape[0]
    return {(int(c), int(h - 1 - r)) for r, c in zip(rows, cols, strict=True)}


def test_single_beam_marks_exactly_the_crossed_cells(rng):
    for _ in range(200):
        g = _grid()
        x, y = rng.uniform(-0.5, 0.5, size=2)
        yaw = rng.uniform(-math.pi, math.pi)
        r = rng.uniform(0.13, 0.45)
        g.integrate(np.array([r]), np.array([0.0]), (x, y, yaw), 0.12, 3.5)
        ex, ey = x + r * math.cos(yaw), y + r * math.sin(yaw)
        end = (math.floor((ex + 1.0) / RES), math.floor((ey + 1.0) / RES))
        crossed = _cells_crossed(x, y, ex, ey)
        assert end in crossed
        assert _changed_cells(g, +1) == {end}
        assert _changed_cells(g, -1) == crossed - {end}
        p = g.params
        assert np.allclose(g.log_odds[g.log_odds > 0], p.l_occ)
        assert np.allclose(g.log_odds[g.log_odds < 0], p.l_free)


def _square_scan(pose, half: float, n_beams: int = 360):
    """Exact ranges from ``pose`` to the walls of the square |x|, |y| <= half."""
    x, y, yaw = pose
    angles = np.linspace(-math.pi, math.pi, n_beams, endpoint=False)
    theta = yaw + angles
    c, s = np.cos(theta), np.sin(theta)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 0, (half - x) / c, np.where(c < 0, (-half - x) / c, np.inf))
        ty = np.where(s > 0, (half - y) / s, np.where(s < 0, (-half - y) / s, np.inf))
    return np.minimum(tx, ty), angles


def test_square_room_walls_occupied_inside_free_outside_unseen(rng):
    # Walls on the line |x| or |y| = 0.505: through pixel centres, so endpoint cells
    # are unambiguous: the ring of columns/rows 150 and 49 (grid units from -1 m).
    half = 0.505
    g = _grid()
    for _ in range(40):
        pose = (*rng.uniform(-0.35, 0.35, size=2), rng.uniform(-math.pi, math.pi))
        ranges, angles = _square_scan(pose, half)
        g.integrate(ranges, angles, pose, 0.12, 3.5)
    centres = np.stack(np.meshgrid(np.arange(200), np.arange(200), indexing="xy"), -1)
    gx = (centres[..., 0] + 0.5) * RES - 1.0  # cell centre x for (row from bottom j, col i)
    gy = (centres[..., 1] + 0.5) * RES - 1.0
    lo = np.flipud(g.log_odds)  # index [j, i] with j from the bottom
    cheb = np.maximum(np.abs(gx), np.abs(gy))
    ring = np.isclose(cheb, half)
    inside = cheb < half - 1e-9
    outside = cheb > half + 1e-9
    assert not lo[outside].any(), "no beam may pass the walls"
    assert (lo[ring] >= 0).all() and (lo[ring] > 0).mean() > 0.9
    assert (lo[inside] <= 0).all() and (lo[inside] < 0).mean() > 0.99
    m = g.to_map()
    occ = np.flipud(m.occupancy)
    assert (occ[outside] == UNKNOWN).all()
    assert set(np.unique(occ[inside])) <= {FREE, UNKNOWN}
    assert set(np.unique(occ[ring])) <= {OCCUPIED, UNKNOWN}


def test_endpoint_is_not_freed_by_a_grazing_beam():
    g = _grid()
    # Beam A ends at (0.305, 0.005); beam B from the same origin along +x passes through
    # the same cell and ends further away.
    angles = np.array([math.atan2(0.005, 0.305), 0.0])
    ranges = np.array([math.hypot(0.305, 0.005), 0.6])
    g.integrate(ranges, angles, (0.0, 0.0, 0.0), 0.12, 3.5)
    i, j = math.floor(1.305 / RES), math.floor(1.005 / RES)
    assert g.log_odds[199 - j, i] == pytest.approx(g.params.l_occ)


def test_no_return_beams_free_up_to_the_chosen_length():
    g = _grid()
    g.integrate(np.array([np.inf]), np.array([0.0]), (0.0005, 0.0005, 0.0), 0.12, 0.5)
    assert (g.log_odds <= 0).all()
    assert _changed_cells(g, -1) == {(i, 100) for i in range(100, 150)}
    g2 = _grid()
    g2.integrate(np.array([np.inf]), np.array([0.0]), (0.0005, 0.0005, 0.0), 0.12, 3.5, inf_free_range=0.2)
    assert _changed_cells(g2, -1) == {(i, 100) for i in range(100, 120)}
    g3 = _grid()
    g3.integrate(np.array([np.inf]), np.array([0.0]), (0.0, 0.0, 0.0), 0.12, 3.5, inf_free_range=0.0)
    assert not g3.log_odds.any()


def test_invalid_and_short_readings_are_ignored():
    g = _grid()
    g.integrate(np.array([np.nan, 0.05, -1.0]), np.zeros(3), (0.0, 0.0, 0.0), 0.12, 3.5)
    assert not g.log_odds.any()
    ends, hit = beam_endpoints(np.array([0.5, np.inf, 0.05, 4.0]), np.zeros(4), (1.0, 2.0, math.pi / 2), 0.12, 3.5)
    np.testing.assert_allclose(ends, [[1.0, 2.5], [1.0, 5.5], [1.0, 5.5]], atol=1e-12)
    np.testing.assert_array_equal(hit, [True, False, False])


def test_log_odds_clamped_and_cells_updated_once_per_scan():
    params = LogOddsParams(l_min=-1.0, l_max=2.0)
    g = _grid(params=params)
    angles = np.linspace(0, 0.01, 50)  # 50 beams sharing most cells
    for k in range(1, 8):
        g.integrate(np.full(50, 0.5), angles, (0.0, 0.0, 0.0), 0.12, 3.5)
        near = g.log_odds[199 - 100, 105]  # crossed by every beam, updated once per scan
        assert near == pytest.approx(max(-1.0, k * params.l_free))
    assert g.log_odds.max() == pytest.approx(2.0)
    assert g.log_odds.min() == pytest.approx(-1.0)


def test_python_backend_gives_identical_grids(rng):
    a, b = _grid(), _grid()
    for _ in range(3):
        pose = (*rng.uniform(-0.3, 0.3, size=2), rng.uniform(-3, 3))
        ranges, angles = _square_scan(pose, 0.6, n_beams=90)
        ranges = ranges + rng.normal(0, 0.01, size=ranges.shape)
        ranges[::7] = np.inf
        na = a.integrate(ranges, angles, pose, 0.12, 3.5)
        nb = b.integrate(ranges, angles, pose, 0.12, 3.5, backend="python")
        assert na == nb
    np.testing.assert_array_equal(a.log_odds, b.log_odds)


def test_covering_grid_aligns_pixel_edges_with_bounds():
    g = OccupancyGrid.covering((-0.75, -0.75, 0.75, 0.75), resolution=0.01, margin=0.25)
    assert g.shape == (200, 200)
    assert g.origin_xy == pytest.approx((-1.0, -1.0))
    m = g.to_map()
    assert (m.occupancy == UNKNOWN).all()
    assert m.origin == pytest.approx((-1.0, -1.0, 0.0))


@pytest.mark.parametrize(
    "kwargs",
    [{"l_occ": -1.0}, {"l_free": 0.5}, {"l_min": 1.0}, {"free_thresh": 0.7}, {"occupied_thresh": 1.2}],
)
def test_bad_params(kwargs):
    with pytest.raises(ValueError):
        LogOddsParams(**kwargs)
