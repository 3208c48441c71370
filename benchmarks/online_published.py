"""Does ``simlab online --protocol published`` reproduce the published navigation experiment?

Dromnelle et al. (2022, Int. J. Social Robotics, sec. 4) ran MB alone, MF alone and the
meta-controlled pair (random, entropy, entropy_and_cost with kappa 1) for 3,200 decisions
on the model a TurtleBot built in 13 hours in the ISIR arena, in three tasks: stable; the
goal moving from 18 to 34 at decision 1,601; a passage closed there (the more used of
20-21 and 6-7). The published code's own runs on that model (10 repetitions per arm) gave
the figures of :data:`PUBLISHED`.

This benchmark runs the same three tasks x five arms x ``--seeds`` runs x 3,200 decisions
on the real model in ``--lab`` (``../shared/real-lab``: ``realisticNavWorld.json`` and the
published after-change files, each read as ``simlab estimate --counts FILE --n-actions 8
--convention ccw-east`` reads it), with ``--protocol published`` and then with simlab's
own protocol, and prints each table beside the published figures with the relative
difference. ``--ablations`` adds one table per rule of the published protocol switched
back to simlab's value (what each rule is worth).

Targets: every arm's total and post-change reward within 10 % of the published figure;
entropy_and_cost's cost relative to MB within 0.05 of the published ratio. Costs are
simlab's planning costs (value-iteration backups of the plans made); ``filtered`` is the
cost the published log records instead (the deciding expert's low-pass filtered cost at
the state, read before its plan), computed from the same runs.

Run: ``python benchmarks/online_published.py [--seeds 10] [--workers 2] [--ablations]``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ARMS = ("mb", "mf", "random", "entropy", "entropy_and_cost_k1")
CRITERIA = ("mb", "mf", "random", "entropy", "entropy_and_cost")

#: The published code's runs on the real model (10 repetitions each): total reward, reward
#: after decision 1,600 (None: not published), and entropy_and_cost's cost relative to MB.
PUBLISHED = {
    "stable": {"reward": {"mb": 229, "mf": 154, "random": 216, "entropy": 229,
                          "entropy_and_cost_k1": 229},
               "after": {}, "cost": 0.36},
    "goal": {"reward": {"mb": 194, "mf": 87, "random": 162, "entropy": 193,
                        "entropy_and_cost_k1": 191},
             "after": {"mb": 94, "mf": 48, "entropy_and_cost_k1": 90}, "cost": 0.41},
    "passages": {"reward": {"mb": 194, "mf": 113, "random": 154, "entropy": 193,
                            "entropy_and_cost_k1": 168},
                 "after": {}, "cost": 0.59},
}
FILES = {"base": "realisticNavWorld.json", "goal": "realisticNavWorld_newGoal.json",
         "20-21": "realisticNavWorld_noTrans20-21.json",
         "6-7": "realisticNavWorld_noTrans6-7.json"}

#: One ablation per published rule: the option set back to simlab's value (and the early
#: published simulator's restart, which the published protocol leaves out).
ABLATIONS = {
    "reset teleport": {"reset": "teleport"},
    "change pays": {"change_pays": True},
    "first state drawn": {"first_state": "drawn"},
    "no phantom start": {"phantom_start": False},
    "ties to MF": {"ties": "mf"},
    "goal moves kept": {"forget_goal_moves": False},
    "goal reward to every move": {"reward_links": False},
    "MB incremental backups": {"mb_params": {"incremental": True}},
    "tau 0.02": {"mf_params": {"tau": 0.02}, "mb_params": {"tau": 0.02}},
    "restart after 200 (first simulator)": {"restart_after": 200},
}


def read_models(lab: Path, folder: Path) -> dict[str, object]:
    """The real model and the after-change models, estimated as the README's command does."""
    from simlab.data.estimate import EstimateConfig, estimate
    from simlab.data.mdp import load_mdp

    out = {}
    for key, name in FILES.items():
        npz = folder / (Path(name).stem + ".npz")
        estimate(EstimateConfig(counts=lab / name, n_actions=8, convention="ccw-east",
                                out=npz, plot=False))
        out[key] = load_mdp(npz)
    return out


def task_options(task: str, models: dict[str, object]) -> dict[str, object]:
    """The options of one task on the real model (the published files after the change)."""
    if task == "stable":
        return {}
    if task == "goal":
        return {"change": "goal", "new_goal": (34,), "after": (models["goal"],)}
    return {"change": "model", "after": (models["20-21"], models["6-7"]), "use_states": (19, 7)}


def filtered_cost(runs: list[dict[str, np.ndarray]]) -> float:
    """Total over the run of the deciding expert's filtered cost read before its plan
    (what the published log records), mean over runs."""
    return float(np.mean([np.where(r["expert"] == 1, r["c_mb"], r["c_mf"]).sum()
                          for r in runs]))


def run_table(models: dict[str, object], executor: object, seeds: int, decisions: int,
              **options: object) -> dict[str, dict[str, object]]:
    """Every task's summary of one protocol (``options`` given to every run)."""
    from simlab.online.command import OnlineConfig, online

    tables = {}
    for task in PUBLISHED:
        cfg = OnlineConfig(mdp=models["base"], criteria=CRITERIA, kappas=(1.0,), seeds=seeds,
                           decisions=decisions, progress=False, plots=False,
                           **task_options(task, models), **options)
        res = online(cfg, executor=executor)
        summary = res.summary
        summary["filtered_vs_mb"] = {arm: filtered_cost(res.logs[arm])
                                     / filtered_cost(res.logs["mb"]) for arm in ARMS}
        tables[task] = summary
    return tables


def _rel(ours: float, theirs: float | None) -> str:
    return "" if theirs is None else f"{(ours - theirs) / theirs:+.1%}"


def _z(ours: float, sd: float, n: int, theirs: float | None) -> str:
    """The difference in standard errors: ours over ``n`` runs, the published mean over its
    10 runs (its spread estimated by ours)."""
    if theirs is None:
        return ""
    se = sd * np.sqrt(1.0 / n + 1.0 / 10.0)
    return f"{(ours - theirs) / se:+.1f}" if se > 0 else ""


def _runs_sd(a: dict[str, object], key: str) -> tuple[float, float]:
    rec = a[key]
    return rec["mean"], rec["std"]


def print_table(title: str, tables: dict[str, dict[str, object]], n: int) -> int:
    """The table beside the published figures; returns how many targets are missed."""
    print(f"\n== {title} ==")
    print("reward: mean over the runs (sd between runs); diff: relative to the published mean; "
          "z: the difference in standard errors of the two means (published: 10 runs)")
    print(f"{'task':9s} {'arm':20s} {'reward (sd)':>13s} {'pub.':>5s} {'diff':>7s} {'z':>5s} | "
          f"{'after (sd)':>12s} {'pub.':>4s} {'diff':>7s} {'z':>5s} | restarts  chosen")
    missed = 0
    for task, s in tables.items():
        pub = PUBLISHED[task]
        for arm in ARMS:
            a = s["arms"][arm]
            (r, sd), pr, pa = _runs_sd(a, "reward"), pub["reward"].get(arm), pub["after"].get(arm)
            missed += abs(r - pr) > 0.1 * pr
            line = (f"{task:9s} {arm:20s} {r:6.1f} ({sd:4.1f}) {pr:5d} {_rel(r, pr):>7s} "
                    f"{_z(r, sd, n, pr):>5s} | ")
            if "reward_after" in a:
                after, sda = _runs_sd(a, "reward_after")
                missed += pa is not None and abs(after - pa) > 0.1 * pa
                line += (f"{after:5.1f} ({sda:4.1f}) "
                         + (f"{pa:4d} {_rel(after, pa):>7s} {_z(after, sda, n, pa):>5s}"
                            if pa is not None else f"{'':18s}"))
            else:
                line += f"{'':31s}"
            chosen = ""
            if "chosen" in a:
                chosen = ", ".join(f"{Path(c).stem.split('_')[-1]} x{a['chosen'].count(c)}"
                                   for c in dict.fromkeys(a["chosen"]))
            print(line + f" | {a['restarts']['runs']:8d}  {chosen}")
        ec = s["arms"]["entropy_and_cost_k1"]
        cost, filt = ec["cost_vs_mb"], s["filtered_vs_mb"]["entropy_and_cost_k1"]
        missed += abs(cost - pub["cost"]) > 0.05
        print(f"{task:9s} {'e&c cost vs MB':20s} {cost:13.2f} {pub['cost']:5.2f} "
              f"{cost - pub['cost']:+7.2f}       | filtered (as logged) {filt:.2f} "
              f"({filt - pub['cost']:+.2f})")
    print(f"targets missed: {missed}")
    return missed


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lab", type=Path,
                        default=Path(__file__).resolve().parents[2] / "shared" / "real-lab")
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--decisions", type=int, default=3200)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--ablations", action="store_true",
                        help="one more table per published rule switched back to simlab's")
    parser.add_argument("--only", nargs="+", default=None, metavar="NAME",
                        help="with --ablations: only these ablations (their names)")
    parser.add_argument("--no-simlab", action="store_true",
                        help="skip the table of simlab's own protocol")
    args = parser.parse_args()
    missing = [n for n in FILES.values() if not (args.lab / n).is_file()]
    if missing:
        print(f"online_published: the real lab's files are not in {args.lab} (missing "
              f"{', '.join(missing)}): give --lab DIR (the published data of "
              "meta-control-decision-making-agent)", file=sys.stderr)
        return 2
    from simlab.base.parallel import make_executor

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp, make_executor("local", workers=args.workers,
                                                             in_process_single=True) as ex:
        models = read_models(args.lab, Path(tmp))
        runs = {"--protocol published": {"protocol": "published"}}
        if not args.no_simlab:
            runs["--protocol simlab (simlab's own rules)"] = {"protocol": "simlab"}
        if args.ablations:
            runs.update({f"published, {name}": {"protocol": "published", **opts}
                         for name, opts in ABLATIONS.items()
                         if args.only is None or name in args.only})
        for title, opts in runs.items():
            t1 = time.perf_counter()
            tables = run_table(models, ex, args.seeds, args.decisions, **opts)
            print_table(f"{title}: {args.seeds} runs x {args.decisions} decisions "
                        f"({time.perf_counter() - t1:.0f} s)", tables, args.seeds)
            sys.stdout.flush()
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
