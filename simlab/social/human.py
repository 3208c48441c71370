"""A kinematic human on the table (thesis 2.1.2 and Table 4.1).

The human is a disc projected on the floor: a position ``(x, y)`` (m), a body orientation
``theta`` (rad, map frame) and, in :mod:`simlab.social.task`, an attention level. It has
no PyBullet body by default: the robot's LIDAR and obstacle detector do not see it, and
the robot could drive through it (the task keeps the two apart by stopping the human, not
the robot); ``SocialConfig.human_body="turtlebot"`` gives it a second TurtleBot's body. Its behaviour parameters are the presets of :mod:`simlab.visitlab.humans`
(F/P/L/O/r and the speed probabilities s_H), read per decision step:

* **metres per step = cells per step x** :attr:`HumanBody.cell_size`. Default 0.15 m:
  the 1.5 m table is then a 10 x 10 grid, the thesis's Manhattan distance classes
  (<= 1, 2, 3, 4, >= 5 cells) become 0.15 / 0.30 / 0.45 / 0.60 m (the defaults of
  :class:`~simlab.social.perception.SocialPerception`), class 0 is about the robot's
  swept radius plus the disc's, and a human at speed 1 covers a bit more than the robot's
  fast primitive (0.11 m) - it can catch up with a robot that leads it, as on the grid
  where both move one cell.
* **random walk** (not engaged; thesis 2.1.2, the grid's ``human_idle``): with
  probability r_H the human walks ``speed x cell_size`` in a uniformly random direction of
  the 8 and faces it; then with probability O_H it turns to one of the 7 *other*
  directions (relative to the direction nearest its orientation; among all 8 with
  ``turn_all``, paper rule 6). Draw order as on the
  grid: u < r_H, direction, speed; u < O_H, new direction.
* **walking** stops at walls and obstacles (one ray in the LIDAR plane, minus the disc
  radius; the centre is also kept ``radius`` inside the table) and before the robot: the
  centre never comes closer than ``min_separation`` (random walk) or ``follow_gap``
  (following) to the robot's centre.
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
from simlab.physics.arena import ArenaConfig
from simlab.social.perception import quantise_direction
from simlab.visitlab.humans import Human

Pose = NDArray[np.float64]


@dataclass(frozen=True)
class HumanBody:
    """Geometry of the projected human (m).

    Attributes:
        cell_size: metres per grid cell (speeds are cells per decision step).
        radius: radius of the disc drawn and kept clear of walls and obstacles.
        min_separation: closest centre distance to the robot a walking human accepts.
        follow_gap: centre distance to the robot at which a following human stops.
            Decision: 0.25 m (distance class 1 with the default bounds). On the grid a
            follower stops one cell before the robot, but there a robot moves a whole cell
            per step; a primitive moves less than one cell (0.05 / 0.11 m), so stopping at
            one cell would put the pair in class 0 (too close), where attention is lost.
    """

    cell_size: float = 0.15
    radius: float = 0.06
    min_separation: float = 0.16
    follow_gap: float = 0.25

    def __post_init__(self) -> None:
        for key in ("cell_size", "radius", "min_separation", "follow_gap"):
            validation.positive(getattr(self, key), f"HumanBody.{key}")
        if self.follow_gap < self.min_separation:
            raise ConfigError(f"must be >= min_separation ({self.min_separation}), got "
                              f"{self.follow_gap}", key="HumanBody.follow_gap")


def draw_speed(rng: np.random.Generator, human: Human) -> int:
    """Speed 1-3 (cells per step) drawn from s_H with one uniform draw."""
    u = rng.random()
    s1, s2, _ = human.speed_probs
    if u < s1:
        return 1
    if u < s1 + s2:
        return 2
    return 3


def is_free(arena: ArenaConfig, xy: NDArray[np.float64] | tuple[float, float],
            clearance: float) -> bool:
    """Whether a disc of radius ``clearance`` (m) at ``xy`` lies inside the table and
    clear of every obstacle (analytic, from the arena description)."""
    x, y = float(xy[0]), float(xy[1])
    cx, cy = arena.center
    if abs(x - cx) > arena.size[0] / 2 - clearance or abs(y - cy) > arena.size[1] / 2 - clearance:
        return False
    for ob in arena.obstacles:
        if ob.kind == "cylinder":
            if math.hypot(x - ob.x, y - ob.y) <= ob.radius + clearance:
                return False
        else:
            c, s = math.cos(ob.yaw), math.sin(ob.yaw)
            lx, ly = c * (x - ob.x) + s * (y - ob.y), -s * (x - ob.x) + c * (y - ob.y)
            if abs(lx) <= ob.size[0] / 2 + clearance and abs(ly) <= ob.size[1] / 2 + clearance:
                return False
    if arena.map_walls is not None:
        for x0, y0, x1, y1 in arena.map_walls.boxes:
            if x0 - clearance <= x <= x1 + clearance and y0 - clearance <= y <= y1 + clearance:
                return False
    return True


def random_pose(world: Any, rng: np.random.Generator, body: HumanBody,
                avoid_xy: NDArray[np.float64] | None = None, tries: int = 1000) -> Pose:
    """A uniformly random free human pose ``(x, y, theta)`` on the table, at least
    ``follow_gap`` from ``avoid_xy`` (the robot); theta one of the 8 directions.

    Rejection sampling: two uniform draws per try, then one integer for the orientation.
    """
    a = world.arena
    cx, cy = a.center
    hx, hy = a.size[0] / 2 - body.radius, a.size[1] / 2 - body.radius
    for _ in range(tries):
        x = cx + rng.uniform(-hx, hx)
        y = cy + rng.uniform(-hy, hy)
        if not is_free(a, (x, y), body.radius):
            continue
        if avoid_xy is not None and math.hypot(x - avoid_xy[0], y - avoid_xy[1]) < body.follow_gap:
            continue
        return np.array([x, y, float(HEADINGS[int(rng.integers(0, 8))])])
    raise ConfigError(f"no free human position found in {tries} tries",
                      key="arena", fix="use an arena with free floor space")


def _separation_limit(xy: NDArray[np.float64], u: NDArray[np.float64], length: float,
                      robot_xy: NDArray[np.float64], gap: float) -> float:
    """Largest t in [0, length] such that xy + s u stays >= gap from robot_xy for s <= t."""
    rel = xy - robot_xy
    if float(rel @ rel) < gap * gap:
        return 0.0  # already too close: do not move
    b = float(rel @ u)
    disc = b * b - (float(rel @ rel) - gap * gap)
    if disc <= 0.0 or b >= 0.0:
        return length  # the path never enters the circle (or moves away from it)
    t = -b - math.sqrt(disc)
    return min(length, max(0.0, t))


def walk(world: Any, xy: NDArray[np.float64], heading: float, length: float,
         robot_xy: NDArray[np.float64], gap: float, body: HumanBody,
         ignore: int | None = None) -> NDArray[np.float64]:
    """New position (2,) after walking up to ``length`` m along ``heading`` (rad) from
    ``xy``: stopped by walls/obstacles (one LIDAR-plane ray, hits on the robot ignored:
    the ``gap`` rule stops the human first; hits on body ``ignore``, the human's own
    TurtleBot, too) and ``gap`` m before the robot's centre."""
    xy = np.asarray(xy, dtype=float)[:2]
    u = np.array([math.cos(heading), math.sin(heading)])
    t = _separation_limit(xy, u, float(length), np.asarray(robot_xy, dtype=float)[:2], gap)
    if t <= 0.0:
        return xy.copy()
    z = float(world.robot_spec.lidar_offset[2])
    reach = t + body.radius
    end = xy + reach * u
    hit = world.client.rayTest([xy[0], xy[1], z], [end[0], end[1], z])[0]
    if hit[0] >= 0 and hit[0] != world.body and (ignore is None or hit[0] != ignore):
        t = min(t, max(0.0, hit[2] * reach - body.radius))
    new = xy + t * u
    a = world.arena
    for k in range(2):  # keep the disc on the table
        half = a.size[k] / 2 - body.radius
        new[k] = min(max(new[k], a.center[k] - half), a.center[k] + half)
    if not is_free(a, new, body.radius * 0.5):
        return xy.copy()  # a grazing path into an obstacle's corner: stay
    return new


def moved_direction(before: NDArray[np.float64], after: NDArray[np.float64],
                    eps: float = 1e-3) -> int:
    """Direction index 0-7 of a displacement, or -1 if it is shorter than ``eps`` m."""
    d = np.asarray(after[:2], dtype=float) - np.asarray(before[:2], dtype=float)
    if math.hypot(d[0], d[1]) < eps:
        return -1
    return quantise_direction(math.atan2(d[1], d[0]))


def idle_step(world: Any, pose: Pose, human: Human, body: HumanBody,
              robot_xy: NDArray[np.float64], rng: np.random.Generator, *,
              turn_all: bool = False, ignore: int | None = None) -> tuple[Pose, int]:
    """One decision step of a human who is not engaged (module docstring).

    ``turn_all`` (paper rule 6): a random turn picks uniformly among all 8 orientations,
    the current one included (one integer 0-7, ``HEADINGS[k]``); else among the 7 others.
    ``ignore``: a body id the walking ray passes (the human's own TurtleBot).
    Returns the new pose (3,) and the direction moved (0-7) or -1.
    """
    new = np.array(pose, dtype=float)
    moved = -1
    if rng.random() < human.random_move:
        d = int(rng.integers(0, 8))
        cells = draw_speed(rng, human)
        new[:2] = walk(world, new[:2], float(HEADINGS[d]), cells * body.cell_size, robot_xy,
                       body.min_separation, body, ignore)
        new[2] = float(HEADINGS[d])
        moved = moved_direction(pose, new)
    if rng.random() < human.orientation_change:
        if turn_all:
            new[2] = float(HEADINGS[int(rng.integers(0, 8))])
            return new, moved
        current = quantise_direction(new[2])
        k = int(rng.integers(0, 7))
        new[2] = float(HEADINGS[k if k < current else k + 1])
    return new, moved


def follow_step(world: Any, pose: Pose, target_xy: NDArray[np.float64],
                robot_xy: NDArray[np.float64], human: Human, body: HumanBody,
                rng: np.random.Generator, *, look: bool = True,
                ignore: int | None = None) -> tuple[Pose, int]:
    """An engaged human (level 7) walks toward ``target_xy`` (where it saw the robot at the
    start of the step) at a speed drawn from s_H, at most up to the target, stopping
    ``follow_gap`` before the robot's current position ``robot_xy``; then it looks at the
    robot (``look=False``, paper rule 4: it keeps the orientation it had). ``ignore``: a
    body id the walking ray passes. Returns the new pose (3,) and the direction moved
    (0-7) or -1."""
    new = np.array(pose, dtype=float)
    cells = draw_speed(rng, human)
    dx, dy = float(target_xy[0]) - new[0], float(target_xy[1]) - new[1]
    dist = math.hypot(dx, dy)
    if dist > 1e-9:
        length = min(cells * body.cell_size, dist)
        new[:2] = walk(world, new[:2], math.atan2(dy, dx), length, robot_xy, body.follow_gap,
                       body, ignore)
    moved = moved_direction(pose, new)
    if look:
        look_at(new, robot_xy)
    return new, moved


def look_at(pose: Pose, xy: NDArray[np.float64]) -> None:
    """Turn ``pose`` (3,) in place to face the point ``xy`` (kept if they coincide)."""
    dx, dy = float(xy[0]) - pose[0], float(xy[1]) - pose[1]
    if math.hypot(dx, dy) > 1e-9:
        pose[2] = math.atan2(dy, dx)
