"""Social perception on the table from continuous poses (thesis 2.1.2 and Fig. 2.7).

Inputs are the robot's pose ``(x, y, yaw)`` and the human's pose ``(x, y, theta)``
(m, m, rad, map frame, angles counter-clockwise from +x). Outputs are the percepts the
grid's social module uses (:mod:`simlab.visitlab.perception`), computed as in its
paper-variant ``continuous=True`` path (the continuous bearing of the code published with
Chartouny et al. 2024):

* **bearing** — the continuous direction from one agent to the other (rad).
* **H sees R** — the bearing human -> robot lies within the *inclusive* visual field
  ``+-visual_deg`` (default 90 deg) of the human's body orientation, and a sight line
  exists. **H looks at R** — within the facing field ``+-facing_deg`` (45 deg).
  **R looks at H** — the bearing robot -> human within ``+-facing_deg`` of the robot's yaw.
  Borders are inclusive up to ``ANGLE_TOL`` (1e-9 rad), so a robot exactly at 90 deg is
  seen and one at 90.1 deg is not.
* **line of sight** — one PyBullet ray in the LIDAR plane (the height of the robot's
  scanner above the floor), cast *from the human to the robot*, in the world's own client:
  the sight line is clear when the ray hits nothing or hits the robot's own body first
  (walls and obstacles are the only other bodies; the human has no body). Casting toward
  the robot avoids starting the ray inside the robot's collision shape.
* **angle** — the bearing robot -> human quantised to the nearest of the 8 directions of
  :class:`simlab.base.directions.Direction` (map frame, UP = +y; headings
  :data:`simlab.base.actions.HEADINGS`); this is the grid's angle, whose UP is "row - 1",
  i.e. up on the screen, as +y is on the table's top-down view. A bearing exactly between
  two directions goes to the counter-clockwise one (the grid rounds half up the same way).
* **distance class** 0-4: ``sum(d > b for b in bounds_m)`` for the Euclidean centre
  distance ``d`` (m). Decision: Euclidean, not Manhattan/Chebyshev — poses are continuous
  and the class should not depend on the map's axes. Defaults ``bounds_m = (0.15, 0.30,
  0.45, 0.60)``: the thesis's Manhattan bounds (1, 2, 3, 4) cells times the default
  ``cell_size`` of :mod:`simlab.social.human` (0.15 m: the 1.5 m table is a 10 x 10 grid).
  So class 0 (too close, <= 0.15 m) is about the robot's and a human disc's radii touching,
  classes 1-3 (0.15-0.60 m) are appropriate, class 4 (> 0.60 m) is too far: across the
  table's half width.
* **percept level** 0-4: 4 H looks at R and R looks at H; 3 H sees R and R looks at H;
  2 H looks at R; 1 H sees R; 0 otherwise (first matching rule wins, as on the grid).

The social observation index is the grid's: ``((level * 5 + distance) * 8 +
required_direction) * 8 + angle`` over :data:`SOCIAL_DIMS` ``(8, 5, 8, 8)`` (the same as
``simlab.visitlab.dynamics.SOCIAL_DIMS``; re-stated here so this package does not import
the grid's kernels), so a Q-table trained on the grid reads these states.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.base import validation
from simlab.base.actions import HEADINGS
from simlab.base.errors import ConfigError
from simlab.physics.robot import wrap_angle
from simlab.visitlab.perception import percept_level

#: Social observation dims (interaction 0-7, distance 0-4, required direction, angle).
SOCIAL_DIMS = (8, 5, 8, 8)
N_SOCIAL_STATES = 2560
#: Tolerance (rad) of the inclusive field borders.
ANGLE_TOL = 1e-9

# Direction index of each 45 deg sector counter-clockwise from +x, built from HEADINGS
# (sector k has heading k * 45 deg).
_SECTOR_DIR = np.array(
    [int(np.argmin(np.abs(wrap_angle(HEADINGS - k * math.pi / 4)))) for k in range(8)],
    dtype=np.int64,
)


@dataclass(frozen=True)
class SocialPerception:
    """Fields of view and distance classes of the physics social task.

    Attributes:
        visual_deg: half-width (deg) of the human's visual field (H sees R); thesis +-90.
        facing_deg: half-width (deg) of the facing field (looks at); thesis +-45.
        bounds_m: four increasing upper bounds (m, inclusive) of distance classes 0-3;
            class 4 is beyond the last. Classes 1-3 are the appropriate distances.
    """

    visual_deg: float = 90.0
    facing_deg: float = 45.0
    bounds_m: tuple[float, float, float, float] = (0.15, 0.30, 0.45, 0.60)

    def __post_init__(self) -> None:
        validation.number(self.visual_deg, "SocialPerception.visual_deg", low=0.0, high=180.0)
        validation.number(self.facing_deg, "SocialPerception.facing_deg", low=0.0,
                          high=float(self.visual_deg))
        try:
            b = tuple(float(x) for x in self.bounds_m)
        except (TypeError, ValueError):
            raise ConfigError(f"expected four numbers, got {self.bounds_m!r}",
                              key="SocialPerception.bounds_m") from None
        if len(b) != 4 or not (0.0 <= b[0] < b[1] < b[2] < b[3]) or not all(
                math.isfinite(x) for x in b):
            raise ConfigError(f"expected 0 <= b0 < b1 < b2 < b3 (m), got {self.bounds_m!r}",
                              key="SocialPerception.bounds_m",
                              fix="e.g. (0.15, 0.30, 0.45, 0.60)")
        object.__setattr__(self, "bounds_m", b)

    @property
    def visual(self) -> float:
        """Visual half-width (rad)."""
        return math.radians(self.visual_deg)

    @property
    def facing(self) -> float:
        """Facing half-width (rad)."""
        return math.radians(self.facing_deg)


@dataclass(frozen=True)
class Percepts:
    """What the robot and the human perceive of each other.

    ``level`` percept level 0-4; ``distance_class`` 0-4; ``angle`` direction index 0-7
    of the bearing robot -> human; ``distance`` (m); ``visible`` line of sight;
    ``h_sees``, ``h_looks``, ``r_looks`` the field tests (with line of sight).
    """

    level: int
    distance_class: int
    angle: int
    distance: float
    visible: bool
    h_sees: bool
    h_looks: bool
    r_looks: bool

    @property
    def appropriate(self) -> bool:
        """Distance class 1-3."""
        return 1 <= self.distance_class <= 3


def bearing(src: NDArray[np.float64] | tuple[float, ...],
            dst: NDArray[np.float64] | tuple[float, ...]) -> float:
    """Direction (rad, in [-pi, pi]) from point ``src`` (x, y, ...) to ``dst``."""
    return math.atan2(float(dst[1]) - float(src[1]), float(dst[0]) - float(src[0]))


def angle_gap(a: float, b: float) -> float:
    """Absolute angular difference (rad, 0..pi) of two angles."""
    d = abs(float(a) - float(b)) % (2.0 * math.pi)
    return min(d, 2.0 * math.pi - d)


def in_field(orientation: float, direction: float, half_width: float) -> bool:
    """Whether ``direction`` (rad) lies within the inclusive ``+-half_width`` (rad) of
    ``orientation`` (rad)."""
    return angle_gap(orientation, direction) <= half_width + ANGLE_TOL


def quantise_direction(theta: float) -> int:
    """Direction index 0-7 (:class:`~simlab.base.directions.Direction`) nearest to the map-frame
    angle ``theta`` (rad); halfway angles go counter-clockwise."""
    sector = math.floor(float(theta) / (math.pi / 4.0) + 0.5) % 8
    return int(_SECTOR_DIR[sector])


def distance_class(distance: float, perception: SocialPerception) -> int:
    """Distance class 0-4 of a centre distance (m): ``sum(d > b)`` over the bounds."""
    return sum(1 for b in perception.bounds_m if distance > b)


def line_of_sight(world: Any, human_xy: NDArray[np.float64] | tuple[float, float],
                  robot_xy: NDArray[np.float64] | tuple[float, float] | None = None,
                  ignore: int | None = None) -> bool:
    """Whether the segment human -> robot in the LIDAR plane hits no wall or obstacle.

    ``world`` is a :class:`~simlab.physics.world.World`; ``robot_xy`` defaults to the
    robot's true position. One ray in the world's client (see the module docstring).
    ``ignore``: a body id whose hits do not block (the human's own TurtleBot body).
    """
    if robot_xy is None:
        robot_xy = world.pose()[:2]
    z = float(world.robot_spec.lidar_offset[2])
    hx, hy = float(human_xy[0]), float(human_xy[1])
    rx, ry = float(robot_xy[0]), float(robot_xy[1])
    if math.hypot(rx - hx, ry - hy) < 1e-9:
        return True
    hit = world.client.rayTest([hx, hy, z], [rx, ry, z])[0]
    return hit[0] < 0 or hit[0] == world.body or (ignore is not None and hit[0] == ignore)


def percepts(robot_pose: NDArray[np.float64] | tuple[float, float, float],
             human_pose: NDArray[np.float64] | tuple[float, float, float],
             visible: bool, perception: SocialPerception | None = None) -> Percepts:
    """Percepts of a robot and a human (poses (3,): x, y, angle; m, m, rad).

    ``visible`` is the line of sight (:func:`line_of_sight`, or True on an open table).
    Coincident positions have bearing 0 (+x), as the grid's shared cell.
    """
    p = perception or SocialPerception()
    d = math.hypot(float(human_pose[0]) - float(robot_pose[0]),
                   float(human_pose[1]) - float(robot_pose[1]))
    to_human = bearing(robot_pose, human_pose) if d > 0 else 0.0
    to_robot = bearing(human_pose, robot_pose) if d > 0 else 0.0
    h_sees = visible and in_field(human_pose[2], to_robot, p.visual)
    h_looks = visible and in_field(human_pose[2], to_robot, p.facing)
    r_looks = visible and in_field(robot_pose[2], to_human, p.facing)
    level = int(percept_level(bool(h_sees), bool(h_looks), bool(r_looks)))
    return Percepts(level=level, distance_class=distance_class(d, p),
                    angle=quantise_direction(to_human), distance=d, visible=bool(visible),
                    h_sees=bool(h_sees), h_looks=bool(h_looks), r_looks=bool(r_looks))


def robot_percepts(robot_estimate: NDArray[np.float64] | tuple[float, float, float],
                   human_pose: NDArray[np.float64] | tuple[float, float, float],
                   truth: Percepts, perception: SocialPerception | None = None) -> Percepts:
    """The robot's percepts when it believes its pose is ``robot_estimate`` (3,).

    The robot's side - ``distance`` and its class, ``angle`` (the bearing from the
    estimate to the human's position), ``r_looks`` (that bearing within the facing field
    of the estimated yaw) - comes from the estimate; the human's side (``h_sees``,
    ``h_looks``) and the line of sight ``visible`` from ``truth`` (the percepts of the
    true poses, :func:`percepts`). The level combines them (:func:`percept_level`).
    With the true pose as the estimate the result equals ``truth``.
    """
    p = perception or SocialPerception()
    d = math.hypot(float(human_pose[0]) - float(robot_estimate[0]),
                   float(human_pose[1]) - float(robot_estimate[1]))
    to_human = bearing(robot_estimate, human_pose) if d > 0 else 0.0
    r_looks = truth.visible and in_field(robot_estimate[2], to_human, p.facing)
    level = int(percept_level(truth.h_sees, truth.h_looks, bool(r_looks)))
    return Percepts(level=level, distance_class=distance_class(d, p),
                    angle=quantise_direction(to_human), distance=d, visible=truth.visible,
                    h_sees=truth.h_sees, h_looks=truth.h_looks, r_looks=bool(r_looks))


def social_obs_index(level: int, distance: int, required_direction: int, angle: int) -> int:
    """Social observation 0-2559, the grid's ``ravel_multi_index`` over SOCIAL_DIMS."""
    values = (level, distance, required_direction, angle)
    for v, n, name in zip(values, SOCIAL_DIMS, ("level", "distance", "direction", "angle"),
                          strict=True):
        if not 0 <= int(v) < n:
            raise ValueError(f"{name} must be in 0..{n - 1}, got {v}")
    return int(((int(level) * 5 + int(distance)) * 8 + int(required_direction)) * 8 + int(angle))
