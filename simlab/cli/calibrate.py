"""``simlab calibrate``: fit the primitive parameters so the simulated T matches a real one."""

from __future__ import annotations

import argparse

HELP = "calibrate primitive parameters against a real transition count table"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--real", required=True,
                        help="real counts: CSV/JSON (s, a, s_next, count) or ISIR model JSON")
    parser.add_argument("--states", required=True,
                        help="states file (JSON of `simlab discretize`) the real states use")
    parser.add_argument("--arena", default="table", help="arena name or TOML (default table)")
    parser.add_argument("--out", required=True,
                        help="output directory: primitives.toml, report.json/.md, figure")
    parser.add_argument("--hours-per-candidate", type=float, default=2.0,
                        help="simulated hours of each candidate's walk (default 2)")
    parser.add_argument("--candidates", type=int, default=16,
                        help="candidates evaluated, the starting point included (default 16)")
    parser.add_argument("--workers", type=int, default=2,
                        help="candidates simulated in parallel processes (default 2)")
    parser.add_argument("--n-actions", type=int, default=16, choices=(8, 16),
                        help="actions of the real table (default 16)")
    parser.add_argument("--convention", default="simlab",
                        help="direction numbering of the real table: simlab, ccw-east or 8 "
                             "comma-separated numbers (default simlab)")
    parser.add_argument("--speed", default="slow", choices=("slow", "fast"),
                        help="primitive speed of an 8-action table (default slow)")
    parser.add_argument("--real-hours", type=float, default=None,
                        help="duration of the real data in hours; fits the decision latency "
                             "(default: unknown, latency kept)")
    parser.add_argument("--space", default=None,
                        help="TOML [parameters.NAME] low/high/scale of the searched fields "
                             "(default: drive time, used speeds, detector margin)")
    parser.add_argument("--primitives", default=None,
                        help="[primitives] TOML to start from (default: built-in defaults)")
    parser.add_argument("--simulator", default="physics", choices=("physics", "kinematic"),
                        help="physics (default) or the physics-free kinematic dry run")
    parser.add_argument("--pose-source", default="truth",
                        help="pose source of the simulated walks (default truth)")
    parser.add_argument("--n-boot", type=int, default=200,
                        help="bootstrap resamples of the sampling floor (default 200)")
    parser.add_argument("--unvisited", default="report", choices=("report", "max"),
                        help="real pairs never simulated: report them (default) or count "
                             "them as distance 1")
    parser.add_argument("--objective", default="excess", choices=("excess", "tv", "loglik"),
                        help="minimised: the TV distance in excess of its sampling floor "
                             "(default; unbiased with few real visits per pair), the plain "
                             "visit-weighted TV distance, or bits per real transition under "
                             "the simulated T")
    parser.add_argument("--no-confirm", action="store_true",
                        help="skip re-simulating the winner on a fresh seed")
    parser.add_argument("--seed", type=int, default=0, help="seed of walks and search (default 0)")
    parser.add_argument("--overwrite", action="store_true", help="replace existing outputs")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    from simlab.actions import parse_action_set
    from simlab.calibration.command import calibrate_files
    from simlab.calibration.search import CalibrationConfig

    aset = parse_action_set(args.n_actions, args.convention, args.speed)
    config = CalibrationConfig(
        hours_per_candidate=args.hours_per_candidate, candidates=args.candidates,
        workers=args.workers, seed=args.seed, simulator=args.simulator,
        pose_source=args.pose_source, n_boot=args.n_boot, unvisited=args.unvisited,
        objective=args.objective,
        confirm=not args.no_confirm, progress=not args.no_progress,
    )
    done = calibrate_files(args.real, args.states, args.arena, args.out, config=config,
                           action_set=aset, real_hours=args.real_hours, space=args.space,
                           primitives=args.primitives, overwrite=args.overwrite)
    r = done.result
    values = ", ".join(f"{n}={getattr(r.params, n):.4g}" for n in r.space.names)
    print(f"best of {len(r.candidates)} candidates: {values}")
    print(f"TV distance {r.final.distance:.3f} (floor {r.floor.median:.3f}, matched "
          f"{r.matched_floor.median:.3f}); argmax agreement {r.agreement:.0%}")
    print("wrote " + ", ".join(str(p) for p in done.files.values()))
    return 0
