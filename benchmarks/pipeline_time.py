"""Wall time of ``simlab pipeline`` per stage against its physics floor.

Runs :func:`simlab.commands.pipeline` on the defaults (``--quick``: a smaller budget) into
a temporary folder and, in the same run, measures the machine's bare PyBullet stepping
rate for the arena (``stepSimulation`` of the robot driving a circle, as
``benchmarks/physics_speed.py`` (a)), then prints per stage:

* its wall time (``pipeline.json``);
* the simulated seconds it stepped: the map's ``exploration.json`` ``sim_seconds``; the
  dataset's ``duration`` column; the replay's ``stepped_seconds`` of the learned run and
  of the random baseline (``replay.json``); 0 for the stages without physics;
* the LIDAR beams it cast, by ray length (every ``Lidar.scan`` of this process and of its
  worker processes is tallied: a ``sitecustomize`` on the workers' ``PYTHONPATH`` wraps it
  in each ``spawn`` child and writes the counts to a folder);
* its physics floor, twice: stepping only = stepped seconds / bare stepping rate (x real
  time) / usable cores, and with sensors = (stepped seconds / bare stepping rate + beams
  cast x bare seconds per beam) / usable cores. A stage can use at most
  ``min(cores, independent worlds)`` cores: the map has one world, the dataset
  ``workers``, the replay two. The bare ray cost per beam is that of one ``rayTestBatch``
  of a full scan from the arena's start pose, measured at several ray lengths and
  interpolated at the stage's (a ray costs by the distance it travels before its hit:
  0.8 us for a 0.4 m ray, 2 us for a full 3.5 m one in the table arena). Both bare rates
  are the ones measured right before and right after the stage (their mean), not once for
  the run: on a shared VM the machine's own speed drifts by 1.5x from minute to minute,
  and a stage must be compared with the machine it ran on;
* wall / floor for both floors;
* its CPU seconds (this process and its worker processes) and CPU / physics, where
  physics = stepped seconds / the bare rate per CPU second: the share of the stage's
  work that is not stepping, which a loaded machine does not inflate (wall time it does).

The numba compile time of the run (``numba:compile`` events of this process; compiles
in worker processes are not seen) is printed separately, as is the load average before
and after (the machine may be shared: compare runs made one after the other).

Then the lower bounds no schedule of this run's work can beat on this machine: all its CPU
seconds / cores, and every physics stage exactly at its floor (stepping only, and with
sensors) plus the stages without physics as measured; the last is *the lower bound*, and the
run's wall time is printed against it (the target: at most 1.25x). The replay's floor by its
runs follows: its two runs are independent but each is one chain of decisions, so the
replay can be no shorter than its longer run at the bare rates: the learned run's stepping,
its rays (this process's beams) and, when the filter ran in this process, its updates at
the filter's own bare cost (one tracker cycle on a scan of the arena, :func:`bare_filter_update`);
the lower bound with that floor in place of the even split is printed too. Last, the floor
of the work that stays whatever the control loop costs: every stage's stepping at the rate
Bullet steps the primitives' own motions (their turns in place, drives and stops step more
slowly than the probe's circle: :func:`own_motion_factor`), the replay by its runs, the
stages without physics as measured. The floors follow the
physics rate of the run (``--physics-hz``, default: simlab's default rate): the bare
stepping rate is measured at that rate. ``--before SECONDS`` (the old code's wall time,
measured one after the other) prints this run / before and the bounds in the same unit.

``--profile FILE`` runs the pipeline under :mod:`cProfile` (this process only: the map, the
in-process replay runs and the stages' writing; the dataset's workers are not seen), writes
the statistics to ``FILE`` (read them with :mod:`pstats`) and prints the functions with the
most own time. The profiler slows Python-heavy code more than the physics: use it to find
where the non-physics time goes, not for the ratios.

    python benchmarks/pipeline_time.py [--quick] [--out DIR] [--bare-seconds 30]
                                       [--before SECONDS] [--profile FILE] [--physics-hz HZ]
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


def bare_rate(arena: str, seconds: float, repeats: int = 3, hz: float | None = None
              ) -> tuple[float, float]:
    """Best real-time factor of bare ``stepSimulation`` at ``hz`` (None: the default rate)
    over ``repeats`` runs, per wall second and per CPU second of this process."""
    from simlab.physics.world import World

    best = best_cpu = 0.0
    with World(arena, physics_hz=hz) as world:
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


#: Ray lengths (m) at which the bare ray cost is measured (the LDS-01 reach last).
RAY_REACHES = (0.25, 0.5, 1.0, 2.0, 3.5)


def bare_rays(arena: str, scans: int = 100, repeats: int = 3) -> dict[float, float]:
    """Best wall seconds per beam of a bare full-scan ``rayTestBatch`` from the arena's
    start pose, per ray length of :data:`RAY_REACHES` (the beams' start and end points are
    computed once, as the LIDAR does per scan)."""
    import numpy as np

    from simlab.physics.world import World

    out: dict[float, float] = {}
    with World(arena) as world:
        lidar = world.lidar
        spec = lidar.spec
        a = spec.angles
        dirs = np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1)
        origin = np.array([*world.pose()[:2], lidar.offset[2]])
        batch = world.client.rayTestBatch
        for reach in RAY_REACHES:
            starts = origin + spec.range_min * dirs
            ends = origin + min(reach, spec.range_max) * dirs
            best = float("inf")
            for _ in range(repeats):
                t = time.perf_counter()
                for _ in range(scans):
                    batch(starts, ends)
                best = min(best, (time.perf_counter() - t) / (scans * len(a)))
            out[reach] = best
    return out


def ray_seconds(costs: dict[float, float], beams: dict[str, int]) -> float:
    """Bare wall seconds of the tallied ``beams`` (ray length -> count), the cost per beam
    interpolated linearly in ray length between the measured ones."""
    import numpy as np

    xs = sorted(costs)
    return sum(n * float(np.interp(float(reach), xs, [costs[x] for x in xs]))
               for reach, n in beams.items())


#: Installed in this process and, through ``sitecustomize``, in every worker it spawns:
#: wraps ``Lidar.scan`` to count the beams cast by ray length and writes the counts of the
#: process to ``<tally folder>/<pid>.json`` every 16 scans and at exit (at most 15 scans
#: of a process that is still running are not yet seen).
TALLY_CODE = """
def _simlab_ray_tally(folder):
    import atexit, json, os
    from simlab.physics.lidar import Lidar

    counts, calls = {}, [0]
    path = os.path.join(folder, f"{os.getpid()}.json")
    original = Lidar.scan

    def flush():
        tmp = path + ".tmp"
        try:
            with open(tmp, "w") as f:
                json.dump(counts, f)
            os.replace(tmp, path)
        except OSError:  # the benchmark is over and its folder gone
            pass

    def scan(self, link_pos, link_rot, pose, rng, stamp=0.0, beams=None, reach=None):
        spec = self.spec
        far = spec.range_max if reach is None else min(float(reach), spec.range_max)
        key = f"{far:.3f}"
        counts[key] = counts.get(key, 0) + (spec.n_beams if beams is None else len(beams))
        calls[0] += 1
        if calls[0] % 16 == 0:
            flush()
        return original(self, link_pos, link_rot, pose, rng, stamp, beams, reach)

    Lidar.scan = scan
    atexit.register(flush)
    return flush


import os as _os
if _os.environ.get("SIMLAB_BENCH_RAY_TALLY"):
    _simlab_flush = _simlab_ray_tally(_os.environ["SIMLAB_BENCH_RAY_TALLY"])
"""


def start_ray_tally(work: Path) -> tuple[Path, Any]:
    """Tally the beams of this process and of the processes it starts from now on (see
    :data:`TALLY_CODE`); returns the folder of the counts and this process's flush."""
    folder = work / "rays"
    folder.mkdir()
    site = work / "site"
    site.mkdir()
    (site / "sitecustomize.py").write_text(TALLY_CODE)
    os.environ["SIMLAB_BENCH_RAY_TALLY"] = str(folder)
    os.environ["PYTHONPATH"] = os.pathsep.join(
        p for p in (str(site), os.environ.get("PYTHONPATH")) if p)
    namespace: dict[str, Any] = {"__name__": "tally"}
    exec(compile(TALLY_CODE, "sitecustomize", "exec"), namespace)
    return folder, namespace["_simlab_flush"]


def tallied_beams(folder: Path, pid: int | None = None) -> dict[str, int]:
    """Beams counted so far by every process, or by process ``pid`` only (ray length in
    m, as text -> count)."""
    total: dict[str, int] = {}
    for f in folder.glob("*.json" if pid is None else f"{pid}.json"):
        try:
            counts = json.loads(f.read_text())
        except (OSError, ValueError):  # being replaced right now: its next flush counts
            continue
        for k, n in counts.items():
            total[k] = total.get(k, 0) + int(n)
    return total


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


def replay_runs(out: Path) -> dict[str, float]:
    """The replay's parts: the learned run's and the baseline's stepped seconds, the
    filter's updates (0 without the mcl pose source)."""
    rep = json.loads((out / "replay" / "replay.json").read_text())
    updates = ((rep.get("localization") or {}).get("mcl") or {}).get("updates") or {}
    return {"learned": float(rep["result"]["stepped_seconds"]),
            "baseline": float((rep.get("random_baseline") or {}).get("stepped_seconds", 0.0)),
            "updates": float(updates.get("n", 0))}


def bare_filter_update(arena: str, repeats: int = 3, n: int = 300) -> float:
    """Best wall seconds of one particle-filter cycle alone (the odometry motion of 2 cm,
    the update on a scan of the filter's beams, resampling and injection as they fall;
    the replay's default :class:`MCLParams`) on the arena's 1 cm map, from its start pose:
    the filter's own work, which the stepping and ray floors leave out."""
    import numpy as np

    from simlab.localization.likelihood import LikelihoodField
    from simlab.localization.maps import arena_map
    from simlab.localization.tracker import MCLTracker
    from simlab.physics.world import World

    with World(arena) as world:
        start = np.asarray(world.arena.start, dtype=np.float64)
        world.reset(tuple(start))
        field = LikelihoodField(arena_map(world.arena, 0.01))
        rng = np.random.default_rng(0)
        best = float("inf")
        for _ in range(repeats):
            tracker = MCLTracker(field, np.random.default_rng(1), initial_pose=world.pose(),
                                 odometry=np.zeros(3))
            beams = tracker.filter.beam_subset(world.lidar_spec.n_beams)
            scan = world.scan(rng, beams=beams)
            odoms = [np.array([0.02 * (k % 2), 0.0, 0.0]) for k in range(n)]
            t = time.perf_counter()
            for odom in odoms:  # back and forth by 2 cm: every scan updates
                tracker.on_scan(scan, odom)
            best = min(best, (time.perf_counter() - t) / n)
    return best


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


def _instrument(cpu: dict[str, float], probe: Any, rates: dict[str, Any],
                beams: dict[str, dict[str, int]], tally: Any) -> None:
    """Record each stage's CPU seconds (this process and its reaped children: the
    dataset's and the replay's worker processes), the beams it cast (``tally(None)``: the
    counts of every process so far; under ``"<stage>:here"`` those of this process,
    ``tally(os.getpid())``) and the bare rates ``probe()`` measured right before and right
    after it is built (outside its wall time)."""
    try:
        from simlab.orchestration.stages import PhysicsChain
    except ModuleNotFoundError:  # the code before the orchestration package (A/B runs)
        from simlab.stages import PhysicsChain  # type: ignore[no-redef]

    original = PhysicsChain.cached_stage

    def cached_stage(self: Any, stage: str, key: Any, build: Any) -> Any:
        def timed(d: Path) -> Any:
            c, b, bh = _cpu(), tally(None), tally(os.getpid())
            try:
                return build(d)
            finally:
                cpu[stage] = cpu.get(stage, 0.0) + _cpu() - c
                for name, before, after in ((stage, b, tally(None)),
                                            (f"{stage}:here", bh, tally(os.getpid()))):
                    mine = beams.setdefault(name, {})
                    for k, n in after.items():
                        mine[k] = mine.get(k, 0) + n - before.get(k, 0)

        first = stage not in rates
        before = probe() if first else None
        result = original(self, stage, key, timed)
        if first:
            rates[stage] = (before, probe()) if result.built else None
        return result

    PhysicsChain.cached_stage = cached_stage  # type: ignore[method-assign]


def stage_rates(rates: dict[str, Any], run_rates: list[Any], name: str
                ) -> tuple[float, float, dict[float, float]]:
    """A stage's bare rates, the mean of the probes right before and after it (of the run's
    first and last probes for a stage that was not built): stepping x real time per wall
    second and per CPU second, seconds per beam by ray length."""
    pair = rates.get(name) or (run_rates[0], run_rates[-1])
    return ((pair[0][0] + pair[1][0]) / 2, (pair[0][1] + pair[1][1]) / 2,
            {k: (pair[0][2][k] + pair[1][2][k]) / 2 for k in pair[0][2]})


def replay_path(parts: dict[str, float], schedule: dict[str, bool], rates: dict[str, Any],
                run_rates: list[Any], beams: dict[str, dict[str, int]], filter_cost: float,
                cores: int, stepping: float = 1.0) -> dict[str, float] | None:
    """The replay's floor by its parts: its two runs are independent but each is one
    sequence of decisions, so the replay can be no shorter than its longer run at the bare
    rates, whatever the cores. The learned run's part: its stepping, the rays this process
    cast (with the baseline in a process of its own, they are the learned run's) and, with
    the filter in this process, its updates at the filter's own bare cost
    (:func:`bare_filter_update`); the baseline's: its stepping and the other rays.
    ``stepping`` scales the stepping's cost (see :func:`own_motion_factor`). None when one
    process ran both (the floor with sensors is then the sum)."""
    rate, _, ray_cost = stage_rates(rates, run_rates, "replay")
    here = ray_seconds(ray_cost, beams.get("replay:here", {}))
    rays = ray_seconds(ray_cost, beams.get("replay", {}))
    if not (schedule.get("baseline_process") and parts["baseline"] > 0):
        return None
    filt = 0.0 if schedule.get("mcl_process") else parts["updates"] * filter_cost
    learned = parts["learned"] / rate * stepping + here + filt
    base = parts["baseline"] / rate * stepping + (rays - here)
    even = ((parts["learned"] + parts["baseline"]) / rate * stepping + rays + filt) / min(cores, 2)
    return {"rate": rate, "here": here, "rays": rays, "learned": learned, "baseline": base,
            "path": max(learned, base, even)}


def print_replay_path(parts: dict[str, float], schedule: dict[str, bool], rec: dict[str, Any],
                      path: dict[str, float], filter_cost: float) -> None:
    """Prints :func:`replay_path` against the replay's wall time."""
    wall = float(rec["stages"]["replay"]["wall_seconds"])
    rate, here, rays = path["rate"], path["here"], path["rays"]
    print(f"replay by its runs: learned {parts['learned']:.0f} stepped s / {rate:.0f}x + its "
          f"rays {here:.1f} s + filter {parts['updates']:.0f} updates x "
          f"{filter_cost * 1e6:.0f} us{' (in its own process)' if schedule.get('mcl_process') else ''}"
          f" = {path['learned']:.1f} s; baseline {parts['baseline']:.0f} stepped s + rays "
          f"{rays - here:.1f} s = {path['baseline']:.1f} s; the replay's floor with the filter = "
          f"max(runs, all / cores) = {path['path']:.1f} s; wall {wall:.1f} s = "
          f"{wall / path['path']:.2f}x it")


def own_motion_factor(arena: str, hz: float | None, repeats: int = 3) -> tuple[float, float, float]:
    """(circle x real time, the primitives' own motions x real time, their ratio), each the
    best of ``repeats``, measured one after the other: the bare floors step at the rate of
    a robot driving a circle, but the robot turns in place, drives and stops, which Bullet
    steps more slowly (``benchmarks/physics_speed.py`` (a) and (a')); the ratio scales the
    stepping floors to the motions the stages step."""
    from physics_speed import same_motions  # benchmarks/ is on sys.path as the script's dir

    circle = bare_rate(arena, 10.0, repeats, hz=hz)[0]
    own = max(same_motions(150, seed, arena, hz)[1] for seed in range(repeats))
    return circle, own, circle / own


def print_bounds(total: float, cpu_run: float, cores: int, floors: tuple[float, float],
                 others: float, before: float | None) -> None:
    """What no schedule of this run's work can beat on this machine, and the
    targets against it (``before``: the old code's wall time, measured one after the other).

    * CPU bound: all the run's CPU seconds (every process; probes excluded) / cores;
    * floor bounds: every physics stage exactly at its floor (stepping only; with sensors),
      plus the wall time of the stages without physics and of the report, as measured
      (``others``): the lower bound, with sensors;
    * this run against the lower bound (the target: at most 1.25x).
    """
    step, sensed = floors
    bound = sensed + others
    print(f"lower bounds: all CPU {cpu_run:.1f} s / {cores} cores = {cpu_run / cores:.1f} s; "
          f"floors stepping only {step:.1f} s / with sensors {sensed:.1f} s + stages without "
          f"physics and report {others:.1f} s = {step + others:.1f} s / {bound:.1f} s "
          f"(the lower bound); at 1.25x the lower bound {1.25 * bound:.1f} s; this run "
          f"{total:.1f} s = {total / bound:.2f}x the lower bound")
    if before:
        print(f"before {before:.1f} s: this run / before = {total / before:.2f}; the lower "
              f"bound / before {bound / before:.2f}, all CPU / cores / before "
              f"{cpu_run / cores / before:.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a small budget (minutes, not hours)")
    ap.add_argument("--out", default=None, help="keep the run here (new folder; default: temp)")
    ap.add_argument("--arena", default="table", help="arena of the pipeline and the bare rate")
    ap.add_argument("--bare-seconds", type=float, default=30.0,
                    help="simulated seconds of each bare-stepping measurement (3 per probe)")
    ap.add_argument("--seed", type=int, default=0, help="root seed of the pipeline")
    ap.add_argument("--physics-hz", type=float, default=None,
                    help="physics rate of the pipeline and of the bare rate (default: simlab's)")
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
    settings = dict(QUICK) if args.quick else {}
    if args.physics_hz is not None:
        settings["physics_hz"] = args.physics_hz
    cpu: dict[str, float] = {}
    rates: dict[str, Any] = {}
    probing = [0.0, 0.0]  # wall, CPU seconds of the probes

    def probe() -> tuple[float, float, dict[float, float]]:
        """(bare stepping x real time per wall second, per CPU second; seconds per beam by
        ray length)."""
        t, c = time.perf_counter(), time.process_time()
        try:
            return (*bare_rate(args.arena, args.bare_seconds, hz=args.physics_hz),
                    bare_rays(args.arena))
        finally:
            probing[0] += time.perf_counter() - t
            probing[1] += time.process_time() - c

    run_rates = [probe()]
    beams: dict[str, dict[str, int]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        folder, flush = start_ray_tally(Path(tmp))

        def tally(pid: int | None) -> dict[str, int]:
            flush()
            return tallied_beams(folder, pid)

        out = Path(args.out) if args.out else Path(tmp) / "run"
        t0 = time.perf_counter()
        _instrument(cpu, probe, rates, beams, tally)
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
        parts = replay_runs(out) if rec["stages"].get("replay", {}).get("built") else None
    filter_cost = bare_filter_update(args.arena) if parts and parts["updates"] else 0.0
    load1 = os.getloadavg()
    print("pipeline log (time since start, bare-rate probes included):")
    print("\n".join(lines))
    every = run_rates + [r for pair in rates.values() if pair for r in pair]
    lo, hi = min(r[0] for r in every), max(r[0] for r in every)
    full = max(RAY_REACHES)
    ray_lo = min(r[2][full] for r in every) * 1e6
    ray_hi = max(r[2][full] for r in every) * 1e6
    print(f"machine: {cores} usable cores, load average {load0[0]:.2f} before / "
          f"{load1[0]:.2f} after; bare stepSimulation ({args.arena}, circle, best of 3 x "
          f"{args.bare_seconds:g} s per probe): {lo:.0f}x to {hi:.0f}x real time; bare "
          f"rayTestBatch of a full scan ({full:g} m rays, best of 3 x 100 scans): "
          f"{ray_lo:.2f} to {ray_hi:.2f} us per beam; over the {len(every)} probes of this run")
    from simlab.physics.rate import DEFAULT_HZ

    print(f"budget: {'--quick ' + json.dumps(QUICK) if args.quick else 'defaults'}; physics "
          f"{args.physics_hz or DEFAULT_HZ:g} Hz")
    print(f"{'stage':<8} {'wall s':>7} {'stepped s':>9} {'beams M':>7} {'worlds':>6} "
          f"{'bare x':>6} {'floor s':>7} {'+rays s':>7} {'wall/floor':>10} "
          f"{'wall/floor+rays':>15} {'CPU s':>7} {'CPU/physics+rays':>16}")
    floor_total = sensed_total = cpu_total = other_wall = 0.0
    sensed_by: dict[str, float] = {}
    floor_by: dict[str, float] = {}
    ratios: list[str] = []
    for name, r in rec["stages"].items():
        sec, worlds = stepped.get(name, (0.0, 1))
        wall = float(r["wall_seconds"])
        rate, cpu_rate, ray_cost = stage_rates(rates, run_rates, name)
        cast = beams.get(name, {})
        n_beams = sum(cast.values())
        rays = ray_seconds(ray_cost, cast)
        usable = min(cores, worlds)
        floor = sec / rate / usable if sec else 0.0
        sensed = (sec / rate + rays) / usable if sec or rays else 0.0
        floor_total += floor
        sensed_total += sensed
        sensed_by[name] = sensed
        floor_by[name] = floor
        other_wall += 0.0 if sensed else wall
        ratio = f"{wall / floor:10.2f}" if floor else f"{'-':>10}"
        sratio = f"{wall / sensed:15.2f}" if sensed else f"{'-':>15}"
        if sensed:
            ratios.append(f"{name} {wall / sensed:.2f}")
        c = cpu.get(name, float("nan"))
        cpu_total += c
        # CPU over the stage's work at the bare rates (rays: wall seconds per beam of a
        # lone process, i.e. CPU seconds)
        work = sec / cpu_rate + rays
        cratio = f"{c / work:16.2f}" if sensed else f"{'-':>16}"
        shown = f"{rate:6.0f}" if sec else f"{'-':>6}"
        print(f"{name:<8} {wall:7.1f} {sec:9.0f} {n_beams / 1e6:7.2f} {worlds:6d} {shown} "
              f"{floor:7.1f} {sensed:7.1f} {ratio} {sratio} {c:7.1f} {cratio}")
    stages_wall = sum(float(r["wall_seconds"]) for r in rec["stages"].values())
    print(f"{'stages':<8} {stages_wall:7.1f} {'':>9} {'':>7} {'':>6} {'':>6} "
          f"{floor_total:7.1f} {sensed_total:7.1f} {stages_wall / floor_total:10.2f} "
          f"{stages_wall / sensed_total:15.2f} {cpu_total:7.1f}")
    others = other_wall + total - stages_wall
    print(f"ratios: whole / floors with sensors + non-physics = "
          f"{total / (sensed_total + others):.2f}; stage wall / floor with sensors: "
          f"{', '.join(ratios)}; whole / stepping floor = {total / floor_total:.2f}")
    print(f"pipeline: done in {total:.1f} s without the {probing[0]:.1f} s of probes "
          f"(stages + report {total - stages_wall:.1f} s)")
    print_bounds(total, cpu_run, cores, (floor_total, sensed_total), others, args.before)
    print(f"replay schedule (extra processes): {stepped.get('replay_schedule')}")
    schedule: Any = stepped.get("replay_schedule") or {}
    path = parts and replay_path(parts, schedule, rates, run_rates, beams, filter_cost, cores)
    if path:
        print_replay_path(parts, schedule, rec, path, filter_cost)
        bound = sensed_total - sensed_by["replay"] + path["path"] + others
        print(f"lower bound with the replay at its floor by its runs: {bound:.1f} s; this run "
              f"{total:.1f} s = {total / bound:.2f}x it")
    circle, own, factor = own_motion_factor(args.arena, args.physics_hz)
    # Every floor again with its stepping at the primitives' own rate, the replay by its runs
    # (or its even split): the work that stays whatever the control loop costs.
    stays = others + sum(sensed_by[n] + floor_by[n] * (factor - 1.0)
                         for n in sensed_by if n != "replay" or not path)
    scaled = path and replay_path(parts, schedule, rates, run_rates, beams, filter_cost, cores,
                                  factor)
    if scaled:
        stays += scaled["path"]
    print(f"the primitives' own motions step at {own:.0f}x real time against the circle's "
          f"{circle:.0f}x ({factor:.2f}x the cost; best of 3 each, one after the other); the "
          f"floor of the work that stays with the control loop's Python at zero (every "
          f"stage's stepping at that rate, the replay by its runs, the stages without physics "
          f"and the report as measured): {stays:.1f} s = {stays / (sensed_total + others):.2f}x "
          f"the lower bound; this run {total / stays:.2f}x it")
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
