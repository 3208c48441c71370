"""Does calibration keep both cores busy? Candidates' walks scheduled walk by walk against
candidate by candidate, in one run, on the same jobs.

A calibration walks its candidates in batches (``--batch`` 4 at rung 1, the four picks and
the start at the confirmation, the two extra twin seeds at the end). Scheduled one candidate
per worker, a batch lasts as long as its slowest candidate's walk, and a batch of one (the
confirmation's fifth candidate) leaves a core idle for a whole walk. The calibration's
:class:`~simlab.calibration.walks.WalkRunner` sends the candidates' walks (one per start
state) to the workers as they free up instead. This benchmark maps the same jobs both ways:

* ``candidate``: one job per worker (the scheduling before: each candidate's whole walk in
  one worker process, via ``executor.map`` of :func:`~simlab.calibration.walks.simulate_table`);
* ``walk``: ``WalkRunner.map`` (the calibration's).

Cases: ``batch`` (``--batch`` candidates of the screening size, their fields spread over the
calibration's default space, so their walks last differently), ``tail`` (one candidate of the
confirming size, alone: the confirmation's fifth). Prints the wall time of each arm, their
ratio, the CPU seconds of the walks (what an ideal schedule on ``--workers`` cores would take
``cpu / workers`` of) and checks that both give the same tables.

Lab: the real ISIR lab (``../shared/real-lab``, the calibrate benchmark's lab) when present,
else the synthetic map-built lab of ``calibrate_speed.py``.

Run: ``python benchmarks/walk_scheduling.py [--workers 2] [--batch 4] [--screen 1335]
[--confirm 8012] [--repeats 2]``.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

REAL_LAB = Path(__file__).resolve().parents[2] / "shared" / "real-lab"


def isir_lab(tmp: Path, folder: Path = REAL_LAB) -> tuple[Any, Any, str]:
    """(arena, discretizer, name) of the ISIR lab built in ``tmp`` from its data in
    ``folder`` (the README's ``discretize`` and ``arena-from-map`` steps)."""
    from simlab.commands import discretize
    from simlab.physics.inputs import load_arena_config, load_discretizer
    from simlab.physics.map_arena import arena_from_map

    states = tmp / "states.json"
    discretize(map=folder / "mymap.yaml", centres=folder / "voronoiCenters_exp.dat",
               out=states, flip_y=True, png=None)
    arena = arena_from_map(folder / "mymap.yaml", tmp / "lab.toml", states=states,
                           flip_y=True)
    return load_arena_config(arena), load_discretizer(states), "ISIR lab (38 states)"


def lab(tmp: Path) -> tuple[Any, Any, str]:
    """(arena, discretizer, name): the ISIR lab when its data are beside the repository."""
    if (REAL_LAB / "mymap.yaml").is_file():
        return isir_lab(tmp)
    from calibrate_speed import map_lab

    from simlab.physics.inputs import load_arena_config, load_discretizer

    arena, states = map_lab(tmp, 40)
    return load_arena_config(arena), load_discretizer(states), "synthetic map lab (40 states)"


def jobs_of(arena: Any, disc: Any, n: int, transitions: int, seed: int) -> list[Any]:
    """``n`` candidates of the calibration's default space (a robot that drives until its
    state changes) at spread points, each a walk of ``transitions`` from every state."""
    from simlab.base.actions import parse_action_set
    from simlab.calibration.space import default_space
    from simlab.calibration.walks import WalkJob
    from simlab.physics.motion import PrimitiveParams

    aset = parse_action_set(8, "ccw-east", "fast")
    base = PrimitiveParams(mode="until_state_change", fast_speed=0.22)
    space = default_space(aset.primitives(), cell_size=0.7, speed_fields=("fast_speed",),
                          mode="until_state_change")
    rng = np.random.default_rng(seed)
    return [WalkJob(index=i, arena=arena, states=disc,
                    params=space.apply(base, rng.uniform(0.1, 0.9, space.dim)), hours=None,
                    transitions=transitions, seed=seed, simulator="physics",
                    pose_source="truth", action_set=aset, start_states="all",
                    n_states=int(disc.n_states))
            for i in range(n)]


def by_candidate(jobs: list[Any], workers: int) -> tuple[list[Any], float]:
    from simlab.base.parallel import make_executor
    from simlab.calibration.walks import simulate_table

    with make_executor("local", workers=workers) as ex:
        ex.map(simulate_table, [{"job": jobs[0]}])  # the pool up (not timed)
        t0 = time.perf_counter()
        out = ex.map(simulate_table, [{"job": j} for j in jobs])
        return out, time.perf_counter() - t0


def by_walk(jobs: list[Any], workers: int) -> tuple[list[Any], float]:
    from simlab.calibration.walks import WalkRunner

    runner = WalkRunner(workers)
    try:
        runner.map(jobs[:1])  # the pool up (not timed)
        t0 = time.perf_counter()
        out = runner.map(jobs)
        return out, time.perf_counter() - t0
    finally:
        runner.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--batch", type=int, default=4)
    parser.add_argument("--screen", type=int, default=1335, help="screening walk size")
    parser.add_argument("--confirm", type=int, default=8012, help="confirming walk size")
    parser.add_argument("--repeats", type=int, default=2, help="batches per arm (seeds)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="simlab-sched-") as tmp:
        arena, disc, name = lab(Path(tmp))
        print(f"{name}, {args.workers} workers, load {os.getloadavg()[0]:.1f}")
        cases = [(f"batch of {args.batch} x {args.screen:,}", args.batch, args.screen),
                 (f"tail: 1 x {args.confirm:,}", 1, args.confirm)]
        for label, n, size in cases:
            walls = {"candidate": 0.0, "walk": 0.0}
            cpu = 0.0
            for r in range(args.repeats):
                jobs = jobs_of(arena, disc, n, size, seed=r)
                old, wall_old = by_candidate(jobs, args.workers)
                new, wall_new = by_walk(jobs, args.workers)
                walls["candidate"] += wall_old
                walls["walk"] += wall_new
                cpu += sum(t.wall_seconds for t in new)
                same = all(np.array_equal(a.counts, b.counts) for a, b in zip(old, new,
                                                                              strict=True))
                if not same:
                    raise SystemExit(f"{label}: the two schedules gave different tables")
            print(f"{label} ({args.repeats} seeds): by candidate {walls['candidate']:.1f} s, "
                  f"walk by walk {walls['walk']:.1f} s ({walls['walk'] / walls['candidate']:.2f}"
                  f"x); the walks' CPU {cpu:.1f} s (ideal on {args.workers} cores "
                  f"{cpu / args.workers:.1f} s); same tables")
        print(f"load {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
