"""Top-down pictures of an arena: floor, walls, obstacles, goal areas, robot, trail, scan.

Drawn in 2-D with OpenCV (fast, headless, exact geometry) rather than with PyBullet's
camera. :class:`TopDown` is a small canvas other figures build on (the replay video adds a
value heat map under the robot); :func:`render_topdown` draws the usual picture in one call.
Images are RGB ``uint8`` arrays (H, W, 3).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np
from numpy.typing import NDArray

from simlab.physics.arena import ArenaConfig
from simlab.physics.robot import RobotSpec

FLOOR = (238, 232, 220)
WALL = (150, 120, 90)
OBSTACLE = (110, 110, 130)
GOAL = (120, 190, 120)
GOAL_ACTIVE = (40, 160, 60)
ROBOT = (40, 40, 48)
HEADING = (240, 200, 40)
TRAIL = (220, 170, 0)
SCAN = (220, 40, 40)


class TopDown:
    """A canvas mapping arena coordinates (m) to pixels, y up.

    ``pixels_per_metre`` sets the scale; the canvas covers the arena including its walls
    plus ``pad`` metres.
    """

    def __init__(self, arena: ArenaConfig, pixels_per_metre: float = 320.0, pad: float = 0.02):
        self.arena = arena
        x0, y0, x1, y1 = arena.bounds
        t = arena.wall_thickness + pad
        self.x0, self.y1 = x0 - t, y1 + t
        self.scale = float(pixels_per_metre)
        self.width = math.ceil((x1 - x0 + 2 * t) * self.scale)
        self.height = math.ceil((y1 - y0 + 2 * t) * self.scale)
        self.image = np.full((self.height, self.width, 3), 255, dtype=np.uint8)

    def px(self, xy: NDArray[np.float64] | Sequence[float]) -> NDArray[np.int32]:
        """Pixel coordinates (col, row) of points ``xy`` (..., 2)."""
        p = np.asarray(xy, dtype=float)
        col = (p[..., 0] - self.x0) * self.scale
        row = (self.y1 - p[..., 1]) * self.scale
        return np.stack([col, row], axis=-1).round().astype(np.int32)

    def metres(self, d: float) -> int:
        return max(1, round(d * self.scale))

    def draw_arena(self, active_goal: str | None = None, goals: bool = True,
                   floor: bool = True) -> TopDown:
        a = self.arena
        x0, y0, x1, y1 = a.bounds
        t = a.wall_thickness
        cv2.rectangle(self.image, tuple(self.px([x0 - t, y1 + t])), tuple(self.px([x1 + t, y0 - t])),
                      WALL, -1)
        if floor:
            cv2.rectangle(self.image, tuple(self.px([x0, y1])), tuple(self.px([x1, y0])), FLOOR, -1)
        if a.map_walls is not None:
            for bx0, by0, bx1, by1 in a.map_walls.boxes:
                cv2.rectangle(self.image, tuple(self.px([bx0, by1])),
                              tuple(self.px([bx1, by0])), WALL, -1)
        if goals:
            self.draw_goals(active_goal)
        for ob in a.obstacles:
            if ob.kind == "cylinder":
                cv2.circle(self.image, tuple(self.px([ob.x, ob.y])), self.metres(ob.radius),
                           OBSTACLE, -1, cv2.LINE_AA)
            else:
                c, s = math.cos(ob.yaw), math.sin(ob.yaw)
                hx, hy = ob.size[0] / 2, ob.size[1] / 2
                corners = [(ob.x + c * u - s * v, ob.y + s * u + c * v)
                           for u, v in ((-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy))]
                cv2.fillPoly(self.image, [self.px(corners)], OBSTACLE, cv2.LINE_AA)
        return self

    def draw_goals(self, active_goal: str | None = None, labels: bool = True) -> TopDown:
        for g in self.arena.goals:
            active = g.name == active_goal
            centre = tuple(self.px([g.x, g.y]))
            cv2.circle(self.image, centre, self.metres(g.radius), GOAL_ACTIVE if active else GOAL,
                       3 if active else 1, cv2.LINE_AA)
            if labels:
                cv2.putText(self.image, g.name, (centre[0] - 8, centre[1] + 5),
                            cv2.FONT_HERSHEY_SIMPLEX, 0.4, GOAL_ACTIVE if active else GOAL, 1,
                            cv2.LINE_AA)
        return self

    def draw_trail(self, xy: NDArray[np.float64], color: tuple[int, int, int] = TRAIL,
                   thickness: int = 2) -> TopDown:
        if len(xy) >= 2:
            cv2.polylines(self.image, [self.px(np.asarray(xy)[:, :2])], False, color, thickness,
                          cv2.LINE_AA)
        return self

    def draw_points(self, xy: NDArray[np.float64], color: tuple[int, int, int] = SCAN,
                    radius: int = 2) -> TopDown:
        for p in self.px(np.asarray(xy).reshape(-1, 2)):
            cv2.circle(self.image, tuple(p), radius, color, -1)
        return self

    def draw_robot(self, pose: Sequence[float], spec: RobotSpec,
                   color: tuple[int, int, int] = ROBOT) -> TopDown:
        x, y, th = (float(v) for v in pose)
        fx0, fx1, fy0, fy1 = spec.footprint
        c, s = math.cos(th), math.sin(th)
        corners = [(x + c * u - s * v, y + s * u + c * v)
                   for u, v in ((fx0, fy0), (fx1, fy0), (fx1, fy1), (fx0, fy1))]
        cv2.fillPoly(self.image, [self.px(corners)], color, cv2.LINE_AA)
        tip = (x + c * (fx1 + 0.05), y + s * (fx1 + 0.05))
        cv2.arrowedLine(self.image, tuple(self.px([x, y])), tuple(self.px(tip)), HEADING, 2,
                        cv2.LINE_AA, tipLength=0.35)
        return self


def render_topdown(
    arena: ArenaConfig,
    spec: RobotSpec,
    pose: Sequence[float],
    *,
    trail: NDArray[np.float64] | None = None,
    scan_points: NDArray[np.float64] | None = None,
    active_goal: str | None = None,
    pixels_per_metre: float = 320.0,
) -> NDArray[np.uint8]:
    """The arena with the robot at ``pose``, an optional trail (k, 2+) and scan points (m, 2)."""
    canvas = TopDown(arena, pixels_per_metre).draw_arena(active_goal)
    if trail is not None:
        canvas.draw_trail(trail)
    if scan_points is not None:
        canvas.draw_points(scan_points)
    canvas.draw_robot(pose, spec)
    return canvas.image


def draw_arena_on(ax: object, arena: ArenaConfig) -> tuple[float, float, float, float]:
    """Draw ``arena``'s occupied floor (walls, map walls, obstacles) in grey on matplotlib
    axes ``ax``, in the arena's own frame (metres, y up), and return its bounds
    ``(x0, y0, x1, y1)``: the background of the figures that draw states and moves on the
    lab (2 cm pixels on a small arena, 5 cm on a larger one)."""
    x0, y0, x1, y1 = arena.bounds
    res = 0.02 if max(x1 - x0, y1 - y0) < 4 else 0.05
    shape = (int(np.ceil((y1 - y0) / res)), int(np.ceil((x1 - x0) / res)))
    occ = arena.rasterize(res, (x0, y0), shape)  # row 0 the top: imshow's default origin
    ax.imshow(occ, cmap="Greys", extent=(x0, x0 + shape[1] * res, y0, y0 + shape[0] * res),
              vmin=0, vmax=1.6, interpolation="nearest")
    return x0, y0, x1, y1
