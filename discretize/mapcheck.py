"""Check points (state centres, logged poses) against an occupancy map, helpfully.

A real robot's centres or poses that land on walls or in unknown space usually mean one
systematic mistake, not one bad point: another frame, other units, or a map image stored
bottom row first (some GMapping exports). So the check lists **every** bad point (outside
the image, on an occupied pixel, on an unknown pixel), and when most of them become free
once the image is flipped vertically it says so and names the fix (``--flip-y``).

Decision: "occupied" is any occupancy > 0 (intermediate ``scale`` values included), as
the discretizer's free space is occupancy 0 only; "most" is more than half of the bad
points, with fewer bad points overall after the flip.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from discretize.gridmap import FREE, UNKNOWN, OccupancyMap

#: Most bad points listed in full in a message (the count is always given).
MAX_LISTED = 60


def _status(grid: OccupancyMap, xy: NDArray[np.float64]) -> NDArray[np.int8]:
    """Per point: 0 free, 1 occupied, 2 unknown, 3 outside the image."""
    rc = grid.world_to_pixel(xy)
    inside = grid.in_bounds(rc)
    status = np.full(len(xy), 3, dtype=np.int8)
    occ = grid.occupancy[rc[inside, 0], rc[inside, 1]]
    status[inside] = np.where(occ == FREE, 0, np.where(occ == UNKNOWN, 2, 1))
    return status


_WORDS = ("free", "occupied", "unknown", "outside the map")


@dataclass(frozen=True)
class PointCheck:
    """Result of :func:`check_points`.

    Attributes:
        xy: ``(N, 2)`` the points (m).
        status: ``(N,)`` 0 free, 1 occupied pixel, 2 unknown pixel, 3 outside the image.
        free_if_flipped: ``(N,)`` bool, free on the vertically flipped image.
        what: what a point is, for messages (``centre``, ``pose``).
    """

    xy: NDArray[np.float64]
    status: NDArray[np.int8]
    free_if_flipped: NDArray[np.bool_]
    what: str = "centre"

    @property
    def bad(self) -> NDArray[np.int64]:
        """Indices of the points not on free pixels."""
        return np.flatnonzero(self.status != 0)

    @property
    def ok(self) -> bool:
        return self.bad.size == 0

    @property
    def flip_suggested(self) -> bool:
        """Most bad points are free, and fewer points are bad, on the flipped image."""
        bad = self.bad
        freed = int(self.free_if_flipped[bad].sum())
        return bool(bad.size and 2 * freed > bad.size
                    and int((~self.free_if_flipped).sum()) < bad.size)

    def message(self) -> str:
        """One line: how many, every bad point with its index and pixel class, the hint."""
        bad = self.bad
        items = [f"{self.what} {k} ({self.xy[k, 0]:g}, {self.xy[k, 1]:g}) "
                 f"{_WORDS[self.status[k]]}" for k in bad[:MAX_LISTED]]
        more = f"; and {bad.size - MAX_LISTED} more" if bad.size > MAX_LISTED else ""
        text = (f"{bad.size} of {len(self.xy)} {self.what}s are not on free pixels of the "
                f"map: " + "; ".join(items) + more)
        if self.flip_suggested:
            freed = int(self.free_if_flipped[bad].sum())
            text += (f". {freed} of these {bad.size} are free when the map image is flipped "
                     "vertically: the image is probably stored bottom row first; try "
                     "--flip-y")
        return text


def check_points(grid: OccupancyMap, xy: NDArray[np.float64], *, what: str = "centre"
                 ) -> PointCheck:
    """Classify every point ``xy`` ``(N, 2)`` (m, map frame) against ``grid``."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    flipped = OccupancyMap(occupancy=grid.occupancy[::-1], resolution=grid.resolution,
                           origin=grid.origin)
    return PointCheck(xy=xy, status=_status(grid, xy),
                      free_if_flipped=_status(flipped, xy) == 0, what=what)
