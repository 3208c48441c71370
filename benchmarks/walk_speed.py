"""How many simulated transitions per wall second does the calibration walk run?

`simlab calibrate` spends its time in one walk: the physics walker driving each primitive
until the *localized* state changes (``mode = "until_state_change"`` with pose noise), the
obstacle detector re-run at every 10 Hz control tick, 8 ccw-east actions at the fast speed,
one walk from every state (``start_states = "all"``). This script builds the benchmark
lab of ``benchmarks/calibrate_twin.py`` (a 9.3 x 2.7 m corridor lab, 38 states), collects
``--transitions`` of that walk, and in the same run the fixed-time walk of the default
table arena (16 primitives, the thesis's 0.5 s drive) as a baseline, and prints
transitions per wall second and CPU second of both and their ratio.

``--profile`` runs the calibration walk once more under ``cProfile`` and prints the top
entries by own time (ray tests, the per-tick state lookup, stepSimulation, Python overhead
of the tick loop).

``--compare-hz HZ`` (default 200, the rate before it was a setting; 0: none) runs the
calibration walk at that physics rate too, in turn with the others, and prints its CPU per
transition against the default rate's (what a calibration's walks gain from the rate).

Run: ``python benchmarks/walk_speed.py [--transitions 760] [--repeat 3] [--profile]
[--top 25] [--compare-hz 200]``. The machine may be shared: the load average (``os.getloadavg``) is printed with
the numbers, and ``--repeat`` alternates the two walks and reports the best (least CPU) and
the median of each. The old code can be measured by the same script with
``PYTHONPATH=<a checkout of it>`` (the script imports ``simlab`` from there).
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

from calibrate_twin import HIDDEN, build_lab  # benchmarks/ is on sys.path as the script's dir
from collect_speed import ground_truth_states

#: A calibration candidate's primitive settings: the twin's searched space holds the drive
#: mode, speed, time limit, detector margin, localization error and a per-move wheel noise
#: (``simlab.calibration.space``); here they take the hidden robot's values.
TWIN = dict(mode="until_state_change", fast_speed=HIDDEN["fast_speed"],
            max_drive_time=HIDDEN["max_drive_time"], detector_margin=HIDDEN["detector_margin"],
            pose_noise_xy=HIDDEN["pose_noise_xy"], wheel_noise=0.05)


def lab_walk(root: Path, transitions: int, seed: int) -> dict[str, Any]:
    """Keyword arguments of :func:`simlab.data.collect.collect` for the calibration walk."""
    from simlab.physics.motion import PrimitiveParams

    arena, states = build_lab(root)
    return dict(arena=arena, states=states, transitions=transitions, seed=seed, workers=1,
                params=PrimitiveParams(**TWIN), n_actions=8, convention="ccw-east",
                speed="fast", start_states="all", progress=False)


def table_walk(root: Path, transitions: int, seed: int) -> dict[str, Any]:
    """Keyword arguments of :func:`simlab.data.collect.collect` for the table baseline."""
    states = ground_truth_states(root / "table_states.json", "table", 41)
    return dict(arena="table", states=states, transitions=transitions, seed=seed, workers=1,
                progress=False)


def timed(kwargs: dict[str, Any], out: Path) -> tuple[float, float, int]:
    """(wall s, CPU s, transitions) of one collection into ``out``."""
    from simlab.data.collect import collect

    w0, c0 = time.perf_counter(), time.process_time()
    result = collect(out=out, **kwargs)
    return time.perf_counter() - w0, time.process_time() - c0, int(result.transitions)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--transitions", type=int, default=760,
                        help="transitions of each walk (760 = 20 per start state of the lab)")
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--repeat", type=int, default=1, help="timed runs of each walk")
    parser.add_argument("--profile", action="store_true", help="cProfile the calibration walk")
    parser.add_argument("--top", type=int, default=25, help="profile entries to print")
    parser.add_argument("--calibration-transitions", type=int, default=77_000,
                        help="transitions of a calibration, for the wall-time estimate")
    parser.add_argument("--compare-hz", type=float, default=200.0,
                        help="physics rate of a second calibration walk (0: none)")
    args = parser.parse_args()

    import simlab

    print(f"simlab from {Path(simlab.__file__).parent}")
    with tempfile.TemporaryDirectory(prefix="simlab-walk-") as tmp:
        root = Path(tmp)
        lab = lab_walk(root, args.transitions, args.seed)
        table = table_walk(root, args.transitions, args.seed)
        load0 = os.getloadavg()[0]
        runs: dict[str, list[tuple[float, float, int]]] = {"lab": [], "table": [],
                                                           "lab at compare-hz": []}
        for i in range(args.repeat):
            runs["lab"].append(timed(lab, root / f"lab-walk-{i}"))
            runs["table"].append(timed(table, root / f"table-walk-{i}"))
            if args.compare_hz:
                runs["lab at compare-hz"].append(timed({**lab, "physics_hz": args.compare_hz},
                                                       root / f"lab-walk-hz-{i}"))
        load1 = os.getloadavg()[0]
        print(f"load average (1 min) {load0:.2f} before, {load1:.2f} after; "
              f"{os.cpu_count()} cores; {args.repeat} run(s) of each walk")
        rate = {}
        for name, label in (("lab", "calibration walk (lab, until_state_change + pose noise, "
                                    "8 fast actions, all starts)"),
                            ("table", "baseline (table, fixed 0.5 s, 16 primitives)")):
            n = runs[name][0][2]
            cpu = sorted(r[1] for r in runs[name])
            wall = sorted(r[0] for r in runs[name])
            rate[name] = (n / wall[0], n / cpu[0])
            print(f"{label}: {n} transitions; best {wall[0]:.1f} s wall / {cpu[0]:.1f} s CPU "
                  f"= {n / wall[0]:.1f} /s wall, {n / cpu[0]:.1f} /s CPU; median "
                  f"{n / statistics.median(cpu):.1f} /s CPU")
        print(f"ratio calibration walk / baseline (best runs): "
              f"{rate['lab'][0] / rate['table'][0]:.3f} wall, "
              f"{rate['lab'][1] / rate['table'][1]:.3f} CPU")
        if args.compare_hz:
            from simlab.physics.rate import DEFAULT_HZ

            other = statistics.median(r[1] / r[2] for r in runs["lab at compare-hz"])
            mine = statistics.median(r[1] / r[2] for r in runs["lab"])
            print(f"calibration walk at {args.compare_hz:g} Hz: {1e3 * other:.2f} ms CPU per "
                  f"transition (median) against {1e3 * mine:.2f} at the default "
                  f"{DEFAULT_HZ:g} Hz: {other / mine:.2f}x")
        n = args.calibration_transitions
        per = 1.0 / rate["lab"][1]
        print(f"estimate: {n} calibration transitions = {n * per:.0f} CPU s, so about "
              f"{n * per / 2:.0f} s wall on 2 idle cores (walks only)")
        if args.profile:
            prof = cProfile.Profile()
            prof.enable()
            timed(lab, root / "lab-walk-profiled")
            prof.disable()
            stats = pstats.Stats(prof)
            stats.sort_stats("tottime").print_stats(args.top)


if __name__ == "__main__":
    main()
