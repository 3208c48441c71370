"""What a bag shows besides the robot: the Markov states' Voronoi cells, the goal areas and
a human, as ``visualization_msgs/msg/MarkerArray`` content (RViz, Foxglove).

The geometry here is plain numpy; :mod:`simlab.ros.bag` turns it into messages. A state
is the nearest centre of the robot's position (thesis 2.1.2, the Voronoi discretization),
so its cell is the set of points nearer to its centre than to any other: the intersection
of the half-planes bounded by the perpendicular bisectors, clipped here to a rectangle
(the arena's bounds).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class SceneMarkers:
    """Static scene content of a bag (all in the ``map`` frame, metres).

    ``centres`` (S, 2) state centres (None: no cells); ``bounds`` ``(x0, y0, x1, y1)``
    rectangle the cells are clipped to; ``goals`` ``(name, x, y, radius)`` per goal area.
    """

    centres: NDArray[np.float64] | None = None
    bounds: tuple[float, float, float, float] | None = None
    goals: tuple[tuple[str, float, float, float], ...] = ()


def _clip(poly: NDArray[np.float64], normal: NDArray[np.float64], offset: float
          ) -> NDArray[np.float64]:
    """The part of the convex polygon ``poly`` (k, 2) where ``normal . p <= offset``
    (one Sutherland-Hodgman step)."""
    if len(poly) == 0:
        return poly
    side = poly @ normal - offset
    out: list[NDArray[np.float64]] = []
    for i in range(len(poly)):
        j = (i + 1) % len(poly)
        if side[i] <= 0:
            out.append(poly[i])
        if (side[i] < 0 < side[j]) or (side[j] < 0 < side[i]):
            f = side[i] / (side[i] - side[j])
            out.append(poly[i] + f * (poly[j] - poly[i]))
    return np.array(out, dtype=np.float64).reshape(-1, 2)


def voronoi_cells(centres: NDArray[np.float64], bounds: tuple[float, float, float, float]
                  ) -> list[NDArray[np.float64]]:
    """Cell of each centre inside ``bounds`` as a convex polygon ``(k, 2)`` (counter-
    clockwise corners, metres; empty for a centre whose cell misses the rectangle).

    Cell ``i`` is the rectangle cut by ``|p - c_i| <= |p - c_j|`` for every ``j``, i.e.
    ``2 (c_j - c_i) . p <= |c_j|^2 - |c_i|^2``. O(S^2) half-plane cuts: fine for the few
    hundred states of a lab.
    """
    c = np.asarray(centres, dtype=np.float64)
    x0, y0, x1, y1 = (float(v) for v in bounds)
    box = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64)
    sq = np.sum(c * c, axis=1)
    cells = []
    for i in range(len(c)):
        poly = box
        for j in range(len(c)):
            if j != i and not np.array_equal(c[j], c[i]):
                poly = _clip(poly, 2.0 * (c[j] - c[i]), float(sq[j] - sq[i]))
        cells.append(poly)
    return cells
