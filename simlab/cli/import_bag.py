"""``simlab import-bag``: a robot's ROS 2 bag -> a simlab dataset.

The options are the fields of :class:`simlab.ros.importer.ImportBagConfig`.
"""

from __future__ import annotations

import argparse

HELP = "import a ROS 2 bag (/amcl_pose or /odom, optional action topic) as a dataset"

#: What comes back exactly from a bag and what to a tolerance (simlab.ros.bag's docstring).
EXACTNESS = (
    "Exactness: x, y and a recorded duration are exact (float64 in the messages); yaw is "
    "exact for every yaw in [-pi, pi] that simlab export-bag wrote (its quaternion is "
    "chosen so), another comes back wrapped into that range; t comes back exactly when it "
    "is a whole number of nanoseconds or at least 2**23 s (a UNIX time), otherwise to the "
    "nearest nanosecond (at most 0.5 ns off: a bag's stamps are integer nanoseconds).")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from simlab.ros.importer import ImportBagConfig

    parser.epilog = EXACTNESS
    ImportBagConfig.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from simlab.ros.importer import ImportBagConfig, import_bag

    res = import_bag(ImportBagConfig.from_args(args))
    print(f"{res.samples} pose samples -> {res.decisions} decisions ({res.blocked} blocked), "
          f"actions from the {res.action_source}")
    return 0
