"""``simlab import-bag``: a robot's ROS 2 bag -> a simlab dataset."""

from __future__ import annotations

import argparse

from simlab.cli.import_log import add_segment_arguments, segment_params_from_args

HELP = "import a ROS 2 bag (/amcl_pose or /odom, optional action topic) as a dataset"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bag", help="ROS 2 bag directory (MCAP or sqlite3)")
    parser.add_argument("--states", required=True,
                        help="states: `simlab discretize` JSON or centres text")
    parser.add_argument("--out", required=True, help="dataset directory to write")
    parser.add_argument("--n-actions", type=int, choices=(8, 16), default=8,
                        help="number of actions of the robot (default 8)")
    parser.add_argument("--convention", default="ccw-east",
                        help="direction numbering: simlab, ccw-east or 8 numbers "
                        "(default ccw-east)")
    parser.add_argument("--pose-topic", default=None,
                        help="pose topic (default: /amcl_pose if present, else /odom)")
    parser.add_argument("--action-topic", default="/simlab/action",
                        help="std_msgs/Int32 action topic; absent from the bag -> the pose "
                        "segmentation of import-log (default /simlab/action)")
    parser.add_argument("--segment", action="store_true",
                        help="ignore the action topic and segment the poses")
    add_segment_arguments(parser)
    parser.add_argument("--overwrite", action="store_true", help="replace a dataset in --out")


def run(args: argparse.Namespace) -> int:
    from simlab.ros.importer import import_bag

    segment = segment_params_from_args(args)
    res = import_bag(args.bag, states=args.states, out=args.out, n_actions=args.n_actions,
                     convention=args.convention, pose_topic=args.pose_topic,
                     action_topic=None if args.segment else args.action_topic,
                     segment=segment, overwrite=args.overwrite)
    print(f"{res.samples} pose samples -> {res.decisions} decisions ({res.blocked} blocked), "
          f"actions from the {res.action_source}")
    return 0
