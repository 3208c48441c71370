"""``simlab arena-from-map``: an arena TOML for a map_server map (map frame kept).

The options are the fields of :class:`simlab.physics.map_arena.ArenaFromMapConfig`.
"""

from __future__ import annotations

import argparse

HELP = "write an arena TOML that extrudes a map_server map's walls (map frame kept)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from simlab.physics.map_arena import ArenaFromMapConfig

    ArenaFromMapConfig.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from simlab.physics.arena import load_arena
    from simlab.physics.map_arena import ArenaFromMapConfig, arena_from_map

    path = arena_from_map(ArenaFromMapConfig.from_args(args))
    arena = load_arena(path)
    x0, y0, x1, y1 = arena.bounds
    n_boxes = len(arena.map_walls.boxes) if arena.map_walls is not None else 0
    print(f"wrote {path}: arena {arena.name}, x {x0:.2f}..{x1:.2f} m, y {y0:.2f}..{y1:.2f} m, "
          f"{n_boxes} wall boxes, {len(arena.goals)} goals")
    return 0
