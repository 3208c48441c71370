"""Social perception on the grid (thesis 2.1.2 and Fig. 2.7).

Percepts of a robot R and a human H, each with a cell and a body orientation
(a direction index 0-7, see :mod:`simlab.visitlab.actions`):

* **angle** — the direction R -> H quantised to the nearest of the 8 directions
  (45 deg sectors; an integer offset never lies on a sector boundary, since
  tan 22.5 deg is irrational, so the quantisation is unambiguous).
* **H sees R** — R lies within ``visual`` sectors (default 2, i.e. +-90 deg) of the
  human's orientation, measured on the quantised direction H -> R, and a sight line
  exists. **H looks at R** — within ``facing`` sectors (default 1, +-45 deg).
  **R looks at H** — the same test from the robot's orientation.
* **line of sight** — the straight segment between the two cell centres does not
  touch any wall segment (closed segments: a sight line through the end point of
  a wall is blocked; this matches the diagonal movement rule, which refuses a
  diagonal step past a wall corner). Symmetric.
* **distance class** 0-4: ``sum(d > b for b in bounds)`` for the distance ``d`` in
  the chosen metric. Thesis: Manhattan with bounds (1, 2, 3, 4): d <= 1 -> 0 too
  close, 2 -> 1, 3 -> 2, 4 -> 3 (appropriate), >= 5 -> 4 too far. Paper code:
  Chebyshev with bounds (1, 2, 4, 5): d <= 1, 2, 3-4, 5, >= 6.
* **percept level** 0-4 (the interaction levels that come from looks alone):
  4 H looks at R and R looks at H; 3 H sees R and R looks at H; 2 H looks at R;
  1 H sees R; 0 otherwise (first matching rule wins).

The paper's rules (Chartouny et al. 2024, sec. 2, as its published code applies them;
not compared with that code here), fields of :class:`Perception` switched on together by ``PAPER_PERCEPTION`` and settable one by one (the kernels read them from the same
array):

* ``continuous`` (rule 3) — sees / looks at are decided on the *continuous* bearing
  (inclusive +-``visual`` x 45 deg and +-``facing`` x 45 deg of the body
  orientation), not on the quantised direction (which makes the fields effectively
  +-112.5 / +-67.5 deg). The state's ``angle`` stays quantised.
* ``gaze_before_move``, ``gth_before_attention``, ``share_cells`` (rules 4-6): rules of
  the social dynamics, see :mod:`simlab.visitlab.dynamics`.

Kernels take the perception parameters as one int64 array (:meth:`Perception.to_array`)
and a line-of-sight table from :meth:`simlab.visitlab.grid.Layout.los_table`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from simlab.base.errors import ConfigError
from simlab.visitlab.actions import DIR_SECTOR, SECTOR_DIR

METRICS = ("manhattan", "chebyshev")

# Indices into the perception parameter array.
(P_METRIC, P_B0, P_B1, P_B2, P_B3, P_VISUAL, P_FACING, P_CONTINUOUS, P_GAZE_BEFORE,
 P_GTH_BEFORE, P_SHARE) = range(11)


@dataclass(frozen=True)
class Perception:
    """Distance classes and fields of view.

    Attributes:
        metric: ``"manhattan"`` (thesis) or ``"chebyshev"`` (paper code), in cells.
        bounds: four increasing upper bounds (cells) of distance classes 0-3; class 4
            is beyond the last one. Classes 1-3 are the *appropriate* distances.
        visual: half-width of the visual field, in 45 deg sectors (H sees R).
        facing: half-width of the facing field, in 45 deg sectors (looks at).
        continuous: paper rule 3 — fields tested on the continuous bearing (inclusive
            borders). Thesis (False): on the bearing quantised to 8 sectors.
        gaze_before_move: paper rule 4 — an engaged human's gaze aims at the robot's
            cell *before* the robot's move and is not re-aimed after the human moves.
            Thesis (False): aimed at the robot's new cell, re-aimed after following.
        gth_before_attention: paper rule 5 — GO_TO_HUMAN works only if the human was
            not engaged *before* this step's attention check, and it lands 2 cells
            along the human's gaze even on the human's own cell. Thesis (False): allowed
            if not engaged after the attention check; nothing happens if the landing
            cell is the human's.
        share_cells: paper rule 6 — robot and human may share a cell (moves are not
            blocked by the other agent, random placements may coincide) and an idle
            human's random turn picks among all 8 orientations (the current one too).
            Thesis (False): agents never share a cell; a turn picks one of the 7 others.
    """

    metric: str = "manhattan"
    bounds: tuple[int, int, int, int] = (1, 2, 3, 4)
    visual: int = 2
    facing: int = 1
    continuous: bool = False
    gaze_before_move: bool = False
    gth_before_attention: bool = False
    share_cells: bool = False

    def __post_init__(self) -> None:
        if self.metric not in METRICS:
            raise ConfigError(f"expected one of {METRICS}, got {self.metric!r}", key="metric")
        b = tuple(self.bounds)
        if len(b) != 4 or any(not isinstance(x, int | np.integer) for x in b):
            raise ConfigError(f"expected four integers, got {self.bounds!r}", key="bounds")
        if not (0 <= b[0] < b[1] < b[2] < b[3]):
            raise ConfigError(f"expected 0 <= b0 < b1 < b2 < b3, got {b}", key="bounds")
        object.__setattr__(self, "bounds", tuple(int(x) for x in b))
        if not 0 <= self.facing <= self.visual <= 4:
            raise ConfigError(
                f"expected 0 <= facing <= visual <= 4 sectors, got facing={self.facing}, "
                f"visual={self.visual}", key="visual")

        for key in ("continuous", "gaze_before_move", "gth_before_attention", "share_cells"):
            if not isinstance(getattr(self, key), bool | np.bool_):
                raise ConfigError(f"expected true or false, got {getattr(self, key)!r}",
                                  key=key)

    def to_array(self) -> np.ndarray:
        """Parameters for the kernels, int64 shape (11,): metric, bounds, visual, facing,
        then the four paper rules (0/1) in field order (``P_*`` indices)."""
        return np.array(
            [METRICS.index(self.metric), *self.bounds, self.visual, self.facing,
             self.continuous, self.gaze_before_move, self.gth_before_attention,
             self.share_cells], dtype=np.int64,
        )


THESIS_PERCEPTION = Perception("manhattan", (1, 2, 3, 4))
PAPER_PERCEPTION = Perception("chebyshev", (1, 2, 4, 5), continuous=True,
                              gaze_before_move=True, gth_before_attention=True,
                              share_cells=True)


def perception_for(variant: str) -> Perception:
    """The perception of a variant: ``"thesis"`` or ``"paper"``."""
    if variant == "thesis":
        return THESIS_PERCEPTION
    if variant == "paper":
        return PAPER_PERCEPTION
    raise ConfigError(f"expected 'thesis' or 'paper', got {variant!r}", key="variant")


# --------------------------------------------------------------------------- kernels


@njit(cache=True)
def direction_of(drow: int, dcol: int) -> int:
    """Direction index (0-7) nearest to the offset ``(drow, dcol)`` (rows grow down)."""
    theta = math.atan2(-drow, dcol)  # counter-clockwise from RIGHT, UP = +pi/2
    # theta / 45 deg lies in [-4, 4]; shift to positive so int() rounds half up
    sector = int(theta / (math.pi / 4.0) + 8.5) % 8
    return SECTOR_DIR[sector]


@njit(cache=True)
def direction_between(width: int, src: int, dst: int) -> int:
    """Quantised direction from cell ``src`` to cell ``dst`` (must differ)."""
    return direction_of(dst // width - src // width, dst % width - src % width)


@njit(cache=True)
def sector_gap(dir_a: int, dir_b: int) -> int:
    """Angular difference of two directions, in 45 deg sectors (0-4)."""
    d = abs(DIR_SECTOR[dir_a] - DIR_SECTOR[dir_b]) % 8
    return min(d, 8 - d)


@njit(cache=True)
def bearing_gap(orientation: int, drow: int, dcol: int) -> float:
    """Angle between direction ``orientation`` and the offset ``(drow, dcol)``, in units
    of 45 deg (continuous, 0-4). A zero offset (shared cell) has gap 0: in view."""
    if drow == 0 and dcol == 0:
        return 0.0
    theta = math.atan2(-drow, dcol) / (math.pi / 4.0)  # sectors, ccw from RIGHT
    d = abs(theta - DIR_SECTOR[orientation]) % 8.0
    return min(d, 8.0 - d)


@njit(cache=True)
def grid_distance(metric: int, drow: int, dcol: int) -> int:
    """Manhattan (``metric`` 0) or Chebyshev (1) length of an offset, in cells."""
    if metric == 0:
        return abs(drow) + abs(dcol)
    return max(abs(drow), abs(dcol))


@njit(cache=True)
def distance_class(pcfg: np.ndarray, width: int, cell_a: int, cell_b: int) -> int:
    """Distance class 0-4 between two cells (see the module docstring)."""
    d = grid_distance(pcfg[P_METRIC], cell_b // width - cell_a // width,
                      cell_b % width - cell_a % width)
    k = 0
    for i in range(4):
        if d > pcfg[P_B0 + i]:
            k += 1
    return k


@njit(cache=True)
def trace_line_of_sight(walls_h: np.ndarray, walls_v: np.ndarray, cell_a: int, cell_b: int) -> bool:
    """Whether the segment between the centres of two cells touches no wall.

    Exact integer arithmetic in doubled coordinates (cell centres at odd values,
    grid lines at even values).
    """
    width = walls_h.shape[1]
    height = walls_v.shape[0]
    r0 = cell_a // width
    c0 = cell_a % width
    r1 = cell_b // width
    c1 = cell_b % width
    x0 = 2 * c0 + 1
    y0 = 2 * r0 + 1
    dx = 2 * (c1 - c0)
    dy = 2 * (r1 - r0)
    # vertical grid lines x = k crossed by the segment
    if dx != 0:
        for k in range(min(c0, c1) + 1, max(c0, c1) + 1):
            num = y0 * dx + (2 * k - x0) * dy  # y (doubled) = num / dx
            den = dx
            if den < 0:
                num = -num
                den = -den
            if num % (2 * den) == 0:  # passes through the grid corner (k, y)
                row = num // (2 * den)
                if row - 1 >= 0 and walls_v[row - 1, k]:
                    return False
                if row < height and walls_v[row, k]:
                    return False
                if walls_h[row, k - 1] or (k < width and walls_h[row, k]):
                    return False
            elif walls_v[num // (2 * den), k]:
                return False
    # horizontal grid lines y = r crossed by the segment (corners handled above)
    if dy != 0:
        for r in range(min(r0, r1) + 1, max(r0, r1) + 1):
            num = x0 * dy + (2 * r - y0) * dx
            den = dy
            if den < 0:
                num = -num
                den = -den
            if num % (2 * den) != 0 and walls_h[r, num // (2 * den)]:
                return False
    return True


@njit(cache=True)
def build_los_table(walls_h: np.ndarray, walls_v: np.ndarray) -> np.ndarray:
    """Line of sight between every pair of cells, uint8 shape ``(n_cells, n_cells)``."""
    n = walls_v.shape[0] * walls_h.shape[1]
    out = np.ones((n, n), dtype=np.uint8)
    for a in range(n):
        for b in range(a + 1, n):
            v = 1 if trace_line_of_sight(walls_h, walls_v, a, b) else 0
            out[a, b] = v
            out[b, a] = v
    return out


@njit(cache=True)
def line_of_sight(
    walls_h: np.ndarray, walls_v: np.ndarray, los: np.ndarray, cell_a: int, cell_b: int
) -> bool:
    """Line of sight using the table ``los`` (``(1, 1)``: open grid; ``(0, 0)``: trace)."""
    if los.shape[0] == 1:
        return True
    if los.shape[0] == 0:
        return trace_line_of_sight(walls_h, walls_v, cell_a, cell_b)
    return los[cell_a, cell_b] != 0


@njit(cache=True, inline="always")
def percept_level(h_sees: bool, h_looks: bool, r_looks: bool) -> int:
    """The percept level 0-4 (thesis 2.1.2) from who sees whom: 4 both look at each other,
    3 the human sees a robot that looks at it, 2 the human looks at the robot, 1 the human
    sees it, 0 not perceived. Shared by the grid and the physics social task."""
    if h_looks and r_looks:
        return 4
    if h_sees and r_looks:
        return 3
    if h_looks:
        return 2
    if h_sees:
        return 1
    return 0


@njit(cache=True)
def percepts(
    walls_h: np.ndarray,
    walls_v: np.ndarray,
    los: np.ndarray,
    pcfg: np.ndarray,
    robot: int,
    robot_ori: int,
    human: int,
    human_ori: int,
) -> tuple[int, int, int, bool, bool, bool]:
    """``(level, distance_class, angle, h_sees_r, h_looks_at_r, r_looks_at_h)``.

    ``angle`` is the quantised direction robot -> human; ``level`` the percept level
    0-4. On a shared cell (paper rule 6) the bearing is 0: angle RIGHT, in view.
    """
    width = walls_h.shape[1]
    drow = human // width - robot // width
    dcol = human % width - robot % width
    angle = direction_of(drow, dcol)
    to_robot = direction_of(-drow, -dcol)
    d = grid_distance(pcfg[P_METRIC], drow, dcol)
    dist = 0
    for i in range(4):
        if d > pcfg[P_B0 + i]:
            dist += 1
    visible = line_of_sight(walls_h, walls_v, los, robot, human)
    if pcfg[P_CONTINUOUS] != 0:
        h_gap = bearing_gap(human_ori, -drow, -dcol)
        h_sees = visible and h_gap <= pcfg[P_VISUAL] + 1e-9
        h_looks = visible and h_gap <= pcfg[P_FACING] + 1e-9
        r_looks = visible and bearing_gap(robot_ori, drow, dcol) <= pcfg[P_FACING] + 1e-9
    else:
        h_gap = sector_gap(human_ori, to_robot)
        h_sees = visible and h_gap <= pcfg[P_VISUAL]
        h_looks = visible and h_gap <= pcfg[P_FACING]
        r_looks = visible and sector_gap(robot_ori, angle) <= pcfg[P_FACING]
    return percept_level(h_sees, h_looks, r_looks), dist, angle, h_sees, h_looks, r_looks



@njit(cache=True)
def field_of_view(
    walls_h: np.ndarray,
    walls_v: np.ndarray,
    los: np.ndarray,
    origin: int,
    orientation: int,
    half_width: int,
) -> np.ndarray:
    """Cells within ``half_width`` sectors of ``orientation`` seen from ``origin``.

    uint8 shape ``(n_cells,)``; the origin cell itself is 0. Same rule as the
    percepts (quantised direction, line of sight); used by the renders.
    """
    width = walls_h.shape[1]
    n = walls_v.shape[0] * width
    out = np.zeros(n, dtype=np.uint8)
    for cell in range(n):
        if cell == origin:
            continue
        d = direction_between(width, origin, cell)
        if sector_gap(orientation, d) <= half_width and line_of_sight(
            walls_h, walls_v, los, origin, cell
        ):
            out[cell] = 1
    return out
