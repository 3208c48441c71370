"""Obstacles added to a live world: a box that appears mid-run (a passage closing).

Dromnelle et al. (2022, sec. 4.1) close passages of the lab while the robot learns; in
simlab's physics a passage closes by a static box added to the running
:class:`~simlab.physics.world.World` through the world's own bullet client (never the
global ``pybullet`` module: two worlds in one process stay apart). The LIDAR's
``rayTestBatch`` sees the box from the next scan on, so the obstacle detector of the
primitives blocks a move into it, exactly as for an obstacle of the arena file.

A box added here lives until the world's next :meth:`~simlab.physics.world.World.reset`
(which rebuilds the arena from its config); :func:`arena_with_box` gives the arena config
that contains it, for a map (or a particle filter's field) that should know the box, and
:func:`remove_box` takes it away again (a passage re-opening).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import pybullet

__all__ = ["add_box", "arena_with_box", "box_obstacle", "remove_box"]

#: Lateral friction of an added box (the walls' value of the world module).
BOX_FRICTION = 0.5


def box_obstacle(x: float, y: float, size: tuple[float, float], *, height: float = 0.25,
                 yaw: float = 0.0) -> Any:
    """The :class:`~simlab.physics.arena.Obstacle` of a box centred at ``(x, y)`` m with
    footprint ``size`` (x, y extents, m) turned by ``yaw`` rad, ``height`` m tall. A box
    must reach above the LIDAR plane to be seen; sizes and height must be > 0."""
    from simlab.base.errors import ConfigError
    from simlab.physics.arena import LIDAR_PLANE_HEIGHT, Obstacle

    for key, value in (("x", x), ("y", y), ("yaw", yaw), ("height", height),
                       ("size", size[0]), ("size", size[1])):
        if not math.isfinite(float(value)):
            raise ConfigError(f"expected a finite number, got {value!r}", key=key)
    if min(size) <= 0 or height <= 0:
        raise ConfigError(f"expected positive sizes, got size {size} and height {height}",
                          key="size")
    if height <= LIDAR_PLANE_HEIGHT:
        raise ConfigError(f"a box of {height} m stays under the LIDAR plane "
                          f"({LIDAR_PLANE_HEIGHT} m): the robot would not see it",
                          key="height", fix="make it taller")
    return Obstacle("box", float(x), float(y), float(height),
                    size=(float(size[0]), float(size[1])), yaw=float(yaw))


def add_box(world: Any, x: float, y: float, size: tuple[float, float], *,
            height: float = 0.25, yaw: float = 0.0) -> int:
    """Add a static box to the running ``world`` (see :func:`box_obstacle` for the
    arguments); returns its PyBullet body id, also appended to ``world.static_bodies``."""
    ob = box_obstacle(x, y, size, height=height, yaw=yaw)
    c = world.client
    ext = [ob.size[0] / 2, ob.size[1] / 2, ob.height / 2]
    shape = c.createCollisionShape(pybullet.GEOM_BOX, halfExtents=ext)
    vis = (c.createVisualShape(pybullet.GEOM_BOX, halfExtents=ext, rgbaColor=[0.8, 0.3, 0.3, 1])
           if getattr(world, "gui", False) else -1)
    body = c.createMultiBody(0, shape, vis, basePosition=[ob.x, ob.y, ob.height / 2],
                             baseOrientation=c.getQuaternionFromEuler([0.0, 0.0, ob.yaw]))
    c.changeDynamics(body, -1, lateralFriction=BOX_FRICTION)
    world.static_bodies.append(body)
    return int(body)


def remove_box(world: Any, body: int) -> None:
    """Remove a body added by :func:`add_box` from the running ``world``."""
    world.client.removeBody(int(body))
    if body in world.static_bodies:
        world.static_bodies.remove(body)


def arena_with_box(arena: Any, x: float, y: float, size: tuple[float, float], *,
                   height: float = 0.25, yaw: float = 0.0) -> Any:
    """A copy of the :class:`~simlab.physics.arena.ArenaConfig` ``arena`` with the box as
    one more obstacle (for a map or a localisation field that knows of it)."""
    ob = box_obstacle(x, y, size, height=height, yaw=yaw)
    return dataclasses.replace(arena, obstacles=(*arena.obstacles, ob))
