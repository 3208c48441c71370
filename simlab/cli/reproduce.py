"""``simlab reproduce``: run the thesis experiments (experiments/*.toml), write results.md."""

from __future__ import annotations

import argparse

HELP = ("reproduce the thesis figures: run experiments/*.toml (quick or full budget, local "
        "or Ray) and write DIR/results.md with PASS/FAIL per thesis claim")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", help="output folder (figures, results.md); required unless --list")
    p.add_argument("--only", metavar="NAME[,NAME]", help="run only these experiments")
    p.add_argument("--budget", choices=("quick", "full"), default="quick",
                   help="quick: tiny runs (seconds); full: the thesis's trial counts, 10 seeds")
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="where independent runs go: local process pool or Ray tasks")
    p.add_argument("--address", help="Ray cluster address (default: start Ray locally)")
    p.add_argument("--workers", type=int, help="local processes (default: all cores)")
    p.add_argument("--experiments", metavar="PATH",
                   help="a folder of experiment TOMLs or one file (default: experiments/)")
    p.add_argument("--seed", type=int, default=0, help="root seed (default 0)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace the results of experiments already in --out")
    p.add_argument("--strict", action="store_true", help="exit 1 when a check FAILs too")
    p.add_argument("--list", action="store_true", help="list the experiments and exit")
    p.add_argument("--no-progress", action="store_true")


def run(args: argparse.Namespace) -> int:
    if args.list:
        from simlab.experiments.spec import discover_experiments

        for s in discover_experiments(args.experiments):
            print(f"{s.name:32s} {s.reference}: {s.title} ({len(s.checks)} checks)")
        return 0
    if not args.out:
        from simlab.errors import ConfigError

        raise ConfigError("missing", key="--out", fix="e.g. --out runs/reproduce")
    from simlab.experiments.reproduce import reproduce

    res = reproduce(args.out, only=args.only, budget=args.budget, backend=args.backend,
                    address=args.address, workers=args.workers, experiments=args.experiments,
                    seed=args.seed, overwrite=args.overwrite, progress=not args.no_progress)
    n_pass = sum(c["status"] == "PASS" for e in res.entries for c in e["checks"])
    n_fail = len(res.failed_checks)
    print(f"{len(res.entries)} experiment(s) in {res.wall_seconds:.0f} s: {n_pass} checks PASS, "
          f"{n_fail} FAIL, {len(res.errors)} experiment(s) failed to run -> {res.results_md}")
    if res.errors:
        return 1
    return 1 if (args.strict and n_fail) else 0
