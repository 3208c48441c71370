"""``simlab reproduce``: run the thesis experiments (experiments/*.toml), write results.md.

The options are the fields of :class:`simlab.experiments.reproduce.ReproduceConfig`;
``--list`` is an action of this command, not an option, so it is added here.
"""

from __future__ import annotations

import argparse

HELP = ("reproduce the thesis figures: run experiments/*.toml (quick or full budget, local "
        "or Ray) and write DIR/results.md with PASS/FAIL per thesis claim")


def add_arguments(p: argparse.ArgumentParser) -> None:
    from simlab.experiments.reproduce import ReproduceConfig

    ReproduceConfig.add_arguments(p)
    p.add_argument("--list", action="store_true", help="list the experiments and exit")


def run(args: argparse.Namespace) -> int:
    from simlab.experiments.reproduce import ReproduceConfig

    cfg = ReproduceConfig.from_args(args)
    if args.list:
        from simlab.experiments.spec import discover_experiments

        for s in discover_experiments(cfg.experiments):
            print(f"{s.name:32s} {s.reference}: {s.title} ({len(s.checks)} checks)")
        return 0
    from simlab.experiments.reproduce import reproduce

    res = reproduce(cfg)  # no --out: a ConfigError naming --out
    n_pass = sum(c["status"] == "PASS" for e in res.entries for c in e["checks"])
    n_fail = len(res.failed_checks)
    print(f"{len(res.entries)} experiment(s) in {res.wall_seconds:.0f} s: {n_pass} checks PASS, "
          f"{n_fail} FAIL, {len(res.errors)} experiment(s) failed to run -> {res.results_md}")
    if res.errors:
        return 1
    return 1 if (cfg.strict and n_fail) else 0
