"""``simlab collect``: the epsilon = 1 random-walk transition dataset."""

from __future__ import annotations

import argparse

HELP = "collect a random-walk transition dataset (Parquet parts + manifest)"


#: Direct primitive flags: (flag, PrimitiveParams field, type, help).
PRIMITIVE_FLAGS = (
    ("--drive-time", "drive_time", float, "s of straight driving per primitive (fixed mode)"),
    ("--slow-speed", "slow_speed", float, "m/s of the slow actions"),
    ("--fast-speed", "fast_speed", float, "m/s of the fast actions"),
    ("--decision-latency", "decision_latency", float, "s of idle time between primitives"),
    ("--mode", "mode", str, "primitive mode: fixed or until_state_change"),
    ("--max-drive-time", "max_drive_time", float, "s, timeout of until_state_change"),
)


def add_primitive_arguments(parser: argparse.ArgumentParser) -> None:
    """``--primitives FILE.toml`` and the direct flags of :data:`PRIMITIVE_FLAGS`."""
    parser.add_argument("--primitives", default=None, metavar="FILE.toml",
                        help="primitive settings ([primitives] table; default: built-in "
                             "PrimitiveParams)")
    for flag, field, kind, text in PRIMITIVE_FLAGS:
        parser.add_argument(flag, type=kind, default=None,
                            choices=("fixed", "until_state_change") if field == "mode" else None,
                            help=f"{text} (default: from --primitives or built-in)")


def primitive_params_from_args(args: argparse.Namespace):  # -> PrimitiveParams | None
    """The PrimitiveParams of ``--primitives`` overridden by the direct flags; None when
    none of them is given (the command's default applies)."""
    from simlab.physics.motion import PrimitiveParams

    changes = {f: getattr(args, flag[2:].replace("-", "_")) for flag, f, _k, _t in
               PRIMITIVE_FLAGS}
    if args.primitives is None and all(v is None for v in changes.values()):
        return None
    base = PrimitiveParams() if args.primitives is None else PrimitiveParams.from_toml(
        args.primitives)
    return base.replace(**changes)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--arena", default="table",
                        help="built-in arena name or .toml path (default: table)")
    parser.add_argument("--states", required=True,
                        help="states file written by `simlab discretize` (JSON)")
    budget = parser.add_mutually_exclusive_group(required=True)
    budget.add_argument("--hours", type=float,
                        help="total simulated robot time in hours, split over the workers")
    budget.add_argument("--transitions", type=int, help="total number of transitions")
    parser.add_argument("--seed", type=int, default=0, help="root seed (default: 0)")
    parser.add_argument("--workers", type=int, default=1,
                        help="parallel walks, one arena per process (default: 1)")
    parser.add_argument("--out", required=True, help="dataset directory (new or empty)")
    parser.add_argument("--resume", action="store_true",
                        help="continue an interrupted collection in --out")
    parser.add_argument("--backend", choices=("local", "ray"), default="local",
                        help="local process pool or Ray tasks (default: local)")
    parser.add_argument("--address", default=None,
                        help="Ray cluster address (ray backend; default: start Ray locally)")
    parser.add_argument("--part-size", type=int, default=None,
                        help="transitions per part file (default: 250)")
    parser.add_argument("--pose-source", choices=("truth", "odometry", "mcl"), default="truth",
                        help="poses that are recorded and discretized (default: truth)")
    parser.add_argument("--simulator", choices=("physics", "kinematic"), default="physics",
                        help="physics (PyBullet, default) or kinematic (physics-free dry run)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_primitive_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from simlab.data.collect import DEFAULT_PART_SIZE, collect
    from simlab.errors import ConfigError

    params = primitive_params_from_args(args)
    if params is not None and args.simulator == "kinematic":
        raise ConfigError("primitive settings apply to the physics simulator only",
                          key="--primitives", fix="drop them or use --simulator physics")

    result = collect(
        args.arena,
        args.states,
        out=args.out,
        hours=args.hours,
        transitions=args.transitions,
        seed=args.seed,
        workers=args.workers,
        resume=args.resume,
        backend=args.backend,
        address=args.address,
        part_size=DEFAULT_PART_SIZE if args.part_size is None else args.part_size,
        pose_source=args.pose_source,
        simulator=args.simulator,
        params=params,
        progress=not args.no_progress,
    )
    rate = result.transitions / result.wall_seconds if result.parts_written else 0.0
    kept = result.parts - result.parts_written
    print(
        f"{result.directory}: {result.transitions} transitions in {result.parts} parts, "
        f"{result.simulated_hours:.2f} simulated h"
        + (f" ({kept} parts were already there)" if kept else "")
        + f"; {result.wall_seconds:.1f} s wall"
        + (f", {rate:.0f} transitions/s" if result.parts_written and not kept else "")
        + ("" if result.complete else " (incomplete)")
    )
    return 0
