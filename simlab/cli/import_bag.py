"""``simlab import-bag``: a robot's ROS 2 bag -> a simlab dataset.

The options are the fields of :class:`simlab.ros.importer.ImportBagConfig`.
"""

from __future__ import annotations

import argparse

HELP = "import a ROS 2 bag (/amcl_pose or /odom, optional action topic) as a dataset"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from simlab.ros.importer import ImportBagConfig

    ImportBagConfig.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from simlab.ros.importer import ImportBagConfig, import_bag

    res = import_bag(ImportBagConfig.from_args(args))
    print(f"{res.samples} pose samples -> {res.decisions} decisions ({res.blocked} blocked), "
          f"actions from the {res.action_source}")
    return 0
