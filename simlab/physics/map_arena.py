"""Write an arena TOML for a map_server map (``simlab arena-from-map``).

The arena names the map (``[map] yaml``, relative to the TOML) and keeps its frame, so
the real robot's poses, centres and goals are used unchanged (see
:mod:`simlab.physics.arena`). Decisions where the issue left it open:

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

from simlab import validation
from simlab.errors import ConfigError
from simlab.io import atomic_write_text, ensure_new
from simlab.options import CommandConfig, command, option
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
    goal_radius: float = option(0.15, "radius of every goal circle in m")
    unknown_as_wall: bool = option(
        False, "extrude unknown pixels as walls too (default: only occupied)")
    name: str | None = option(None, "arena name (default: the file's stem)")
    overwrite: bool = option(False, "replace an existing --out")

    def validate(self) -> None:
        validation.positive(self.goal_radius, "goal_radius")
        if self.start is not None:
            object.__setattr__(self, "start", _check_start(self.start))


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
    * ``name``: arena name (default: the TOML's stem).
    * ``overwrite``: replace an existing ``out``.

    The written file is loaded back (validated) before it is renamed into place.
    """
    from discretize.mapio import read_map

    out, map_yaml, states, start, goal_radius = (cfg.out, cfg.map_yaml, cfg.states, cfg.start,
                                                 cfg.goal_radius)
    ensure_new(out, overwrite=cfg.overwrite, what="arena file")
    grid = read_map(map_yaml)
    clear = _clearance(grid.occupancy, grid.resolution)
    if clear.max() < START_CLEARANCE:
        raise ConfigError("no free pixel is far enough from the walls for the robot",
                          path=map_yaml, fix="check the map's thresholds")
    if states is not None:
        from simlab.physics.inputs import load_discretizer

        centres = np.asarray(load_discretizer(states).centres, dtype=float)
        goals = [(f"s{i}", float(x), float(y)) for i, (x, y) in enumerate(centres)]
    else:
        goals = _auto_goals(grid, clear, goal_radius)
    if start is None:
        if states is not None:
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
        start = (sx, sy, 90.0)
    rel = os.path.relpath(map_yaml.resolve(), out.resolve().parent)
    lines = [
        f"# Arena built from the map {map_yaml} by `simlab arena-from-map`; map frame kept.",
        f'name = "{cfg.name or out.stem}"',
        "",
        "[map]",
        f'yaml = "{Path(rel).as_posix()}"',
        f"unknown_as_wall = {'true' if cfg.unknown_as_wall else 'false'}",
        "",
        "[walls]",
        "height = 0.25",
        "thickness = 0.05",
        "",
        "[start]",
        f"pose = [{start[0]:.4f}, {start[1]:.4f}, {start[2]:.2f}]",
    ]
    for gname, gx, gy in goals:
        lines += ["", "[[goals]]", f'name = "{gname}"', f"center = [{gx:.4f}, {gy:.4f}]",
                  f"radius = {goal_radius}"]
    text = "\n".join(lines) + "\n"
    tmp = out.with_name(f".{out.name}.check.toml")
    try:
        tmp.write_text(text, encoding="utf-8")
        load_arena(tmp)  # validate with the real loader (paths relative to the same dir)
    finally:
        tmp.unlink(missing_ok=True)
    atomic_write_text(out, text)
    return out
