"""``simlab import-log``: a real robot's pose log (no action column) -> a simlab dataset."""

from __future__ import annotations

import argparse

HELP = "segment a pose log 't x y yaw [cell [n_cells]]' into decisions and write a dataset"


def add_segment_arguments(parser: argparse.ArgumentParser) -> None:
    """The decision-segmentation thresholds (:class:`~simlab.data.poselog.SegmentParams`)."""
    from simlab.data.poselog import SegmentParams

    d = SegmentParams()
    parser.add_argument("--move-speed", type=float, default=d.move_speed, metavar="M/S",
                        help=f"translation faster than this is a move (default {d.move_speed})")
    parser.add_argument("--turn-rate", type=float, default=d.turn_rate, metavar="RAD/S",
                        help=f"rotation faster than this is a turn (default {d.turn_rate})")
    parser.add_argument("--join-gap", type=float, default=d.join_gap, metavar="S",
                        help="longest pause between a turn and its move "
                        f"(default {d.join_gap})")
    parser.add_argument("--speed-split", type=float, default=d.speed_split, metavar="M/S",
                        help="16 actions: faster mean translation = fast primitive "
                        f"(default {d.speed_split})")


def segment_params_from_args(args: argparse.Namespace):  # -> SegmentParams
    """The :class:`~simlab.data.poselog.SegmentParams` of :func:`add_segment_arguments`."""
    from simlab.data.poselog import SegmentParams

    return SegmentParams(move_speed=args.move_speed, turn_rate=args.turn_rate,
                         join_gap=args.join_gap, speed_split=args.speed_split)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("log", help="pose log: whitespace text 't x y yaw [cell [n_cells]]', "
                        "'#' comments")
    parser.add_argument("--states", required=True,
                        help="states: `simlab discretize` JSON or centres text ('x y' or "
                        "'id x y theta' lines)")
    parser.add_argument("--out", required=True, help="dataset directory to write")
    parser.add_argument("--n-actions", type=int, choices=(8, 16), default=8,
                        help="number of actions of the robot (default 8)")
    parser.add_argument("--convention", default="ccw-east",
                        help="direction numbering: simlab, ccw-east or 8 comma-separated "
                        "numbers (default ccw-east, the ISIR robot's)")
    parser.add_argument("--use-cell-column", action="store_true",
                        help="states from the log's cell column (default: nearest centre)")
    add_segment_arguments(parser)
    parser.add_argument("--map", default=None, metavar="YAML",
                        help="map_server map to check the poses against (default: no check)")
    parser.add_argument("--flip-y", action="store_true",
                        help="flip the --map image vertically (stored bottom row first)")
    parser.add_argument("--overwrite", action="store_true", help="replace a dataset in --out")


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from simlab.data.poselog import import_log

    segment = segment_params_from_args(args)
    res = import_log(args.log, states=args.states, out=args.out, n_actions=args.n_actions,
                     convention=args.convention, use_cell_column=args.use_cell_column,
                     segment=segment, overwrite=args.overwrite, map=args.map,
                     flip_y=args.flip_y)
    per_action = np.bincount(res.actions, minlength=res.action_set.n_actions)
    print(f"{res.samples} samples -> {res.decisions} decisions ({res.blocked} blocked), "
          f"{res.action_set.describe()}, states from the {res.state_source}")
    print("decisions per action: " + " ".join(str(int(n)) for n in per_action))
    if args.map is not None:
        print(f"{res.off_map} pose samples off the map's free pixels")
    print(f"wrote {res.out}")
    return 0
