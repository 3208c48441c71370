"""Wall time of ``simlab reproduce``, per experiment (target: ``--budget full`` <= 20 min
on the 2-core machine).

Runs :func:`simlab.experiments.reproduce.reproduce` once into a fresh folder and prints:

* the wall time of every experiment and the total, against the 20-minute target
  (the ratio printed is total / 1200 s);
* the CPU time of the driver process and of its children, and the machine's load
  average before and after (the machine is shared: a busy neighbour inflates the wall
  time; CPU time does not depend on it);
* for the physics experiments, the build time of each stage of the shared chain
  (map, states, walk, MDP, training) and the baseline of the same run without the
  shared cache: Figs. 4.9 and 4.10 would each rebuild the chain up to what they need,
  so the saving is the sum of those stage times (measured in this run).

Run: ``python benchmarks/reproduce_time.py [--budget full] [--only NAME,...]
[--backend local|ray] [--out DIR]`` (default ``--out``: a temporary folder, deleted at
the end). Run it 2-3 times on a quiet machine and report best and spread.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import tempfile
import time
from pathlib import Path

TARGET_SECONDS = 20 * 60
#: Stages of the physics chain each experiment needs (beyond map and states).
NEEDS = {"fig4_8_entropy": ("map", "states", "dataset", "mdp"),
         "fig4_9_empirical_training": ("map", "states", "dataset", "mdp", "train"),
         "fig4_10_replay": ("map", "states", "dataset", "mdp", "train")}


def _cpu() -> tuple[float, float]:
    me = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime, kids.ru_utime + kids.ru_stime


def _stage_times(out: Path) -> dict[str, float]:
    """Total build time (s) per physics stage kind, from the cache's ``_stage.json``."""
    times: dict[str, float] = {}
    for marker in sorted((out / "_cache" / "physics").glob("*/_stage.json")):
        kind = marker.parent.name.split("-")[0]
        times[kind] = times.get(kind, 0.0) + float(json.loads(marker.read_text())
                                                  .get("wall_seconds", 0.0))
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--budget", choices=("quick", "full"), default="full")
    parser.add_argument("--only", default=None)
    parser.add_argument("--backend", choices=("local", "ray"), default="local")
    parser.add_argument("--out", default=None, help="keep the outputs here (new folder)")
    args = parser.parse_args()

    from simlab.experiments.reproduce import reproduce

    tmp = None
    if args.out is None:
        tmp = tempfile.TemporaryDirectory(prefix="simlab-reproduce-")
        out = Path(tmp.name) / "out"
    else:
        out = Path(args.out)
    load0 = os.getloadavg()
    cpu0 = _cpu()
    t0 = time.perf_counter()
    res = reproduce(out, only=args.only, budget=args.budget, backend=args.backend,
                    progress=False, log=print)
    wall = time.perf_counter() - t0
    cpu1 = _cpu()
    load1 = os.getloadavg()

    print()
    print(f"simlab reproduce --budget {args.budget} --backend {args.backend}: "
          f"{len(res.entries)} experiments, {res.backend}, {os.cpu_count()} cores")
    print(f"load average before {load0[0]:.1f}, after {load1[0]:.1f} (1 min)")
    print(f"{'experiment':34s} {'wall s':>8s}  status  checks")
    for e in res.entries:
        counts: dict[str, int] = {}
        for c in e["checks"]:
            counts[c["status"]] = counts.get(c["status"], 0) + 1
        summary = ", ".join(f"{v} {k}" for k, v in sorted(counts.items())) or "-"
        print(f"{e['name']:34s} {e['wall_seconds']:8.1f}  {e['status']:6s}  {summary}")
    print(f"{'total':34s} {wall:8.1f}  = {wall / TARGET_SECONDS:.2f} x the 20-min target")
    print(f"CPU time: driver {cpu1[0] - cpu0[0]:.0f} s, child processes "
          f"{cpu1[1] - cpu0[1]:.0f} s (Ray workers are not counted)")

    stages = _stage_times(out)
    if stages:
        print("physics chain stage build times (s): "
              + ", ".join(f"{k} {v:.1f}" for k, v in stages.items()))
        ran = [e["name"] for e in res.entries if e["name"] in NEEDS]
        without = sum(sum(stages.get(s, 0.0) for s in NEEDS[n]) for n in ran)
        shared = sum(stages.values())
        if len(ran) > 1:
            print(f"chain work of {', '.join(ran)}: {shared:.0f} s shared vs {without:.0f} s "
                  f"if each built its own chain (ratio {without / max(shared, 1e-9):.2f})")
    if tmp is not None:
        tmp.cleanup()


if __name__ == "__main__":
    main()
