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
  world, the dataset ``workers``, the replay two). The bare rate is the one measured right
  before and right after the stage (their mean), not once for the run: on a shared VM the
  machine's own speed drifts by 1.5x from minute to minute, and a stage must be compared
  with the machine it ran on;
* wall / floor;
* its CPU seconds (this process and its worker processes) and CPU / physics, where
  physics = stepped seconds / the bare rate per CPU second: the share of the stage's
  work that is not stepping, which a loaded machine does not inflate (wall time it does).

The numba compile time of the run (``numba:compile`` events of this process; compiles
in worker processes are not seen) is printed separately, as is the load average before
and after (the machine may be shared: compare runs made one after the other).

Then the lower bounds no schedule of this run's work can beat on this machine: all its CPU
seconds / cores, and every physics stage exactly at its floor plus the stages without
physics as measured (and the same at 1.3x every floor). ``--before SECONDS`` (the old
code's wall time, measured one after the other) prints this run / before and the bounds in
the same unit, so a target such as "0.5 x before" can be checked against what the work
itself allows.

``--profile FILE`` runs the pipeline under :mod:`cProfile` (this process only: the map, the
in-process replay runs and the stages' writing; the dataset's workers are not seen), writes
the statistics to ``FILE`` (read them with :mod:`pstats`) and prints the functions with the
most own time. The profiler slows Python-heavy code more than the physics: use it to find
where the non-physics time goes, not for the ratios.

    python benchmarks/pipeline_time.py [--quick] [--out DIR] [--bare-seconds 30]
                                       [--before SECONDS] [--profile FILE]
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


def bare_rate(arena: str, seconds: float, repeats: int = 3) -> tuple[float, float]:
    """Best real-time factor of bare ``stepSimulation`` over ``repeats`` runs, per wall
    second and per CPU second of this process."""
    from simlab.physics.world import World

    best = best_cpu = 0.0
    with World(arena) as world:
        for _ in range(repeats):
            world.reset((0.0, -0.3, 0.0))
            world.drive.command(0.15, 0.5)  # a 0.3 m circle inside the table
            world.step(round(world.physics_hz))
            n = round(seconds * world.physics_hz)
            step = world.client.stepSimulation
            t, c = time.perf_counter(), time.process_time()
            for _ in range(n):
                step()
            best = max(best, seconds / (time.perf_counter() - t))
            best_cpu = max(best_cpu, seconds / max(time.process_time() - c, 1e-9))
    return best, best_cpu


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
    res["replay_schedule"] = rep.get("schedule")  # type: ignore[assignment]
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


def _live_children_cpu() -> float:
    """CPU seconds of this process's children that are still running (Linux ``/proc``):
    the pipeline's lent warm-up worker is reaped only at the end, so ``RUSAGE_CHILDREN``
    does not see the baseline and training work it does."""
    me, total = str(os.getpid()), 0.0
    tick = os.sysconf("SC_CLK_TCK")
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if fields[1] == me:  # field 4 (ppid); then utime, stime are fields 14, 15
            total += (int(fields[11]) + int(fields[12])) / tick
    return total


def _cpu() -> float:
    """CPU seconds of this process, its reaped children and its running children."""
    import resource

    me = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime + _live_children_cpu()


def _instrument(cpu: dict[str, float], probe: Any, rates: dict[str, tuple[float, float]]
                ) -> None:
    """Record each stage's CPU seconds (this process and its reaped children: the
    dataset's and the replay's worker processes) and the bare rate ``probe()`` measured
    right before and right after it is built (outside its wall time)."""
    try:
        from simlab.orchestration.stages import PhysicsChain
    except ModuleNotFoundError:  # the code before the orchestration package (A/B runs)
        from simlab.stages import PhysicsChain  # type: ignore[no-redef]

    original = PhysicsChain.cached_stage

    def cached_stage(self: Any, stage: str, key: Any, build: Any) -> Any:
        def timed(d: Path) -> Any:
            c = _cpu()
            try:
                return build(d)
            finally:
                cpu[stage] = cpu.get(stage, 0.0) + _cpu() - c

        first = stage not in rates
        before = probe() if first else None
        result = original(self, stage, key, timed)
        if first:
            rates[stage] = (before, probe()) if result.built else (0.0, 0.0)
        return result

    PhysicsChain.cached_stage = cached_stage  # type: ignore[method-assign]


def print_bounds(total: float, cpu_run: float, cores: int, floors: float, others: float,
                 before: float | None) -> None:
    """What no schedule of this run's work can beat on this machine, and the issue's
    targets against it (``before``: the old code's wall time, measured one after the other).

    * CPU bound: all the run's CPU seconds (every process; probes excluded) / cores;
    * floor bound: every physics stage exactly at its physics floor, plus the wall time of
      the stages without physics and of the report, as measured (``others``);
    * the same with every physics stage at the allowed 1.3x its floor.
    """
    print(f"lower bounds: all CPU {cpu_run:.1f} s / {cores} cores = {cpu_run / cores:.1f} s; "
          f"physics floors {floors:.1f} s + stages without physics and report {others:.1f} s "
          f"= {floors + others:.1f} s; at 1.3x every floor {1.3 * floors + others:.1f} s; "
          f"this run {total:.1f} s")
    if before:
        print(f"before {before:.1f} s: this run / before = {total / before:.2f}; a target of "
              f"0.5 x before = {0.5 * before:.1f} s against the bounds above: CPU "
              f"{cpu_run / cores / before:.2f}, floors {(floors + others) / before:.2f}, "
              f"1.3x floors {(1.3 * floors + others) / before:.2f} (x before)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a small budget (minutes, not hours)")
    ap.add_argument("--out", default=None, help="keep the run here (new folder; default: temp)")
    ap.add_argument("--arena", default="table", help="arena of the pipeline and the bare rate")
    ap.add_argument("--bare-seconds", type=float, default=30.0,
                    help="simulated seconds of each bare-stepping measurement (3 per probe)")
    ap.add_argument("--seed", type=int, default=0, help="root seed of the pipeline")
    ap.add_argument("--before", type=float, default=None, metavar="SECONDS",
                    help="wall time of the code before the change under test, measured one "
                         "after the other on this machine: prints this run / before and what "
                         "the bounds below allow")
    ap.add_argument("--profile", default=None, metavar="FILE",
                    help="run the pipeline under cProfile and write its statistics here "
                         "(default: no profile)")
    args = ap.parse_args()

    from simlab.commands import pipeline

    load0 = os.getloadavg()
    cores = usable_cores()
    settings = QUICK if args.quick else {}
    cpu: dict[str, float] = {}
    rates: dict[str, Any] = {}
    probing = [0.0, 0.0]  # wall, CPU seconds of the probes

    def probe() -> tuple[float, float]:
        t, c = time.perf_counter(), time.process_time()
        try:
            return bare_rate(args.arena, args.bare_seconds)
        finally:
            probing[0] += time.perf_counter() - t
            probing[1] += time.process_time() - c

    run_rates = [probe()]
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(args.out) if args.out else Path(tmp) / "run"
        t0 = time.perf_counter()
        _instrument(cpu, probe, rates)
        lines: list[str] = []

        def log(msg: str) -> None:
            lines.append(f"{time.perf_counter() - t0:8.1f} s  {msg}")

        probing[0] = probing[1] = 0.0
        cpu0 = _cpu()
        with CompileTimer() as ct:
            if args.profile:
                import cProfile

                with cProfile.Profile() as prof:
                    pipeline(args.arena, out, seed=args.seed, progress=False, log=log,
                             **settings)
                prof.dump_stats(args.profile)
            else:
                pipeline(args.arena, out, seed=args.seed, progress=False, log=log, **settings)
        total = time.perf_counter() - t0 - probing[0]
        cpu_run = _cpu() - cpu0 - probing[1]
        run_rates.append(probe())
        rec = json.loads((out / "pipeline.json").read_text())
        stepped = stepped_seconds(out)
    load1 = os.getloadavg()
    print("pipeline log (time since start, bare-rate probes included):")
    print("\n".join(lines))
    every = run_rates + [r for pair in rates.values() for r in pair if r]
    lo, hi = min(r[0] for r in every), max(r[0] for r in every)
    print(f"machine: {cores} usable cores, load average {load0[0]:.2f} before / "
          f"{load1[0]:.2f} after; bare stepSimulation ({args.arena}, circle, best of 3 x "
          f"{args.bare_seconds:g} s per probe): {lo:.0f}x to {hi:.0f}x real time over the "
          f"{len(every)} probes of this run")
    print(f"budget: {'--quick ' + json.dumps(QUICK) if args.quick else 'defaults'}")
    print(f"{'stage':<8} {'wall s':>8} {'stepped s':>10} {'worlds':>6} {'bare x':>7} "
          f"{'floor s':>8} {'wall/floor':>10} {'CPU s':>8} {'CPU/physics':>11}")
    floor_total = cpu_total = other_wall = 0.0
    for name, r in rec["stages"].items():
        sec, worlds = stepped.get(name, (0.0, 1))
        wall = float(r["wall_seconds"])
        pair = rates.get(name) or (run_rates[0], run_rates[-1])
        rate = (pair[0][0] + pair[1][0]) / 2 if pair[0] else run_rates[0][0]
        cpu_rate = (pair[0][1] + pair[1][1]) / 2 if pair[0] else run_rates[0][1]
        floor = sec / rate / min(cores, worlds) if sec else 0.0
        floor_total += floor
        other_wall += 0.0 if sec else wall
        ratio = f"{wall / floor:10.2f}" if floor else f"{'-':>10}"
        c = cpu.get(name, float("nan"))
        cpu_total += c
        cratio = f"{c / (sec / cpu_rate):11.2f}" if sec else f"{'-':>11}"
        shown = f"{rate:7.0f}" if sec else f"{'-':>7}"
        print(f"{name:<8} {wall:8.1f} {sec:10.0f} {worlds:6d} {shown} {floor:8.1f} {ratio} "
              f"{c:8.1f} {cratio}")
    stages_wall = sum(float(r["wall_seconds"]) for r in rec["stages"].values())
    print(f"{'stages':<8} {stages_wall:8.1f} {'':>10} {'':>6} {'':>7} {floor_total:8.1f} "
          f"{stages_wall / floor_total:10.2f} {cpu_total:8.1f}")
    print(f"pipeline: done in {total:.1f} s without the {probing[0]:.1f} s of probes "
          f"(stages + report {total - stages_wall:.1f} s); whole / physics floor = "
          f"{total / floor_total:.2f}")
    print_bounds(total, cpu_run, cores, floor_total, other_wall + total - stages_wall,
                 args.before)
    try:
        from simlab.replay.scheduling import shares_per_session

        rule = "session (autogroup: idle cores decide)" if shares_per_session() else "process"
    except ModuleNotFoundError:  # the code before the replay package (A/B runs)
        rule = "?"
    print(f"replay schedule (extra processes): {stepped.get('replay_schedule')}; CPUs shared "
          f"per {rule}")
    warm = rec.get("warmup", {})
    print(f"numba compile in this process: {ct.seconds:.1f} s; the warm-up worker (compile + "
          f"imports, beside the map and the walk) took {warm.get('worker_seconds')} s and the "
          f"training waited {warm.get('wait_seconds', 0.0):.1f} s for it (outside its wall time)")
    if args.profile:
        import pstats

        print(f"profile (this process) written to {args.profile}; most own time:")
        pstats.Stats(args.profile).sort_stats("tottime").print_stats(15)


if __name__ == "__main__":
    main()
