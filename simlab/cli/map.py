"""``simlab map``: random exploration in physics, occupancy map in the ROS map_server format."""

from __future__ import annotations

import argparse

HELP = "explore an arena at random in physics and write its occupancy map (map.pgm + map.yaml)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--arena", default="table", help="built-in arena name or .toml path")
    parser.add_argument(
        "--minutes",
        type=float,
        default=10.0,
        help="robot time to explore, driving + idle latency (default 10; the thesis: 73.1)",
    )
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument(
        "--out", default=None, metavar="DIR", help="output directory (default maps/<arena>)"
    )
    parser.add_argument(
        "--resolution", type=float, default=0.01, metavar="M", help="cell size (default 0.01 m)"
    )
    parser.add_argument(
        "--pose-source",
        choices=("truth", "odometry"),
        default="truth",
        help="pose to map with: truth (stand-in for GMapping's corrected pose) or "
        "odometry (shows the drift)",
    )
    parser.add_argument("--overwrite", action="store_true", help="replace existing outputs")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from simlab.orchestration.mapping import build_map

    out = args.out
    if out is None:
        out = Path("maps") / Path(str(args.arena)).stem
    result = build_map(
        arena=args.arena,
        minutes=args.minutes,
        seed=args.seed,
        out=out,
        resolution=args.resolution,
        pose_source=args.pose_source,
        overwrite=args.overwrite,
        progress=not args.no_progress,
    )
    acc = result.accuracy
    h, w = result.map.shape
    print(
        f"map {w} x {h} px at {result.map.resolution} m -> {result.yaml_path} "
        f"({result.n_scans} scans, {result.n_actions} actions, {result.n_blocked} blocked, "
        f"{result.robot_seconds / 60:.1f} robot min)"
    )
    print(
        f"vs arena geometry: walls {100 * acc.wall_correct:.1f} % correct, "
        f"{100 * acc.wall_coverage:.1f} % of the wall surface seen, "
        f"free space {100 * acc.free_correct:.1f} % correct "
        f"(+-{acc.tolerance_px} px band); odometry drift {result.final_drift:.3f} m"
    )
    return 0
