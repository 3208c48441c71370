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

An arena may instead be built from a map_server map (``map.yaml`` + image, e.g. made by
GMapping on the real robot): replace ``[floor]`` by::

    [map]
    yaml = "lab/map.yaml"             # relative to the TOML file
    unknown_as_wall = false           # optional: unknown pixels become walls too
    occupied_min = 65                 # optional: occupancy (%) from which a pixel is a wall
    flip_y = false                    # optional: the image is stored bottom row first

The arena then keeps the map's frame (no centring): start pose, goals and obstacles are
in map coordinates and used unchanged. Walls are extruded (``[walls] height``) from the
occupied pixels, merged into few axis-aligned boxes (:func:`merge_rectangles`); the free
area is the bounding box of the map's known pixels (plus one pixel), closed by perimeter
walls of ``[walls] thickness``. ``[start] clearance`` (m, default 0.09: half the Burger's
width) is the radius of the disc around the start position that must be free of walls and
obstacles (on every arena: a body started half inside a box is pushed out by the engine).

Every problem raises :class:`~simlab.base.errors.ConfigError` naming the file and the key.
"""

from __future__ import annotations

import hashlib
import math
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from simlab.base import validation
from simlab.base.assets import resolve
from simlab.base.errors import ConfigError
from simlab.base.io import NESTED_TOO_DEEPLY

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


def merge_rectangles(mask: NDArray[np.bool_]) -> list[tuple[int, int, int, int]]:
    """Cover the True pixels of ``mask`` (H, W) exactly by few disjoint rectangles.

    Greedy: scan rows top to bottom; at the first uncovered True pixel grow a run to the
    right, then grow it down while the whole run stays True and uncovered. Returns
    ``(row0, col0, row1, col1)`` half-open pixel ranges. Exact (the union is the mask), not
    minimal; wall lines of a map become one box per straight segment.
    """
    todo = np.array(mask, dtype=bool, copy=True)
    h, w = todo.shape
    out: list[tuple[int, int, int, int]] = []
    for r in range(h):
        row = todo[r]
        c = 0
        while True:
            hits = np.flatnonzero(row[c:])
            if hits.size == 0:
                break
            c0 = c + int(hits[0])
            gaps = np.flatnonzero(~row[c0:])
            c1 = c0 + (int(gaps[0]) if gaps.size else w - c0)
            r1 = r + 1
            while r1 < h and todo[r1, c0:c1].all():
                r1 += 1
            todo[r:r1, c0:c1] = False
            out.append((r, c0, r1, c1))
            c = c1
            if c >= w:
                break
    return out


@dataclass(frozen=True)
class MapWalls:
    """Walls extruded from a map_server map, in the map's frame (metres).

    ``walls`` (H, W) bool, row 0 the top (largest y), the pixels that are walls (occupied,
    and unknown if ``unknown_as_wall``); ``resolution`` m/pixel; ``origin_xy`` the lower-left
    corner of pixel (H-1, 0); ``boxes`` the merged walls as ``(x_min, y_min, x_max, y_max)``.
    """

    yaml: str
    resolution: float
    origin_xy: tuple[float, float]
    walls: NDArray[np.bool_] = field(compare=False, repr=False)
    boxes: tuple[tuple[float, float, float, float], ...] = field(repr=False)
    unknown_as_wall: bool = False

    @classmethod
    def from_mask(cls, yaml: str, walls: NDArray[np.bool_], resolution: float,
                  origin_xy: tuple[float, float], unknown_as_wall: bool) -> MapWalls:
        walls = np.array(walls, dtype=bool)
        walls.setflags(write=False)
        h = walls.shape[0]
        ox, oy = origin_xy
        boxes = tuple(
            (ox + c0 * resolution, oy + (h - r1) * resolution,
             ox + c1 * resolution, oy + (h - r0) * resolution)
            for r0, c0, r1, c1 in merge_rectangles(walls)
        )
        return cls(yaml, float(resolution), (float(ox), float(oy)), walls, boxes,
                   bool(unknown_as_wall))

    def contains(self, xy: ArrayLike) -> NDArray[np.bool_]:
        """Whether points ``xy`` (..., 2) lie on a wall pixel (False off the map)."""
        p = np.asarray(xy, dtype=float)
        h, w = self.walls.shape
        col = np.floor((p[..., 0] - self.origin_xy[0]) / self.resolution).astype(np.int64)
        row = h - 1 - np.floor((p[..., 1] - self.origin_xy[1]) / self.resolution).astype(np.int64)
        ok = (col >= 0) & (col < w) & (row >= 0) & (row < h)
        out = np.zeros(p.shape[:-1], dtype=bool)
        out[ok] = self.walls[row[ok], col[ok]]
        return out


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
    center: tuple[float, float] = (0.0, 0.0)
    map_walls: MapWalls | None = None

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """``(x_min, y_min, x_max, y_max)`` of the inner free area (m); centred on
        ``center`` (the origin, except for an arena built from a map)."""
        hx, hy = self.size[0] / 2, self.size[1] / 2
        cx, cy = self.center
        return (cx - hx, cy - hy, cx + hx, cy + hy)

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
        if self.map_walls is not None:
            out |= self.map_walls.contains(p)
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

_TOP_KEYS = {"name", "description", "floor", "map", "walls", "start", "goals", "obstacles"}

#: Default radius (m) of the disc around a map arena's start position that must be free of
#: walls: half the TurtleBot3 Burger's width (0.178 m).
START_CLEARANCE = 0.09


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
        return validation.number(data[name], full, low=0.0 if positive else None,
                                 low_open=positive, path=self.path)

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
            out.append(validation.number(v, full, low=0.0 if positive else None,
                                         low_open=positive, path=self.path))
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


def check_arena_option(value: Any, key: str = "arena") -> Any:
    """An arena option of a command's config: a built-in name, a ``.toml`` path or (from
    Python) an :class:`ArenaConfig`; returned unchanged, else a ConfigError naming ``key``
    (a number or a table from a ``--config`` file)."""
    if not isinstance(value, ArenaConfig) and (not isinstance(value, str | os.PathLike)
                                               or not str(value)):
        raise ConfigError(f"expected an arena name or .toml path, got {value!r}", key=key,
                          fix='a built-in name such as "table", or the .toml of simlab '
                              "arena-from-map")
    return value


def load_arena(name_or_path: str | Path) -> ArenaConfig:
    """Load and validate an arena by built-in name (``"table"``) or ``.toml`` path."""
    path = resolve("arenas", name_or_path, ".toml")
    raw = path.read_bytes()
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"not valid TOML: {exc}", path=path) from None
    except RecursionError:
        raise ConfigError(NESTED_TOO_DEEPLY, path=path) from None
    return _parse(data, path, hashlib.sha256(raw).hexdigest())


def _parse_map(c: _Checker, data: dict[str, Any], path: Path
               ) -> tuple[tuple[float, float], tuple[float, float], MapWalls, str]:
    """The ``[map]`` table: (size, centre, walls, sha256 of the map's YAML and image)."""
    from discretize.gridmap import UNKNOWN
    from discretize.mapio import read_map, read_map_yaml

    table = c.table(data, "map", {"yaml", "unknown_as_wall", "occupied_min", "flip_y"})
    yaml_path = path.parent / c.string(table, "map", "yaml")
    unknown_as_wall = validation.boolean(table.get("unknown_as_wall", False),
                                         "map.unknown_as_wall", path=c.path)
    flip_y = validation.boolean(table.get("flip_y", False), "map.flip_y", path=c.path)
    occupied_min = c.number(table, "map", "occupied_min", default=65.0)
    if not 0 < occupied_min <= 100:
        raise c.fail("map.occupied_min", f"expected a percentage in (0, 100], got {occupied_min}")
    if not yaml_path.is_file():
        raise c.fail("map.yaml", f"map file {str(yaml_path)!r} not found",
                     fix="the path is relative to the arena TOML's directory")
    grid = read_map(yaml_path, flip_y=flip_y)
    if abs(grid.origin[2]) > 1e-9:
        raise c.fail("map.yaml", f"the map's origin yaw is {grid.origin[2]} rad; only "
                     "unrotated maps (yaw 0) can be extruded", fix="re-save the map with yaw 0")
    occ = grid.occupancy
    known = occ != UNKNOWN
    if not known.any():
        raise c.fail("map.yaml", "the map has no known pixel")
    walls = occ >= occupied_min
    if unknown_as_wall:
        walls = walls | ~known
    # Crop to the known part plus one pixel (the frame is kept: only the extent shrinks).
    rows, cols = np.flatnonzero(known.any(axis=1)), np.flatnonzero(known.any(axis=0))
    h, w = occ.shape
    r0, r1 = max(0, rows[0] - 1), min(h, rows[-1] + 2)
    c0, c1 = max(0, cols[0] - 1), min(w, cols[-1] + 2)
    res = grid.resolution
    ox, oy = float(grid.origin[0] + c0 * res), float(grid.origin[1] + (h - r1) * res)
    mw = MapWalls.from_mask(str(yaml_path), walls[r0:r1, c0:c1], res, (ox, oy), unknown_as_wall)
    size = (float((c1 - c0) * res), float((r1 - r0) * res))
    center = (ox + size[0] / 2, oy + size[1] / 2)
    digest = hashlib.sha256(yaml_path.read_bytes())
    digest.update(read_map_yaml(yaml_path).image.read_bytes())
    return size, center, mw, digest.hexdigest()


def _fmt_bounds(size: tuple[float, ...], center: tuple[float, float]) -> str:
    if center == (0.0, 0.0):
        return str(size)
    return (f"x {center[0] - size[0] / 2:.3f}..{center[0] + size[0] / 2:.3f}, "
            f"y {center[1] - size[1] / 2:.3f}..{center[1] + size[1] / 2:.3f}")


def _parse(data: dict[str, Any], path: Path, sha: str) -> ArenaConfig:
    """The whole arena TOML -> a checked :class:`ArenaConfig` (errors name file and key)."""
    c = _Checker(path)
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise c.fail("(top level)", f"unknown key(s) {sorted(unknown)}",
                     fix=f"allowed: {sorted(_TOP_KEYS)}")
    name = c.string(data, "", "name")
    description = data.get("description", "")
    if not isinstance(description, str):
        raise c.fail("description", "expected a string")

    map_walls: MapWalls | None = None
    center = (0.0, 0.0)
    if ("floor" in data) == ("map" in data):
        raise c.fail("floor", "give exactly one of [floor] (a rectangle) or [map] (a "
                     "map_server map)")
    if "map" in data:
        size, center, map_walls, map_sha = _parse_map(c, data, path)
        sha = hashlib.sha256((sha + map_sha).encode()).hexdigest()
    else:
        floor = c.table(data, "floor", {"size"})
        size = c.vector(floor, "floor", "size", 2, positive=True)
    wall_height, wall_thickness = _parse_walls(c, data)
    start_t = c.table(data, "start", {"pose", "clearance"})
    sx, sy, syaw_deg = c.vector(start_t, "start", "pose", 3)
    start = (sx, sy, math.radians(syaw_deg))
    clearance = c.number(start_t, "start", "clearance", default=START_CLEARANCE)
    validation.number(clearance, "start.clearance", low=0.0, path=c.path)
    arena = ArenaConfig(
        name=name,
        size=(size[0], size[1]),
        wall_height=wall_height,
        wall_thickness=wall_thickness,
        start=start,
        goals=_parse_goals(c, data, size, center),
        obstacles=_parse_obstacles(c, data, size, center),
        description=description,
        source=str(path),
        source_sha256=sha,
        center=center,
        map_walls=map_walls,
    )
    _check_placements(c, arena, clearance)
    return arena


def _parse_walls(c: _Checker, data: dict[str, Any]) -> tuple[float, float]:
    """``[walls]``: height (above the LIDAR plane) and thickness, metres."""
    walls = c.table(data, "walls", {"height", "thickness"})
    wall_height = c.number(walls, "walls", "height", positive=True)
    if wall_height <= LIDAR_PLANE_HEIGHT:
        raise c.fail("walls.height", f"{wall_height} m is not above the LIDAR plane "
                     f"({LIDAR_PLANE_HEIGHT} m): the walls would be invisible",
                     fix="use e.g. 0.25")
    return wall_height, c.number(walls, "walls", "thickness", positive=True)


def _on_floor(c: _Checker, key: str, xy: tuple[float, float], size: Any, center: Any) -> None:
    """Refuse a centre outside the floor rectangle."""
    if not (-size[0] / 2 < xy[0] - center[0] < size[0] / 2
            and -size[1] / 2 < xy[1] - center[1] < size[1] / 2):
        raise c.fail(f"{key}.center", f"({xy[0]}, {xy[1]}) is outside the floor "
                     f"{_fmt_bounds(size, center)}")


def _parse_goals(c: _Checker, data: dict[str, Any], size: Any, center: Any
                 ) -> tuple[GoalArea, ...]:
    """``[[goals]]``: at least one, unique names, centres on the floor."""
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
        _on_floor(c, key, (gx, gy), size, center)
        goals.append(GoalArea(gname, gx, gy, c.number(g, key, "radius", positive=True)))
    return tuple(goals)


def _parse_obstacles(c: _Checker, data: dict[str, Any], size: Any, center: Any
                     ) -> tuple[Obstacle, ...]:
    """``[[obstacles]]``: boxes (size, yaw in degrees) and cylinders (radius) on the floor."""
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
        _on_floor(c, key, (ox, oy), size, center)
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
    return tuple(obstacles)


def _check_placements(c: _Checker, arena: ArenaConfig, clearance: float) -> None:
    """The start in free space (with ``clearance`` m around it on a map arena) and no goal
    centre inside an obstacle or on a wall pixel."""
    sx, sy = arena.start[:2]
    x0, y0, x1, y1 = arena.bounds
    if not (x0 <= sx <= x1 and y0 <= sy <= y1):
        raise c.fail("start.pose", f"start position {arena.start[:2]} is outside the floor "
                     f"(x {x0:g}..{x1:g}, y {y0:g}..{y1:g} m)",
                     fix="give a start on the floor")
    if arena.occupied(np.array([sx, sy])):
        raise c.fail("start.pose", f"start position {arena.start[:2]} is inside an obstacle "
                     "or wall", fix="move the start into free space")
    # the robot's body, a disc of ``clearance`` around the start, must not overlap a wall, a
    # box or the floor's edge either (a body half inside a box is pushed out by the engine)
    ang = np.linspace(0.0, 2 * math.pi, 48, endpoint=False)
    rad = np.linspace(0.0, clearance, 6)[1:, None]
    disc = np.stack([sx + rad * np.cos(ang), sy + rad * np.sin(ang)], axis=-1)
    hit = disc[arena.occupied(disc)]
    if hit.size:
        raise c.fail("start.pose", f"the robot at {arena.start[:2]} would overlap a wall or "
                     f"obstacle (e.g. at ({hit[0][0]:.3f}, {hit[0][1]:.3f})) within "
                     f"{clearance} m", fix="move the start into free space, or lower "
                     "[start] clearance")
    map_walls = arena.map_walls
    for i, g in enumerate(arena.goals):
        if any(ob.contains(np.array([g.x, g.y])) for ob in arena.obstacles):
            raise c.fail(f"goals[{i}].center", f"goal {g.name!r} centre is inside an obstacle")
        if map_walls is not None and map_walls.contains(np.array([g.x, g.y])):
            raise c.fail(f"goals[{i}].center", f"goal {g.name!r} centre is on a wall pixel")
