"""Wall time of ``simlab pipeline`` per stage against its physics floor (issue 17).

Runs :func:`simlab.commands.pipeline` on the defaults (``--quick``: a smaller budget) into
a temporary folder and, in the same run, measures the machine's bare PyBullet stepping
rate for the arena (``stepSimulation`` of the robot driving a circle, as
``benchmarks/physics_speed.py`` (a)), then prints per stage:

* its wall time (``pipeline.json``);
* the simulated seconds it stepped: the map's ``exploration.json`` ``sim_seconds``; the
  dataset's ``duration`` column; the replay's ``stepped_seconds`` of the learned run and
  of the random baseline (``replay.json``); 0 for the stages without physics;
* its physics floor = stepped seconds / bare rate (x real time) / usable cores (the
  stage can use at most ``min(cores, independent worlds)`` of them: the map has one
  world, the dataset ``workers``, the replay two);
* wall / floor.

The numba compile time of the run (``numba:compile`` events of this process; compiles
in worker processes are not seen) is printed separately, as is the load average before
and after (the machine may be shared: compare runs made one after the other).

    python benchmarks/pipeline_time.py [--quick] [--out DIR] [--bare-seconds 30]
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path
from typing import Any

QUICK = {"map_minutes": 5.0, "hours": 1.0, "episodes": 300, "runs": 2, "replay_hours": 0.5}


def bare_rate(arena: str, seconds: float, repeats: int = 2) -> float:
    """Best real-time factor of bare ``stepSimulation`` over ``repeats`` runs."""
    from simlab.physics.world import World

    best = 0.0
    for _ in range(repeats):
        with World(arena) as world:
            world.reset((0.0, -0.3, 0.0))
            world.drive.command(0.15, 0.5)  # a 0.3 m circle inside the table
            world.step(round(world.physics_hz))
            n = round(seconds * world.physics_hz)
            step = world.client.stepSimulation
            t = time.perf_counter()
            for _ in range(n):
                step()
            best = max(best, seconds / (time.perf_counter() - t))
    return best


def usable_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def stepped_seconds(out: Path) -> dict[str, tuple[float, int]]:
    """Per stage: (simulated seconds stepped, independent worlds it stepped in)."""
    import pyarrow.parquet as pq

    rec = json.loads((out / "pipeline.json").read_text())
    res: dict[str, tuple[float, int]] = {k: (0.0, 1) for k in rec["stages"]}
    expl = json.loads((out / "map" / "exploration.json").read_text())
    res["map"] = (float(expl["sim_seconds"]), 1)
    parts = [p for p in sorted((out / "dataset" / "data").rglob("*.parquet"))
             if not p.name.startswith(".")]
    dur = sum(float(pq.read_table(p, columns=["duration"]).column("duration")
                    .to_numpy().sum()) for p in parts)
    res["dataset"] = (dur, int(rec["settings"]["workers"]))
    rep = json.loads((out / "replay" / "replay.json").read_text())
    worlds = 1
    total = float(rep["result"]["stepped_seconds"])
    if rep.get("random_baseline"):
        total += float(rep["random_baseline"]["stepped_seconds"])
        worlds = 2
    res["replay"] = (total, worlds)
    return res


class CompileTimer:
    """Total seconds of ``numba:compile`` events in this process."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self.count = 0

    def __enter__(self) -> CompileTimer:
        from numba.core import event

        self._listener = event.TimingListener()
        event.register("numba:compile", self._listener)
        return self

    def __exit__(self, *exc: Any) -> None:
        from numba.core import event

        event.unregister("numba:compile", self._listener)
        if self._listener.done:
            self.seconds = self._listener.duration


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a small budget (minutes, not hours)")
    ap.add_argument("--out", default=None, help="keep the run here (new folder; default: temp)")
    ap.add_argument("--arena", default="table", help="arena of the pipeline and the bare rate")
    ap.add_argument("--bare-seconds", type=float, default=30.0,
                    help="simulated seconds of each bare-stepping measurement")
    ap.add_argument("--seed", type=int, default=0, help="root seed of the pipeline")
    args = ap.parse_args()

    from simlab.commands import pipeline

    load0 = os.getloadavg()
    cores = usable_cores()
    rate0 = bare_rate(args.arena, args.bare_seconds)
    settings = QUICK if args.quick else {}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(args.out) if args.out else Path(tmp) / "run"
        t0 = time.perf_counter()
        with CompileTimer() as ct:
            pipeline(args.arena, out, seed=args.seed, progress=False, log=None, **settings)
        total = time.perf_counter() - t0
        rate1 = bare_rate(args.arena, args.bare_seconds)
        rec = json.loads((out / "pipeline.json").read_text())
        stepped = stepped_seconds(out)
    load1 = os.getloadavg()
    rate = max(rate0, rate1)
    print(f"machine: {cores} usable cores, load average {load0[0]:.2f} before / "
          f"{load1[0]:.2f} after; bare stepSimulation ({args.arena}, circle): "
          f"{rate:.0f}x real time per core (before {rate0:.0f}x, after {rate1:.0f}x)")
    print(f"budget: {'--quick ' + json.dumps(QUICK) if args.quick else 'defaults'}")
    print(f"{'stage':<8} {'wall s':>8} {'stepped s':>10} {'worlds':>6} {'floor s':>8} "
          f"{'wall/floor':>10}")
    floor_total = 0.0
    for name, r in rec["stages"].items():
        sec, worlds = stepped.get(name, (0.0, 1))
        wall = float(r["wall_seconds"])
        floor = sec / rate / min(cores, worlds) if sec else 0.0
        floor_total += floor
        ratio = f"{wall / floor:10.2f}" if floor else f"{'-':>10}"
        print(f"{name:<8} {wall:8.1f} {sec:10.0f} {worlds:6d} {floor:8.1f} {ratio}")
    stages_wall = sum(float(r["wall_seconds"]) for r in rec["stages"].values())
    print(f"{'stages':<8} {stages_wall:8.1f} {'':>10} {'':>6} {floor_total:8.1f} "
          f"{stages_wall / floor_total:10.2f}")
    print(f"pipeline: done in {total:.1f} s (stages + report {total - stages_wall:.1f} s); "
          f"whole / physics floor = {total / floor_total:.2f}")
    print(f"numba compile in this process: {ct.seconds:.1f} s")


if __name__ == "__main__":
    main()
