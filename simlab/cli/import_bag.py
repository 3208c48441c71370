"""``simlab import-bag``: a robot's ROS 2 bag -> a simlab dataset."""

from __future__ import annotations

import argparse

HELP = "import a ROS 2 bag (/amcl_pose or /odom, optional action topic) as a dataset"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from simlab.data.poselog import SegmentParams

    d = SegmentParams()
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
    parser.add_argument("--move-speed", type=float, default=d.move_speed, metavar="M/S",
                        help=f"translation faster than this is a move (default {d.move_speed})")
    parser.add_argument("--turn-rate", type=float, default=d.turn_rate, metavar="RAD/S",
                        help=f"rotation faster than this is a turn (default {d.turn_rate})")
    parser.add_argument("--join-gap", type=float, default=d.join_gap, metavar="S",
                        help=f"longest pause between a turn and its move (default {d.join_gap})")
    parser.add_argument("--speed-split", type=float, default=d.speed_split, metavar="M/S",
                        help="16 actions: faster mean translation = fast primitive "
                        f"(default {d.speed_split})")
    parser.add_argument("--overwrite", action="store_true", help="replace a dataset in --out")


def run(args: argparse.Namespace) -> int:
    from simlab.data.poselog import SegmentParams
    from simlab.ros.importer import import_bag

    segment = SegmentParams(move_speed=args.move_speed, turn_rate=args.turn_rate,
                            join_gap=args.join_gap, speed_split=args.speed_split)
    res = import_bag(args.bag, states=args.states, out=args.out, n_actions=args.n_actions,
                     convention=args.convention, pose_topic=args.pose_topic,
                     action_topic=None if args.segment else args.action_topic,
                     segment=segment, overwrite=args.overwrite)
    print(f"{res.samples} pose samples -> {res.decisions} decisions ({res.blocked} blocked), "
          f"actions from the {res.action_source}")
    return 0
