"""How long does `simlab calibrate` take, and how close does it get to the sampling floor?

The benchmark: a calibration on a map-built arena of ~40 m2 with ~40 states on 2
cores. The default arena is ``map-lab``: a synthetic GMapping-like 8 x 5 m lab map written
here, turned into an arena by ``arena_from_map`` and discretized into 40 Voronoi states;
``--arena table_obstacles`` (or any TOML, with ``--states``) runs another case.

The "real" table: ``--real COUNTS`` (with ``--n-actions/--convention/--real-hours``), or by
default a hidden physics walk of ``--real-hours`` hours with 8 ccw-east actions and hidden
primitive settings (drive time 0.8 s, detector margin 0.08 m), so the benchmark also shows
how well they are recovered.

Prints: wall time of the calibration (and per candidate), simulated hours per wall second,
the distance of the starting point and of the calibrated parameters (fresh seed) against
the bootstrap floor and the matched floor, argmax agreement, and the parameters found.

Run: ``python benchmarks/calibrate_speed.py [--candidates 12] [--hours-per-candidate 2]
[--workers 2]``. The machine may be shared: the CPU times of the candidates are printed too.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from collect_speed import ground_truth_states  # benchmarks/ is on sys.path as the script's dir


def map_lab(directory: Path, n_states: int) -> tuple[Path, Path]:
    """A GMapping-like 8 x 5 m lab (40 m2: walls, a desk row, a pillar; unknown outside) at
    5 cm, its arena (``arena_from_map``, map frame kept) and ``n_states`` Voronoi states."""
    import numpy as np

    from discretize.gridmap import OccupancyMap
    from discretize.mapio import write_map
    from discretize.voronoi import Discretizer
    from simlab.physics.map_arena import arena_from_map

    res = 0.05
    occ = np.full((112, 172), -1, dtype=np.int8)         # 5.6 x 8.6 m image, unknown
    occ[5:107, 5:167] = 100                               # outer walls ...
    occ[6:106, 6:166] = 0                                 # ... around 8 x 5 m of floor
    occ[30:46, 40:120] = 100                              # a row of desks
    occ[75:83, 130:138] = 100                             # a pillar
    grid = OccupancyMap(occ, res, (-1.0, 2.0, 0.0))       # an off-origin map frame
    yaml_path, _ = write_map(directory / "map.yaml", grid)
    states = directory / "states.json"
    Discretizer.from_map(grid, n_states).save(states)
    arena = arena_from_map(yaml_path, directory / "lab.toml")
    return arena, states


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--arena", default="map-lab",
                        help="map-lab (a synthetic 40 m2 map-built lab, default), a built-in "
                             "arena or a TOML")
    parser.add_argument("--states", default=None, help="states file (default: ground truth)")
    parser.add_argument("--n-states", type=int, default=40)
    parser.add_argument("--real", default=None, help="real counts (default: hidden walk)")
    parser.add_argument("--n-actions", type=int, default=8)
    parser.add_argument("--convention", default="ccw-east")
    parser.add_argument("--real-hours", type=float, default=4.0)
    parser.add_argument("--hours-per-candidate", type=float, default=2.0)
    parser.add_argument("--candidates", type=int, default=12)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    from simlab.calibration.config import OBJECTIVES

    parser.add_argument("--objective", default="signature", choices=OBJECTIVES)
    args = parser.parse_args()

    from simlab.base.actions import parse_action_set
    from simlab.calibration.config import CalibrationConfig, RealTable
    from simlab.calibration.stages import calibrate
    from simlab.calibration.walks import simulate_counts
    from simlab.data.counts import load_counts
    from simlab.physics.inputs import load_discretizer
    from simlab.physics.motion import PrimitiveParams

    aset = parse_action_set(args.n_actions, args.convention)
    with tempfile.TemporaryDirectory(prefix="simlab-bench-") as tmp:
        if args.arena == "map-lab":
            args.arena, default_states = map_lab(Path(tmp), args.n_states)
        else:
            default_states = None if args.states else ground_truth_states(
                Path(tmp) / "states.json", args.arena, args.n_states)
        states = Path(args.states) if args.states else default_states
        disc = load_discretizer(states)
        hidden = None
        t0 = time.perf_counter()
        if args.real:
            counts = load_counts(args.real, n_states=disc.n_states,
                                 n_actions=aset.n_actions).counts
            real = RealTable(counts, aset, hours=args.real_hours, source=args.real)
        else:
            hidden = PrimitiveParams(drive_time=0.8, detector_margin=0.08)
            sim = simulate_counts(args.arena, disc, hidden, hours=args.real_hours,
                                  seed=10_000 + args.seed, action_set=aset)
            real = RealTable(sim.counts, aset, hours=sim.hours, blocked=sim.blocked,
                             source=f"hidden walk {hidden.drive_time} s / "
                                    f"{hidden.detector_margin} m")
        t_real = time.perf_counter() - t0
        cfg = CalibrationConfig(hours_per_candidate=args.hours_per_candidate,
                                candidates=args.candidates, workers=args.workers,
                                seed=args.seed, objective=args.objective, progress=False)
        t0 = time.perf_counter()
        res = calibrate(real, args.arena, disc, config=cfg)
        wall = time.perf_counter() - t0
    n_sim = (args.candidates + 1) * args.hours_per_candidate
    cpu = [c.sim.wall_seconds for c in res.candidates]
    print(f"arena {args.arena}, {disc.n_states} states, real: {real.source} "
          f"({int(real.counts.sum())} transitions, {aset.describe()}; made in {t_real:.0f} s)")
    print(f"  objective {args.objective}; calibration wall {wall:.0f} s with {args.workers} workers: {args.candidates} "
          f"candidates + 1 confirmation x {args.hours_per_candidate:g} h = {n_sim:g} simulated "
          f"h ({n_sim * 3600 / wall:.0f} simulated s per wall s); per candidate "
          f"{min(cpu):.0f}-{max(cpu):.0f} s")
    print(f"  start (defaults) distance {res.candidates[0].distance:.3f}; calibrated "
          f"{res.final.distance:.3f} on a fresh seed; floor {res.floor.median:.3f} "
          f"[{res.floor.low:.3f}, {res.floor.high:.3f}], matched floor "
          f"{res.matched_floor.median:.3f} [{res.matched_floor.low:.3f}, "
          f"{res.matched_floor.high:.3f}]; argmax agreement {res.agreement:.0%}")
    found = ", ".join(f"{n} {getattr(res.params, n):.3f}" for n in res.space.names)
    truth = "" if hidden is None else " (hidden: " + ", ".join(
        f"{n} {getattr(hidden, n):.3f}" for n in res.space.names) + ")"
    print(f"  found {found}{truth}; decision latency {res.params.decision_latency:.2f} s "
          f"({'fitted' if res.latency_fitted else 'kept'})")


if __name__ == "__main__":
    main()
