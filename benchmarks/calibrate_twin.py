"""Does `simlab calibrate`, exactly as the README gives it, make a faithful twin of a real lab?

The benchmark lab has the signature of a real TurtleBot lab's published data (a corridor lab
of about 9.3 m x 2.7 m mapped by GMapping at 5 cm, 38 Voronoi states with centres about
0.7 m apart, 8 actions numbered counter-clockwise from East, about 13 h and 5,000
transitions, a robot that drives until its state changes and stays in its state in about a
quarter of its moves, states from a noisy localization). Its "real" robot is a physics walk
whose settings the calibration never sees, and which holds effects that are **not** in the
searched space, so that the twin can only approximate them:

* drive until the state changes at a hidden speed, time limit and detector margin;
* wheel noise redrawn at every control tick and a random slip of up to 8 % of each move
  (the twin searches only a per-move wheel noise);
* states from a pose with 4 cm of localization error.

Prints the real table's signature, then the calibration's figures against the targets: the
visit-weighted TV distance against the bootstrap and matched floors, coverage, the
self-transition share and entropy sim vs real, the transfer of twin policies over the twin
seeds (expected steps to every goal on the real model against its optimum: mean and worst),
and the wall time on this machine.

``--compare-hz HZ`` runs the same calibration a second time with ``HZ`` as the default
physics rate (every walk of it, in every worker: ``benchmarks/rate_arm.py``), right after
the first, and prints both wall times and their ratio (200: the rate before it was a
setting).

Run: ``python benchmarks/calibrate_twin.py [--quick] [--workers 2] [--keep DIR]
[--compare-hz 200]``. ``--quick`` shrinks every budget (a smoke run, not the benchmark).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

#: The hidden robot (see the module docstring).
HIDDEN = dict(mode="until_state_change", fast_speed=0.18, max_drive_time=7.0,
              detector_margin=0.06, wheel_noise_tick=0.02, slip=0.08, pose_noise_xy=0.04)
REAL_HOURS = 13.0
REAL_TRANSITIONS = 5357


def build_lab(directory: Path, n_states: int = 38) -> tuple[Path, Path]:
    """The corridor lab's map (map_server files), its 38 states and its arena TOML."""
    from discretize.gridmap import OccupancyMap
    from discretize.mapio import write_map
    from discretize.voronoi import Discretizer
    from simlab.physics.map_arena import arena_from_map

    res = 0.05
    h, w = 54 + 12, 186 + 12                 # 2.7 x 9.3 m of floor and a margin
    occ = np.full((h, w), -1, dtype=np.int8)  # unknown outside the walls
    occ[4:h - 4, 4:w - 4] = 100               # walls ...
    occ[6:h - 6, 6:w - 6] = 0                 # ... around the floor
    occ[6:18, 40:76] = 100                    # a desk row against the top wall
    occ[6:16, 120:150] = 100                  # a bench
    occ[44:60, 100:108] = 100                 # a cabinet at the bottom wall
    occ[30:36, 160:166] = 100                 # a pillar
    grid = OccupancyMap(occ, res, (-0.3, -0.3, 0.0))
    yaml_path, _ = write_map(directory / "map.yaml", grid)
    states = directory / "states.json"
    Discretizer.from_map(grid, n_states).save(states)
    arena = arena_from_map(yaml_path, directory / "lab.toml", states=states)
    return arena, states


def hidden_real(arena: Path, states: Path, out: Path, seed: int, hours: float,
                workers: int) -> dict:
    """Collect the hidden robot's walk and write its counts (CSV); returns a summary."""
    from simlab.base.actions import parse_action_set
    from simlab.calibration.walks import simulate_counts
    from simlab.data.collect import collect
    from simlab.data.dataset import read_dataset
    from simlab.data.estimate import count_transitions
    from simlab.physics.motion import PrimitiveParams

    aset = parse_action_set(8, "ccw-east", "fast")
    probe = PrimitiveParams(**HIDDEN)
    # the latency that makes `hours` give REAL_TRANSITIONS, from a short probe of the walk
    short = simulate_counts(arena, states, probe, transitions=400, seed=seed + 1000,
                            action_set=aset, start_states="all")
    latency = max(0.0, 3600 * REAL_HOURS / REAL_TRANSITIONS - short.mean_duration)
    params = PrimitiveParams(**HIDDEN, decision_latency=latency)
    walk = out.with_suffix("")
    collect(arena, states, out=walk, hours=hours, seed=seed, workers=workers, params=params,
            n_actions=8, convention="ccw-east", speed="fast", start_states="all",
            progress=False)
    t = read_dataset(walk)
    counts = count_transitions(t.column("s").to_numpy(), t.column("a").to_numpy(),
                               t.column("s_next").to_numpy(), 38, aset.n_actions)
    s, a, s2 = np.nonzero(counts)
    lines = ["s,a,s_next,count"] + [f"{i},{j},{k},{counts[i, j, k]}"
                                    for i, j, k in zip(s, a, s2, strict=True)]
    out.write_text("\n".join(lines) + "\n")
    real_hours = float((t.column("duration").to_numpy() + latency).sum()) / 3600
    return {"transitions": int(counts.sum()), "hours": real_hours, "latency": latency}


def run_calibrate(cmd: list[str], env: dict[str, str]) -> float:
    """Run the calibrate command line; its wall seconds (its output printed)."""
    t1 = time.perf_counter()
    proc = subprocess.run(cmd, text=True, capture_output=True, env=env)
    wall = time.perf_counter() - t1
    print(proc.stdout.strip())
    if proc.returncode:
        print(proc.stderr.strip())
        raise SystemExit(proc.returncode)
    return wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="small budgets (smoke run)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=7, help="seed of the hidden walk")
    parser.add_argument("--keep", type=Path, default=None, help="keep the files here")
    parser.add_argument("--reuse", action="store_true",
                        help="reuse the lab and hidden walk already in --keep")
    parser.add_argument("--compare-hz", type=float, default=0.0,
                        help="also calibrate with this default physics rate (0: no)")
    args = parser.parse_args()

    from simlab.calibration.signature import real_signature
    from simlab.data.counts import load_counts
    from simlab.physics.inputs import load_discretizer

    root = args.keep or Path(tempfile.mkdtemp(prefix="simlab-twin-"))
    root.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    real_csv = root / "real.csv"
    if args.reuse and (root / "real.json").is_file():
        arena, states = root / "lab.toml", root / "states.json"
        info = json.loads((root / "real.json").read_text())
    else:
        arena, states = build_lab(root)
        info = hidden_real(arena, states, real_csv, args.seed,
                           2.0 if args.quick else REAL_HOURS, args.workers)
        (root / "real.json").write_text(json.dumps(info))
    t_real = time.perf_counter() - t0
    disc = load_discretizer(states)
    counts = load_counts(real_csv, n_states=int(disc.n_states), n_actions=8).counts
    sig = real_signature(counts, disc.centres)
    print(f"benchmark lab: {disc.n_states} states, cells {sig.cell_size:.2f} m; hidden real "
          f"walk {info['transitions']} transitions in {info['hours']:.1f} h "
          f"(made in {t_real:.0f} s)")
    print(f"real signature: self-transition share {sig.self_share:.2f}, mean entropy "
          f"{sig.mean_entropy:.2f} bits, {sig.pairs_visited}/{sig.pairs} pairs, "
          f"{sig.states_visited}/{sig.states} states")

    out = root / "cal"
    cmd = [sys.executable, "-m", "simlab", "calibrate", "--real", str(real_csv),
           "--states", str(states), "--arena", str(arena), "--n-actions", "8",
           "--convention", "ccw-east", "--speed", "fast", "--real-hours",
           f"{info['hours']:.4f}", "--out", str(out), "--workers", str(args.workers),
           "--no-progress"]
    if args.quick:
        cmd += ["--candidates", "4", "--confirm-top", "1", "--confirm-seeds", "1",
                "--transfer-seeds", "2", "--confirm-hours", "1"]
    print("$ simlab " + " ".join(cmd[3:]))
    load0 = os.getloadavg()[0]
    wall = run_calibrate(cmd, dict(os.environ))
    rep = json.loads((out / "report.json").read_text())
    if args.compare_hz:
        from rate_arm import default_rate_env

        from simlab.physics.rate import DEFAULT_HZ

        other = root / f"cal-{args.compare_hz:g}hz"
        cmd_hz = [other if c == str(out) else c for c in cmd]
        wall_hz = run_calibrate([str(c) for c in cmd_hz], default_rate_env(args.compare_hz, root))
        d_hz = json.loads((other / "report.json").read_text())["distance"]["distance"]
        print(f"\ncalibrate at the default {DEFAULT_HZ:g} Hz: {wall:.0f} s wall; at "
              f"{args.compare_hz:g} Hz: {wall_hz:.0f} s ({wall_hz / wall:.2f}x; its TV distance "
              f"{d_hz:.3f}); load {load0:.2f} before, {os.getloadavg()[0]:.2f} after")
    d = rep["distance"]["distance"]
    fl, mf = rep["floor"]["median"], rep["matched_floor"]["median"]
    cov = rep["coverage"]
    ov = rep["transfer"]["overview"] if rep["transfer"] else None
    print()
    print(f"TV distance {d:.3f}: {d / mf:.2f} x the matched floor {mf:.3f} (target <= 1.5), "
          f"{d / fl:.2f} x the bootstrap floor {fl:.3f} (target <= 2)")
    print(f"coverage: the twin tried {cov['real_pairs_tried']} of {cov['real_pairs']} real "
          f"pairs ({100 * cov['real_weight_tried']:.1f} % of the real transitions), reached "
          f"{cov['states_reached']} of {cov['states']} states")
    print(f"self-transition share sim {rep['sim']['self_transition_share']:.2f} / real "
          f"{rep['real']['self_transition_share']:.2f}; mean entropy sim "
          f"{rep['sim']['mean_entropy_bits']:.2f} / real {rep['real']['mean_entropy_bits']:.2f}"
          " bits")
    if ov is not None:
        ratios = [t["ratio"] if t["ratio"] is not None else float("inf") for t in ov["twins"]]
        print(f"transfer over {len(ratios)} twin seeds, {ov['goals']} goals: steps / real "
              f"optimum mean {np.mean(ratios):.3f}, worst {max(ratios):.3f} (target: every "
              f"seed <= 1.05); per seed " + ", ".join(f"{r:.3f}" for r in ratios))
    if rep["transfer"] and rep["transfer"].get("data_curve"):
        print("transfer against the twin's data (the twin walks pooled): " + "; ".join(
            f"{r['transitions']} transitions {r['mean_ratio']:.3f} (worst {r['worst_ratio']:.3f})"
            for r in rep["transfer"]["data_curve"] if r["mean_ratio"] is not None))
        need = rep["transfer"].get("data_need")
        if need:
            print(f"  fitted limit (unlimited twin data) {need['limit']:.3f}; "
                  f"{need['transitions']} twin transitions bring a policy within "
                  f"{need['tolerance']} of it")
    hidden = {k: v for k, v in HIDDEN.items() if k in rep["params"]}
    found = {k: rep["params"][k] for k in hidden}
    print(f"hidden {hidden}\nfound  {found}")
    print(f"wall time of calibrate: {wall:.0f} s on {os.cpu_count()} cores (target < 900 s); "
          f"files in {root}")


if __name__ == "__main__":
    main()
