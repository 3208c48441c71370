"""``simlab discretize``: Voronoi states on an occupancy map (thesis Fig. 3.5)."""

from __future__ import annotations

import argparse

HELP = "place Voronoi state centres on a map_server map and save them as JSON (and a figure)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--map", required=True, metavar="YAML", help="map_server map.yaml")
    parser.add_argument("--out", required=True, metavar="JSON", help="states file to write")
    how = parser.add_mutually_exclusive_group()
    how.add_argument(
        "--states", type=int, default=None, metavar="N", help="number of states (default 41)"
    )
    how.add_argument(
        "--radius",
        type=float,
        default=None,
        metavar="M",
        help="cell-radius rule: N = eroded free area / (pi r^2) (thesis r_V = 0.09 m)",
    )
    how.add_argument(
        "--centres",
        default=None,
        metavar="TXT",
        help="use these centres (text file, one 'x y' or 'id x y theta' line per state, "
        "metres; ids number the states)",
    )
    parser.add_argument(
        "--renumber",
        action="store_true",
        help="renumber --centres row-major from the top-left (default: file order)",
    )
    parser.add_argument(
        "--robot-radius",
        type=float,
        default=0.113,
        metavar="M",
        help="erode free space by this radius (default 0.113 m, TurtleBot3 Burger)",
    )
    parser.add_argument(
        "--all-components",
        action="store_true",
        help="keep every free region, not only the largest",
    )
    parser.add_argument(
        "--flip-y",
        action="store_true",
        help="flip the map image vertically (images stored bottom row first; default off)",
    )
    parser.add_argument("--png", default=None, metavar="PNG", help="also draw the states figure")
    parser.add_argument(
        "--dataset",
        default=None,
        metavar="DIR",
        help="Parquet dataset (column s) to colour the figure by visits",
    )
    parser.add_argument("--overwrite", action="store_true", help="replace existing outputs")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")


def run(args: argparse.Namespace) -> int:
    from discretize.voronoi import discretize_map

    result = discretize_map(
        args.map,
        args.out,
        args.states,
        radius=args.radius,
        robot_radius=args.robot_radius,
        centres=args.centres,
        renumber=args.renumber,
        component="all" if args.all_components else "largest",
        png=args.png,
        dataset=args.dataset,
        overwrite=args.overwrite,
        progress=not args.no_progress,
        flip_y=args.flip_y,
    )
    disc = result.discretizer
    line = f"{disc.n_states} states ({disc.method}) -> {result.out}"
    if result.png is not None:
        line += f", figure {result.png}"
    print(line)
    print(f"content hash {disc.content_hash()[:16]}, map hash {(disc.map_hash or '-')[:16]}")
    if result.visits is not None:
        unvisited = int((result.visits == 0).sum())
        print(f"visits: {int(result.visits.sum())} total, {unvisited} states unvisited")
    return 0
