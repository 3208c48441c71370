"""``simlab export-bag``: a collection dataset or a replay as a ROS 2 bag (MCAP)."""

from __future__ import annotations

import argparse

HELP = "write a dataset or a replay as a ROS 2 bag (MCAP; tf, odom, scan, map; ros extra)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("source", help="dataset directory (simlab collect / import-log) or "
                        "replay directory (simlab replay)")
    parser.add_argument("--out", required=True, help="bag directory to write")
    parser.add_argument("--worker", type=int, default=0,
                        help="dataset: which worker's walk to export (default 0)")
    parser.add_argument("--arena", default=None,
                        help="arena (name or TOML) for the scans and the map (default: the "
                        "source's)")
    parser.add_argument("--map", default=None, metavar="YAML",
                        help="map_server map to publish on /map (default: the arena "
                        "rasterized)")
    parser.add_argument("--resolution", type=float, default=0.02, metavar="M",
                        help="pixel size of the rasterized arena map (default 0.02)")
    parser.add_argument("--no-scans", action="store_true",
                        help="leave out /scan (default: cast at every sample pose)")
    parser.add_argument("--overwrite", action="store_true", help="replace a bag in --out")


def run(args: argparse.Namespace) -> int:
    from simlab.ros.export import export_bag

    res = export_bag(args.source, args.out, worker=args.worker, arena=args.arena, map=args.map,
                     scans=not args.no_scans, resolution=args.resolution,
                     overwrite=args.overwrite)
    print(f"{res.samples} pose samples of the {res.source} -> {res.out}")
    return 0
