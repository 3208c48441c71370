"""The doorway of a passage between two states: where a box closes it in physics.

Dromnelle et al. (2022, sec. 4.1) close a passage of the lab while the robot learns (the
transitions between two neighbouring states disappear). In simlab's physics the passage
``u <-> v`` is closed by a box standing on its doorway: the free part of the boundary
between the two states' cells, on the perpendicular bisector of their centres (the
boundary of two Voronoi cells). The box spans the free run of that boundary nearest the
centres' midpoint, reaching ``overlap`` metres into the walls at both ends so that no gap
is left beside it, and is ``thickness`` metres deep.

Decision: the boundary is sampled every ``step`` metres along the bisector; a sample
belongs to the doorway when its nearest centre is ``u`` or ``v`` (no third cell is
closer) and the arena is free there. Cells that share no free boundary have no passage to
close (a :class:`~simlab.base.errors.ConfigError` naming them).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from simlab.base.errors import ConfigError

__all__ = ["Doorway", "doorway"]


@dataclass(frozen=True)
class Doorway:
    """A box across a passage: centre ``x``, ``y`` (m), ``length`` along the doorway and
    ``thickness`` across it (m), ``yaw`` (rad) of its length; ``free_width`` is the free
    width of the doorway itself (m)."""

    x: float
    y: float
    length: float
    thickness: float
    yaw: float
    free_width: float

    def as_dict(self) -> dict[str, float]:
        return {k: round(float(getattr(self, k)), 4) for k in self.__dataclass_fields__}


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[start, end)`` index runs of True in a 1-D bool array."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def doorway(occupied: Callable[[np.ndarray], np.ndarray], state_of: Callable[[np.ndarray], Any],
            centres: np.ndarray, u: int, v: int, *, thickness: float = 0.05,
            overlap: float = 0.03, step: float = 0.01, reach: float = 3.0) -> Doorway:
    """The :class:`Doorway` of the passage between states ``u`` and ``v`` (module docstring).

    ``occupied(xy (N, 2)) -> (N,)`` bool (an arena's :meth:`occupied`), ``state_of(xy (N, 2))
    -> (N,)`` the states of positions, ``centres`` (S, 2) m; the bisector is searched
    ``reach`` m either side of the midpoint."""
    u, v = min(u, v), max(u, v)  # one passage, whichever way it is named
    cu, cv = np.asarray(centres[u], float), np.asarray(centres[v], float)
    d = cv - cu
    if not np.linalg.norm(d) > 0:
        raise ConfigError(f"states {u} and {v} have the same centre", key="passages")
    along = np.array([-d[1], d[0]]) / np.linalg.norm(d)
    mid = (cu + cv) / 2
    offsets = np.arange(-reach, reach + step / 2, step)
    pts = mid + offsets[:, None] * along
    # a bisector point is equidistant from u and v: just off it on u's side it must be
    # u's, just off it on v's side v's (no third cell closer), and free
    nudge = 1e-6 * d / np.linalg.norm(d)
    ok = ((np.asarray(state_of(pts - nudge)) == u) & (np.asarray(state_of(pts + nudge)) == v)
          & ~np.asarray(occupied(pts), dtype=bool))
    runs = _runs(ok)
    if not runs:
        raise ConfigError(f"states {u} and {v} share no free boundary: there is no passage "
                          "between them to close", key="passages",
                          fix="name two neighbouring states whose cells touch in free space")
    centre_index = int(np.argmin(np.abs(offsets)))
    a, b = min(runs, key=lambda r: 0 if r[0] <= centre_index < r[1] else
               min(abs(r[0] - centre_index), abs(r[1] - 1 - centre_index)))
    lo, hi = offsets[a] - step / 2, offsets[b - 1] + step / 2
    centre = mid + (lo + hi) / 2 * along
    return Doorway(x=float(centre[0]), y=float(centre[1]), length=float(hi - lo + 2 * overlap),
                   thickness=float(thickness), yaw=float(math.atan2(along[1], along[0])),
                   free_width=float(hi - lo))
