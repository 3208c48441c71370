"""``simlab map``: random exploration in physics, occupancy map in the ROS map_server format."""

from __future__ import annotations

import argparse

HELP = "explore an arena at random in physics and write its occupancy map (map.pgm + map.yaml)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from simlab.orchestration.mapping import MapConfig

    MapConfig.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from simlab.orchestration.mapping import MapConfig, build_map

    result = build_map(MapConfig.from_args(args))
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
