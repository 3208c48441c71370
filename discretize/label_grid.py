"""The state of one point at a time, from a grid of cell labels filled as the robot goes.

A robot that drives until its state changes asks for the state of its position at every
control tick (10 Hz), one point at a time. :class:`LabelGrid` answers most of those asks
with a dictionary lookup and gives exactly the answer of the nearest-centre search
(:meth:`discretize.voronoi.Discretizer.state_of`) for every point:

* the plane is cut into square cells of ``resolution`` metres; a cell is labelled, on the
  first ask that falls in it, with the state of its centre if that state is provably the
  nearest for *every* point of the cell, else with -1;
* the proof: with ``d1`` and ``d2`` the distances from the cell's centre to the nearest and
  the second-nearest centre and ``h`` the cell's half-diagonal, every point of the cell is
  within ``d1 + h`` of the nearest centre and beyond ``d2 - h`` of every other, so
  ``d2 - d1 > 2 h`` (plus a slack of ``2e-6`` m for the rounding of the cell index and of
  the distances) leaves no tie to break and no other answer;
* a point in a -1 cell (within about a half-diagonal of a Voronoi boundary) is answered by
  the exact search, so boundary ties break as that search breaks them.

Cells are labelled lazily (a walk visits a small part of a large map) and kept in a
dictionary: at 1 cm, a 9 x 3 m lab has at most 270,000 of them.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

__all__ = ["LabelGrid"]

#: Slack (m) of the labelling proof: the rounding of a cell index (~1e-16 of a coordinate)
#: and of the distances, with room to spare for maps of kilometres.
SLACK = 1e-6


class LabelGrid:
    """Exact state of single points ``(x, y)`` (m) of a nearest-centre partition.

    Args:
        centres: ``(N, 2)`` float64 centres (m); state ``i`` is the cell of ``centres[i]``.
        exact: the exact state of one point, ``exact(x, y) -> int``, asked for points near
            a boundary; it must be the nearest-centre partition of ``centres``.
        resolution: side of the label cells (m).
    """

    def __init__(self, centres: NDArray[np.float64], exact: Callable[[float, float], int],
                 resolution: float = 0.01) -> None:
        c = np.asarray(centres, dtype=np.float64)
        if c.ndim != 2 or c.shape[1] != 2 or c.shape[0] < 1:
            raise ValueError(f"centres: expected a non-empty (N, 2) array, got shape {c.shape}")
        if not resolution > 0:
            raise ValueError(f"resolution must be > 0 m, got {resolution}")
        self._cx, self._cy = c[:, 0].copy(), c[:, 1].copy()
        self._exact = exact
        self.resolution = float(resolution)
        self._inv = 1.0 / self.resolution
        self._clear = 2.0 * self.resolution * math.sqrt(0.5) + 2.0 * SLACK
        self._labels: dict[tuple[int, int], int] = {}

    @classmethod
    def of(cls, discretizer: object, resolution: float = 0.01) -> LabelGrid:
        """The grid of a :class:`~discretize.voronoi.Discretizer` (its ``state_of`` is the
        exact search)."""
        state_of = discretizer.state_of  # type: ignore[attr-defined]

        def exact(x: float, y: float) -> int:
            return int(state_of(np.array((x, y))))

        return cls(discretizer.centres, exact, resolution)  # type: ignore[attr-defined]

    def state(self, x: float, y: float) -> int:
        """The state of the point ``(x, y)`` (m, finite floats)."""
        key = (math.floor(x * self._inv), math.floor(y * self._inv))
        label = self._labels.get(key)
        if label is None:
            label = self._labels[key] = self._label(*key)
        if label >= 0:
            return label
        return self._exact(x, y)

    def _label(self, i: int, j: int) -> int:
        """The state of every point of cell ``(i, j)``, or -1 when it is not provably one."""
        if self._cx.shape[0] == 1:
            return 0
        x, y = (i + 0.5) * self.resolution, (j + 0.5) * self.resolution
        d = np.hypot(self._cx - x, self._cy - y)
        two = np.argpartition(d, 1)[:2]
        near, second = (two[0], two[1]) if d[two[0]] <= d[two[1]] else (two[1], two[0])
        return int(near) if d[second] - d[near] > self._clear else -1

    @property
    def cells(self) -> int:
        """Number of cells labelled so far."""
        return len(self._labels)
