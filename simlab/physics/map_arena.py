"""Write an arena TOML for a map_server map (``simlab arena-from-map``).

The arena names the map (``[map] yaml``, relative to the TOML) and keeps its frame, so
the real robot's poses, centres and goals are used unchanged (see
:mod:`simlab.physics.arena`). Decisions:

* start pose: ``start`` if given, else the state centre (with ``states``) or free pixel
  (without) farthest from any wall or unknown pixel, heading +y (UP);
* goals: with ``states``, one circle per state centre named ``s<id>`` (so a goal state
  of the real data is a goal area here); without, the free pixel farthest from walls in
  each ninth of the known part of the map (3 x 3, named NW ... SE; a ninth with no pixel
  at least ``goal_radius`` from walls gets no goal).
"""

from __future__ import annotations

import math
import numbers
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.base import validation
from simlab.base.errors import ConfigError
from simlab.base.io import atomic_write_text, ensure_new
from simlab.base.options import CommandConfig, command, option
from simlab.physics.arena import START_CLEARANCE, load_arena

_NINTHS = ("NW", "N", "NE", "W", "C", "E", "SW", "S", "SE")


def _clearance(occ: NDArray[np.int8], resolution: float) -> NDArray[np.float64]:
    """Distance (m) of each free pixel's centre to the nearest non-free (wall or unknown)
    pixel; 0 off the free space."""
    from scipy.ndimage import distance_transform_edt

    free = occ == 0
    return distance_transform_edt(free) * resolution * free


def _pixel_xy(grid: Any, row: int, col: int) -> tuple[float, float]:
    h = grid.occupancy.shape[0]
    res = grid.resolution
    return (grid.origin[0] + (col + 0.5) * res, grid.origin[1] + (h - 1 - row + 0.5) * res)


def _auto_goals(grid: Any, clear: NDArray[np.float64], radius: float
                ) -> list[tuple[str, float, float]]:
    known = grid.occupancy >= 0
    rows, cols = np.flatnonzero(known.any(axis=1)), np.flatnonzero(known.any(axis=0))
    r_edges = np.linspace(rows[0], rows[-1] + 1, 4).round().astype(int)
    c_edges = np.linspace(cols[0], cols[-1] + 1, 4).round().astype(int)
    goals = []
    for i, name in enumerate(_NINTHS):
        r0, r1 = r_edges[i // 3], r_edges[i // 3 + 1]
        c0, c1 = c_edges[i % 3], c_edges[i % 3 + 1]
        block = clear[r0:r1, c0:c1]
        if block.size == 0 or block.max() < radius:
            continue
        r, c = np.unravel_index(int(block.argmax()), block.shape)
        goals.append((name, *_pixel_xy(grid, r0 + int(r), c0 + int(c))))
    return goals


def _start_pose(text: str) -> tuple[float, float, float]:
    """``--start X,Y,YAW``: the command line's spelling of ``start`` (argparse turns the
    ArgumentTypeError into its usage error, as for any bad option value)."""
    import argparse

    try:
        x, y, yaw = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y,YAW_DEGREES, got {text!r}") from None
    return x, y, yaw


def _check_start(value: Any) -> tuple[float, float, float]:
    """``start`` as three finite numbers (a TOML list or a Python tuple)."""
    ok = (isinstance(value, list | tuple) and len(value) == 3
          and all(isinstance(v, numbers.Real) and not isinstance(v, bool)
                  and math.isfinite(v) for v in value))
    if not ok:
        raise ConfigError(f"expected [x, y, yaw_degrees], got {value!r}", key="start")
    return float(value[0]), float(value[1]), float(value[2])


@dataclass(frozen=True, kw_only=True)
class ArenaFromMapConfig(CommandConfig):
    """Options of ``simlab arena-from-map`` / :func:`arena_from_map`."""

    COMMAND = "arena-from-map"
    ARGUMENTS = ("map_yaml", "out")

    map_yaml: Path = option(help="map_server YAML (image beside it)", positional=True,
                            metavar="MAP.yaml")
    out: Path = option(help="arena TOML to write")
    states: Any | None = option(
        None, "states file (JSON): one goal per state centre (default: 3 x 3 goals at the "
        "freest points)")
    start: Any | None = option(
        None, "start pose in map coordinates, yaw in degrees (default: the freest state "
        "centre or pixel, facing +y)", metavar="X,Y,YAW", parse=_start_pose)
    start_state: int | None = option(
        None, "start at this state's centre (needs --states; instead of --start), facing +y",
        metavar="N")
    goal_radius: float = option(0.15, "radius of every goal circle in m")
    unknown_as_wall: bool = option(
        False, "extrude unknown pixels as walls too (default: only occupied)")
    flip_y: bool = option(False, "flip the map image vertically (stored bottom row first); "
                          "the arena records it")
    name: str | None = option(None, "arena name (default: the file's stem)")
    overwrite: bool = option(False, "replace an existing --out")

    EXCLUSIVE = ("start", "start_state")

    def validate(self) -> None:
        validation.positive(self.goal_radius, "goal_radius")
        if self.start is not None:
            object.__setattr__(self, "start", _check_start(self.start))
        if self.name is not None:
            try:
                self.name.encode("utf-8")
            except UnicodeEncodeError:
                raise ConfigError(f"not UTF-8 text: {self.name!r}", key="name",
                                  fix="choose a name of plain text") from None
        if self.start is not None and self.start_state is not None:
            raise ConfigError("give either start or start_state", key="start_state")
        if self.start_state is not None:
            validation.whole(self.start_state, "start_state")
            if self.states is None:
                raise ConfigError("a start state needs the states file", key="start_state",
                                  fix="add --states FILE (the centres the numbers refer to)")


@command(ArenaFromMapConfig)
def arena_from_map(cfg: ArenaFromMapConfig) -> Path:
    """Write an arena TOML ``out`` for the map ``map_yaml``; returns the path.

    Takes an :class:`ArenaFromMapConfig` or its fields
    (``arena_from_map(map_yaml, out, states=..., ...)``):

    * ``map_yaml``: map_server YAML (its image beside it).
    * ``out``: the TOML to write (refused if it exists, unless ``overwrite``).
    * ``states``: optional states file (``simlab discretize`` JSON) or discretizer: its
      centres become goals ``s<id>``.
    * ``start``: ``(x, y, yaw_degrees)`` in map coordinates; default: see module doc.
    * ``goal_radius``: radius (m) of every goal circle.
    * ``unknown_as_wall``: extrude unknown pixels too.
    * ``start_state``: start at this state's centre (with ``states``), facing +y.
    * ``flip_y``: flip the map image vertically (bottom row first, as some GMapping exports
      store it); the arena's ``[map]`` records ``flip_y = true`` so that the arena, its
      walls and the goals agree with the flipped map.
    * ``name``: arena name (default: the TOML's stem).
    * ``overwrite``: replace an existing ``out``.

    The written file is loaded back (validated) before it is renamed into place.
    """
    from discretize.mapio import read_map

    ensure_new(cfg.out, overwrite=cfg.overwrite, what="arena file")
    grid = read_map(cfg.map_yaml, flip_y=cfg.flip_y)
    clear = _clearance(grid.occupancy, grid.resolution)
    if clear.max() < START_CLEARANCE:
        raise ConfigError("no free pixel is far enough from the walls for the robot",
                          path=cfg.map_yaml, fix="check the map's thresholds")
    goals, centres = _goals(cfg, grid, clear)
    start = _initial_pose(cfg, grid, clear, centres)
    text = _arena_text(cfg, start, goals)
    _check_arena_text(text, cfg)
    atomic_write_text(cfg.out, text)
    return cfg.out


def _goals(cfg: ArenaFromMapConfig, grid: Any, clear: NDArray[np.float64]
           ) -> tuple[list[tuple[str, float, float]], NDArray[np.float64] | None]:
    """The goal circles ``[(name, x, y)]`` (m, map frame) and the state centres (S, 2) in m
    (None without ``states``): one goal per centre, else one per ninth of the map."""
    if cfg.states is not None:
        from simlab.physics.inputs import load_discretizer

        centres = np.asarray(load_discretizer(cfg.states).centres, dtype=float)
        return [(f"s{i}", float(x), float(y)) for i, (x, y) in enumerate(centres)], centres
    goals = _auto_goals(grid, clear, cfg.goal_radius)
    if not goals:
        raise ConfigError(f"no ninth of the map has a free point {cfg.goal_radius:g} m from "
                          f"the walls (the freest is {clear.max():.3g} m from them)",
                          key="goal_radius", fix="a smaller --goal-radius, or --states "
                          "for goals at the state centres")
    return goals, None


def _initial_pose(cfg: ArenaFromMapConfig, grid: Any, clear: NDArray[np.float64],
                  centres: NDArray[np.float64] | None) -> tuple[float, float, float]:
    """The start pose ``(x m, y m, yaw degrees)``: ``start`` (checked to lie on the map), the
    centre of ``start_state``, else the freest state centre or free pixel, facing +y."""
    start, states = cfg.start, cfg.states
    if start is not None:
        h, w = grid.occupancy.shape
        x0, y0 = grid.origin[0], grid.origin[1]
        x1, y1 = x0 + w * grid.resolution, y0 + h * grid.resolution
        if not (x0 <= start[0] <= x1 and y0 <= start[1] <= y1):
            raise ConfigError(f"({start[0]:g}, {start[1]:g}) is outside the map (x {x0:.2f}.."
                              f"{x1:.2f} m, y {y0:.2f}..{y1:.2f} m)", key="start",
                              fix="give --start X,Y,YAW in the map's frame, in metres")
        return start
    if cfg.start_state is not None:
        assert centres is not None  # the config refuses a start state without states
        if cfg.start_state >= len(centres):
            raise ConfigError(f"expected a state in [0, {len(centres) - 1}] of the states "
                              f"file, got {cfg.start_state}", key="start_state", path=states
                              if isinstance(states, str | os.PathLike) else None)
        cx, cy = centres[cfg.start_state]
        return (float(cx), float(cy), 90.0)
    if centres is not None:
        h = grid.occupancy.shape[0]
        col = np.floor((centres[:, 0] - grid.origin[0]) / grid.resolution).astype(int)
        row = h - 1 - np.floor((centres[:, 1] - grid.origin[1]) / grid.resolution).astype(int)
        ok = (row >= 0) & (row < h) & (col >= 0) & (col < grid.occupancy.shape[1])
        c = np.zeros(len(centres))
        c[ok] = clear[row[ok], col[ok]]
        best = int(c.argmax())
        sx, sy = (float(centres[best, 0]), float(centres[best, 1]))
    else:
        r, cc = np.unravel_index(int(clear.argmax()), clear.shape)
        sx, sy = _pixel_xy(grid, int(r), int(cc))
    return (sx, sy, 90.0)


def _arena_text(cfg: ArenaFromMapConfig, start: tuple[float, float, float],
                goals: list[tuple[str, float, float]]) -> str:
    """The arena TOML's text: the map (path relative to ``out``), walls, start, goals."""
    map_yaml, out = cfg.map_yaml, cfg.out
    rel = os.path.relpath(map_yaml.resolve(), out.resolve().parent)
    comment = " ".join(str(map_yaml).split())  # a comment is one line
    lines = [
        f"# Arena built from the map {comment} by `simlab arena-from-map`; map frame kept.",
        f"name = {toml_string(cfg.name or out.stem)}",
        "",
        "[map]",
        f"yaml = {toml_string(Path(rel).as_posix())}",
        f"unknown_as_wall = {'true' if cfg.unknown_as_wall else 'false'}",
        *(["flip_y = true"] if cfg.flip_y else []),
        "",
        "[walls]",
        "height = 0.25",
        "thickness = 0.05",
        "",
        "[start]",
        f"pose = [{start[0]:.4f}, {start[1]:.4f}, {start[2]:.2f}]",
    ]
    for gname, gx, gy in goals:
        lines += ["", "[[goals]]", f"name = {toml_string(gname)}",
                  f"center = [{gx:.4f}, {gy:.4f}]", f"radius = {cfg.goal_radius}"]
    return "\n".join(lines) + "\n"


def toml_string(text: str) -> str:
    """``text`` as a TOML basic string: quotes, backslashes and the control characters
    TOML forbids raw (U+0000-U+001F, U+007F; TOML 1.0, "String") escaped, the rest kept, so
    a name holding ``"`` still gives a valid file."""
    out = []
    for ch in text:
        if ch in '"\\':
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def _check_arena_text(text: str, cfg: ArenaFromMapConfig) -> None:
    """Load ``text`` with the real arena loader before anything is written under ``out``.

    The loader reads a file (the map path in it is relative to the file), so the text goes
    to a hidden temporary file beside ``out``; its errors are reported against the user's
    inputs, never that file: a goal from the states file, the start, or the map."""
    import tempfile

    out = Path(cfg.out)
    try:
        fd, name = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".check.toml",
                                    dir=out.parent)
    except OSError as exc:
        raise type(exc)(exc.errno, exc.strerror, str(out)) from exc
    tmp = Path(name)
    try:
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                fh.write(text)
        except OSError as exc:
            raise type(exc)(exc.errno, exc.strerror, str(out)) from exc
        try:
            load_arena(tmp)
        except ConfigError as exc:
            raise _blame_inputs(exc, cfg) from None
    finally:
        tmp.unlink(missing_ok=True)


def _blame_inputs(exc: ConfigError, cfg: ArenaFromMapConfig) -> ConfigError:
    """An error of the generated arena, said of the input it came from."""
    key = exc.key or ""
    states = cfg.states if isinstance(cfg.states, str | os.PathLike) else None
    if key.startswith("goals[") and cfg.states is not None:
        i = key[len("goals["):].split("]", 1)[0]
        return ConfigError(f"centre {i} (goal s{i}): {exc.problem}", path=states,
                           key="centres", fix="use the states file made for this map "
                           "(simlab discretize --map ...), or drop --states for 3 x 3 goals")
    if key.startswith("start"):
        given = "--start-state" if cfg.start_state is not None else "--start"
        return ConfigError(f"the start pose: {exc.problem}", key=key,
                           fix=f"choose another {given}, on the map's free space")
    return ConfigError(f"{key + ': ' if key else ''}{exc.problem}", path=cfg.map_yaml,
                       fix=exc.fix or "check the map (and --unknown-as-wall, --flip-y)")
