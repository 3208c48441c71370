"""``simlab arena-from-map``: an arena TOML for a map_server map (map frame kept)."""

from __future__ import annotations

import argparse

HELP = "write an arena TOML that extrudes a map_server map's walls (map frame kept)"


def _start(text: str) -> tuple[float, float, float]:
    try:
        x, y, yaw = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y,YAW_DEGREES, got {text!r}") from None
    return x, y, yaw


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("map", metavar="MAP.yaml", help="map_server YAML (image beside it)")
    parser.add_argument("--out", required=True, help="arena TOML to write")
    parser.add_argument("--states", default=None,
                        help="states file (JSON): one goal per state centre (default: 3 x 3 "
                             "goals at the freest points)")
    parser.add_argument("--start", type=_start, default=None, metavar="X,Y,YAW",
                        help="start pose in map coordinates, yaw in degrees (default: the "
                             "freest state centre or pixel, facing +y)")
    parser.add_argument("--goal-radius", type=float, default=0.15,
                        help="radius of every goal circle in m (default 0.15)")
    parser.add_argument("--unknown-as-wall", action="store_true",
                        help="extrude unknown pixels as walls too (default: only occupied)")
    parser.add_argument("--name", default=None, help="arena name (default: the file's stem)")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --out")


def run(args: argparse.Namespace) -> int:
    from simlab.physics.arena import load_arena
    from simlab.physics.map_arena import arena_from_map

    path = arena_from_map(args.map, args.out, states=args.states, start=args.start,
                          goal_radius=args.goal_radius, unknown_as_wall=args.unknown_as_wall,
                          name=args.name, overwrite=args.overwrite)
    arena = load_arena(path)
    x0, y0, x1, y1 = arena.bounds
    n_boxes = len(arena.map_walls.boxes) if arena.map_walls is not None else 0
    print(f"wrote {path}: arena {arena.name}, x {x0:.2f}..{x1:.2f} m, y {y0:.2f}..{y1:.2f} m, "
          f"{n_boxes} wall boxes, {len(arena.goals)} goals")
    return 0
