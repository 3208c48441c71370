"""The label grid gives the nearest-centre state of every point, ties included.

:class:`discretize.label_grid.LabelGrid` is what the walker asks at every control tick of
an ``until_state_change`` drive; it must answer as the discretizer's own ``state_of``
(one point: brute force, ties broken by the KD-tree) at every point: cell centres, random
points, exact ties on a lattice, points on Voronoi edges and at Voronoi vertices.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from discretize.label_grid import LabelGrid
from discretize.voronoi import Discretizer
from simlab.data.walkers import point_state_of


def _one(disc: Discretizer, x: float, y: float) -> int:
    return int(disc.state_of(np.array((x, y))))


@pytest.fixture
def lab() -> Discretizer:
    """38 random centres over a 9.3 x 2.7 m lab, as the benchmark lab has."""
    rng = np.random.default_rng(4)
    return Discretizer(rng.uniform((0.0, 0.0), (9.3, 2.7), size=(38, 2)), method="file")


def test_every_cell_centre_and_random_point_gets_the_nearest_centre(lab: Discretizer) -> None:
    grid = LabelGrid.of(lab, resolution=0.05)
    xs, ys = np.arange(-0.5, 9.8, 0.05) + 0.025, np.arange(-0.5, 3.2, 0.05) + 0.025
    for x, y in itertools.product(xs.tolist(), ys.tolist()):
        assert grid.state(x, y) == _one(lab, x, y)
    pts = np.random.default_rng(5).uniform((-1.0, -1.0), (10.3, 3.7), size=(20_000, 2))
    got = np.array([grid.state(x, y) for x, y in pts.tolist()])
    np.testing.assert_array_equal(got, lab.state_of(pts))  # no ties among random points


def test_most_cells_are_labelled_and_a_label_holds_for_the_whole_cell(lab: Discretizer) -> None:
    grid = LabelGrid.of(lab, resolution=0.02)
    rng = np.random.default_rng(6)
    pts = rng.uniform((0.0, 0.0), (9.3, 2.7), size=(3000, 2))
    for x, y in pts.tolist():
        grid.state(x, y)
    labels = dict(grid._labels)
    assert sum(v >= 0 for v in labels.values()) > 0.85 * len(labels)
    for (i, j), label in itertools.islice(labels.items(), 400):
        inside = (np.array([i, j]) + rng.random((50, 2))) * grid.resolution
        expected = lab.state_of(inside)
        if label >= 0:
            assert (expected == label).all()


def test_ties_break_as_the_discretizer_breaks_them() -> None:
    """A unit lattice: every point with a half-integer coordinate is an exact tie of two
    (or four) centres; the grid must defer those to the discretizer's own rule."""
    centres = np.array(list(itertools.product(range(4), range(3))), dtype=float)
    disc = Discretizer(centres, method="file")
    grid = LabelGrid.of(disc, resolution=0.01)
    ties = [(x + 0.5, y) for x in range(3) for y in np.linspace(0.0, 2.0, 41).tolist()]
    ties += [(x, y + 0.5) for y in range(2) for x in np.linspace(0.0, 3.0, 61).tolist()]
    ties += [(x + 0.5, y + 0.5) for x in range(3) for y in range(2)]  # four-way ties
    for x, y in ties:
        assert grid.state(x, y) == _one(disc, x, y)


def test_points_on_voronoi_edges_and_vertices_of_random_centres(lab: Discretizer) -> None:
    """Midpoints of centre pairs (on their bisector, up to rounding) and circumcentres of
    centre triples (Voronoi vertices when no other centre is nearer), with nudges of a
    few ulps to either side."""
    grid = LabelGrid.of(lab, resolution=0.01)
    c = lab.centres
    points = [((c[i] + c[j]) / 2).tolist() for i, j in itertools.combinations(range(38), 2)]
    for i, j, k in itertools.islice(itertools.combinations(range(38), 3), 0, 8000, 7):
        (ax, ay), (bx, by), (cx, cy) = c[i], c[j], c[k]
        d = 2 * (ax * (by - cy) + bx * (cy - ay) + cx * (ay - by))
        if abs(d) < 1e-9:
            continue
        ux = ((ax * ax + ay * ay) * (by - cy) + (bx * bx + by * by) * (cy - ay)
              + (cx * cx + cy * cy) * (ay - by)) / d
        uy = ((ax * ax + ay * ay) * (cx - bx) + (bx * bx + by * by) * (ax - cx)
              + (cx * cx + cy * cy) * (bx - ax)) / d
        points.append([ux, uy])
    for x, y in points:
        for dx, dy in ((0.0, 0.0), (1e-15, 0.0), (-1e-15, 0.0), (0.0, 1e-15)):
            px, py = x + dx, y + dy
            if math.isfinite(px) and abs(px) < 1e3 and abs(py) < 1e3:
                assert grid.state(px, py) == _one(lab, px, py)


def test_one_centre_is_every_point_s_state() -> None:
    grid = LabelGrid.of(Discretizer(np.array([[1.0, 2.0]]), method="file"))
    assert grid.state(-50.0, 7.0) == grid.state(1.0, 2.0) == 0


def test_bad_arguments_are_refused() -> None:
    with pytest.raises(ValueError, match="resolution"):
        LabelGrid(np.array([[0.0, 0.0], [1.0, 1.0]]), lambda x, y: 0, resolution=0.0)
    with pytest.raises(ValueError, match="centres"):
        LabelGrid(np.zeros((3,)), lambda x, y: 0)


def test_the_walker_asks_other_discretizers_directly() -> None:
    class Halves:
        """Not a nearest-centre partition: left and right of x = 0."""

        def state_of(self, xy):
            return (np.asarray(xy)[:, 0] > 0).astype(np.int64)

    state = point_state_of(Halves())
    assert state(-0.1, 5.0) == 0 and state(0.1, -5.0) == 1
    lab = Discretizer(np.array([[0.0, 0.0], [1.0, 0.0]]), method="file")
    assert point_state_of(lab)(0.2, 0.0) == 0 and point_state_of(lab)(0.9, 3.0) == 1
