"""``simlab export-bag``: a collection dataset or a replay as a ROS 2 bag (MCAP).

The options are the fields of :class:`simlab.ros.export.ExportBagConfig`.
"""

from __future__ import annotations

import argparse

HELP = "write a dataset or a replay as a ROS 2 bag (MCAP; tf, odom, scan, map; ros extra)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from simlab.ros.export import ExportBagConfig

    ExportBagConfig.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from simlab.ros.export import ExportBagConfig, export_bag

    res = export_bag(ExportBagConfig.from_args(args))
    print(f"{res.samples} pose samples of the {res.source} -> {res.out}")
    return 0
