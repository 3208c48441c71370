"""Arena descriptions: TOML files validated into frozen dataclasses.

An arena is a flat floor with an inner rectangular free area centred at the origin,
surrounded by walls taller than the LIDAR plane, optional box and cylinder obstacles, a
start pose and named goal areas (circles). Frame: x right, y up ("UP" = +y), metres,
yaw in radians counter-clockwise from +x.

File format (``arenas/table.toml`` is the reference)::

    name = "table"
    description = "..."               # optional

    [floor]
    size = [1.5, 1.5]                 # inner free area, x and y extent (m)

    [walls]
    height = 0.25                     # m, must exceed the LIDAR plane (0.182 m)
    thickness = 0.05                  # m

    [start]
    pose = [0.0, 0.0, 90.0]           # x (m), y (m), yaw (degrees)

    [[goals]]                         # one table per goal area
    name = "NW"
    center = [-0.45, 0.45]            # m
    radius = 0.15                     # m

    [[obstacles]]                     # optional
    kind = "box"                      # "box" or "cylinder"
    center = [0.3, 0.2]               # m
    size = [0.2, 0.1]                 # box only: x and y extent before rotation (m)
    yaw = 30.0                        # box only, degrees (default 0)
    radius = 0.06                     # cylinder only (m)
    height = 0.3                      # m

Every problem raises :class:`~simlab.errors.ConfigError` naming the file and the key.
"""

from __future__ import annotations

import hashlib
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from simlab.assets import resolve
from simlab.errors import ConfigError

#: Height of the LIDAR scan plane above the floor (m); walls and obstacles must reach above it
#: to be seen. Kept in sync with ``scan_joint`` in robots/turtlebot3_burger.urdf by a test.
LIDAR_PLANE_HEIGHT = 0.182


@dataclass(frozen=True)
class GoalArea:
    """A named circular goal area (metres)."""

    name: str
    x: float
    y: float
    radius: float

    def contains(self, xy: ArrayLike) -> NDArray[np.bool_]:
        """Whether points ``xy`` (..., 2) lie inside the circle (boundary included)."""
        p = np.asarray(xy, dtype=float)
        return np.hypot(p[..., 0] - self.x, p[..., 1] - self.y) <= self.radius


@dataclass(frozen=True)
class Obstacle:
    """A static obstacle: ``kind`` is ``"box"`` (``size`` x/y extent, ``yaw`` rad) or
    ``"cylinder"`` (``radius``); ``height`` in metres."""

    kind: str
    x: float
    y: float
    height: float
    size: tuple[float, float] = (0.0, 0.0)
    yaw: float = 0.0
    radius: float = 0.0

    def contains(self, xy: ArrayLike) -> NDArray[np.bool_]:
        """Whether points ``xy`` (..., 2) lie inside the obstacle's footprint."""
        p = np.asarray(xy, dtype=float)
        dx, dy = p[..., 0] - self.x, p[..., 1] - self.y
        if self.kind == "cylinder":
            return np.hypot(dx, dy) <= self.radius
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        u, v = c * dx + s * dy, -s * dx + c * dy
        return (np.abs(u) <= self.size[0] / 2) & (np.abs(v) <= self.size[1] / 2)


@dataclass(frozen=True)
class ArenaConfig:
    """A validated arena. Build with :func:`load_arena`."""

    name: str
    size: tuple[float, float]
    wall_height: float
    wall_thickness: float
    start: tuple[float, float, float]
    goals: tuple[GoalArea, ...]
    obstacles: tuple[Obstacle, ...] = ()
    description: str = ""
    source: str | None = None
    source_sha256: str | None = None

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(x_min, y_min, x_max, y_max)`` of the inner free area (m)."""
        hx, hy = self.size[0] / 2, self.size[1] / 2
        return (-hx, -hy, hx, hy)

    @property
    def goal_names(self) -> tuple[str, ...]:
        return tuple(g.name for g in self.goals)

    def goal(self, name: str) -> GoalArea:
        """The goal area called ``name`` (ConfigError listing the valid names otherwise)."""
        for g in self.goals:
            if g.name == name:
                return g
        raise ConfigError(
            f"unknown goal {name!r}",
            path=self.source,
            fix=f"valid goals: {', '.join(self.goal_names)}",
        )

    def occupied(self, xy: ArrayLike) -> NDArray[np.bool_]:
        """Whether points ``xy`` (..., 2) are inside a wall, outside the arena or in an obstacle."""
        p = np.asarray(xy, dtype=float)
        x0, y0, x1, y1 = self.bounds
        out = (p[..., 0] < x0) | (p[..., 0] > x1) | (p[..., 1] < y0) | (p[..., 1] > y1)
        for ob in self.obstacles:
            out |= ob.contains(p)
        return out

    def rasterize(
        self, resolution: float, origin_xy: tuple[float, float], shape: tuple[int, int]
    ) -> NDArray[np.bool_]:
        """Occupied pixels (walls, outside, obstacles) on a map_server-oriented grid.

        Returns a bool array (H, W): row 0 is the top (largest y); pixel (row, col) covers
        ``x in [ox + col*res, ox + (col+1)*res)`` and
        ``y in [oy + (H-1-row)*res, oy + (H-row)*res)``; a pixel is occupied when its centre is.
        """
        h, w = shape
        ox, oy = origin_xy
        xs = ox + (np.arange(w) + 0.5) * resolution
        ys = oy + (h - 1 - np.arange(h) + 0.5) * resolution
        gx, gy = np.meshgrid(xs, ys)
        return self.occupied(np.stack([gx, gy], axis=-1))


# --------------------------------------------------------------------------------------
# Loading and validation
# --------------------------------------------------------------------------------------

_TOP_KEYS = {"name", "description", "floor", "walls", "start", "goals", "obstacles"}


class _Checker:
    """Typed access to a TOML table with errors naming the file and the dotted key."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, key: str, problem: str, fix: str | None = None) -> ConfigError:
        return ConfigError(problem, path=self.path, key=key, fix=fix)

    def table(self, data: dict[str, Any], key: str, allowed: set[str]) -> dict[str, Any]:
        value = data.get(key.rsplit(".", 1)[-1])
        if not isinstance(value, dict):
            raise self.fail(key, "missing table" if value is None else "expected a table")
        unknown = set(value) - allowed
        if unknown:
            raise self.fail(
                key, f"unknown key(s) {sorted(unknown)}", fix=f"allowed: {sorted(allowed)}"
            )
        return value

    def number(
        self, data: dict[str, Any], key: str, name: str, *, positive: bool = False,
        default: float | None = None,
    ) -> float:
        full = f"{key}.{name}"
        if name not in data:
            if default is not None:
                return default
            raise self.fail(full, "missing key")
        value = data[name]
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(full, f"expected a number, got {value!r}")
        value = float(value)
        if not math.isfinite(value):
            raise self.fail(full, f"expected a finite number, got {value!r}")
        if positive and value <= 0:
            raise self.fail(full, f"expected a number > 0, got {value!r}")
        return value

    def vector(self, data: dict[str, Any], key: str, name: str, n: int, *,
               positive: bool = False) -> tuple[float, ...]:
        full = f"{key}.{name}"
        if name not in data:
            raise self.fail(full, "missing key")
        value = data[name]
        if not isinstance(value, list) or len(value) != n:
            raise self.fail(full, f"expected a list of {n} numbers, got {value!r}")
        out = []
        for v in value:
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise self.fail(full, f"expected a list of {n} numbers, got {value!r}")
            if positive and v <= 0:
                raise self.fail(full, f"expected numbers > 0, got {value!r}")
            out.append(float(v))
        return tuple(out)

    def string(self, data: dict[str, Any], key: str, name: str, default: str | None = None) -> str:
        full = f"{key}.{name}" if key else name
        if name not in data:
            if default is not None:
                return default
            raise self.fail(full, "missing key")
        value = data[name]
        if not isinstance(value, str) or not value:
            raise self.fail(full, f"expected a non-empty string, got {value!r}")
        return value


def load_arena(name_or_path: str | Path) -> ArenaConfig:
    """Load and validate an arena by built-in name (``"table"``) or ``.toml`` path."""
    path = resolve("arenas", name_or_path, ".toml")
    raw = path.read_bytes()
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"not valid TOML: {exc}", path=path) from None
    return _parse(data, path, hashlib.sha256(raw).hexdigest())


def _parse(data: dict[str, Any], path: Path, sha: str) -> ArenaConfig:
    c = _Checker(path)
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise c.fail("(top level)", f"unknown key(s) {sorted(unknown)}",
                     fix=f"allowed: {sorted(_TOP_KEYS)}")
    name = c.string(data, "", "name")
    description = data.get("description", "")
    if not isinstance(description, str):
        raise c.fail("description", "expected a string")

    floor = c.table(data, "floor", {"size"})
    size = c.vector(floor, "floor", "size", 2, positive=True)

    walls = c.table(data, "walls", {"height", "thickness"})
    wall_height = c.number(walls, "walls", "height", positive=True)
    if wall_height <= LIDAR_PLANE_HEIGHT:
        raise c.fail("walls.height", f"{wall_height} m is not above the LIDAR plane "
                     f"({LIDAR_PLANE_HEIGHT} m): the walls would be invisible",
                     fix="use e.g. 0.25")
    wall_thickness = c.number(walls, "walls", "thickness", positive=True)

    start_t = c.table(data, "start", {"pose"})
    sx, sy, syaw_deg = c.vector(start_t, "start", "pose", 3)
    start = (sx, sy, math.radians(syaw_deg))

    hx, hy = size[0] / 2, size[1] / 2
    inside = lambda x, y: -hx < x < hx and -hy < y < hy  # noqa: E731

    goals_raw = data.get("goals")
    if not isinstance(goals_raw, list) or not goals_raw:
        raise c.fail("goals", "expected at least one [[goals]] table")
    goals = []
    seen: set[str] = set()
    for i, g in enumerate(goals_raw):
        key = f"goals[{i}]"
        if not isinstance(g, dict):
            raise c.fail(key, "expected a table")
        unknown = set(g) - {"name", "center", "radius"}
        if unknown:
            raise c.fail(key, f"unknown key(s) {sorted(unknown)}",
                         fix="allowed: ['center', 'name', 'radius']")
        gname = c.string(g, key, "name")
        if gname in seen:
            raise c.fail(f"{key}.name", f"duplicate goal name {gname!r}")
        seen.add(gname)
        gx, gy = c.vector(g, key, "center", 2)
        if not inside(gx, gy):
            raise c.fail(f"{key}.center", f"({gx}, {gy}) is outside the floor {size}")
        goals.append(GoalArea(gname, gx, gy, c.number(g, key, "radius", positive=True)))

    obstacles = []
    obstacles_raw = data.get("obstacles", [])
    if not isinstance(obstacles_raw, list):
        raise c.fail("obstacles", "expected a list of [[obstacles]] tables")
    for i, o in enumerate(obstacles_raw):
        key = f"obstacles[{i}]"
        if not isinstance(o, dict):
            raise c.fail(key, "expected a table")
        kind = c.string(o, key, "kind")
        allowed = {"kind", "center", "height"} | (
            {"size", "yaw"} if kind == "box" else {"radius"} if kind == "cylinder" else set()
        )
        if kind not in ("box", "cylinder"):
            raise c.fail(f"{key}.kind", f"unknown obstacle kind {kind!r}",
                         fix="use 'box' or 'cylinder'")
        unknown = set(o) - allowed
        if unknown:
            raise c.fail(key, f"unknown key(s) {sorted(unknown)} for a {kind}",
                         fix=f"allowed: {sorted(allowed)}")
        ox, oy = c.vector(o, key, "center", 2)
        if not inside(ox, oy):
            raise c.fail(f"{key}.center", f"({ox}, {oy}) is outside the floor {size}")
        height = c.number(o, key, "height", positive=True)
        if kind == "box":
            bsize = c.vector(o, key, "size", 2, positive=True)
            yaw = math.radians(c.number(o, key, "yaw", default=0.0))
            obstacles.append(Obstacle("box", ox, oy, height, size=(bsize[0], bsize[1]), yaw=yaw))
        else:
            obstacles.append(
                Obstacle("cylinder", ox, oy, height, radius=c.number(o, key, "radius",
                                                                    positive=True))
            )

    arena = ArenaConfig(
        name=name,
        size=(size[0], size[1]),
        wall_height=wall_height,
        wall_thickness=wall_thickness,
        start=start,
        goals=tuple(goals),
        obstacles=tuple(obstacles),
        description=description,
        source=str(path),
        source_sha256=sha,
    )
    if arena.occupied(np.array(start[:2])):
        raise c.fail("start.pose", f"start position {start[:2]} is inside an obstacle")
    for i, g in enumerate(arena.goals):
        if any(ob.contains(np.array([g.x, g.y])) for ob in arena.obstacles):
            raise c.fail(f"goals[{i}].center", f"goal {g.name!r} centre is inside an obstacle")
    return arena
