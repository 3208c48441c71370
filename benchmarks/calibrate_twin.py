"""Does `simlab calibrate`, exactly as the README gives it, make a faithful twin of a real lab?

Two labs (``--lab``):

* ``isir`` (the benchmark): the real ISIR TurtleBot arena of ``../shared/real-lab`` (its
  13-hour transition model, GMapping map and 38 state centres; refused, naming the path,
  when the folder is absent). The README's "Your own lab" path, command by command:
  ``discretize --flip-y``, ``arena-from-map --flip-y``, ``estimate --counts``,
  ``calibrate``, the policy data the report recommends (``collect`` + ``estimate``), and
  ``transfer`` on the real model with state 18's real moves (its rows from
  ``_newGoal.json``: in the 13-hour model they are the episode reset). Prints the figures
  of the real lab's table: TV against its floors, self-transition share and entropy twin
  / real, the blocked share and the signature by region, the twin policies as calibrate's
  report says and from the recommended policy data against the perfect-twin line at the
  same data, and calibrate's wall time with the machine's load.
* ``synthetic``: a corridor lab with the real lab's signature whose "real" robot is a
  physics walk with hidden settings: the check that a known robot is recovered. The
  hidden robot holds what the real lab taught (a drifting localization error, a stop at
  the localization's rate, slides and back-offs at walls) and effects the twin cannot
  represent (per-tick wheel noise, a random slip). Calibrate runs with its profile
  (``--profile-step 0.25`` unless ``--calibrate-args`` gives one), and every searched field's
  hidden value (its setting here, else the default it walked with) is checked against the
  spread the report states for it: the values the profile's moves do not exclude. Then
  the search against the truth: every seed's winner, the hidden values in the twin's space
  (the searched fields at the hidden robot's values, the held ones at calibrate's) and the
  hidden robot itself walk on the same fresh seeds, and their TV to the real table says how
  far above the truth the search stopped, and how optimistic the distance calibrate reports
  (on the winner's own confirming seed) is.
  Measured (three seeds, 2-core VM, load 1.8-1.9, 66 minutes): 1.14/1.19/1.18x the matched
  floor, at the recommended data 1.019/1.026/1.024x a perfect twin; six of nine fields held the
  hidden value on every seed (pose persistence, localization rate, wall back-off on two of
  three: the profile is a slice at the winner, and those fields trade off; seven on every seed
  once the confirmation's other candidates are read, which free seed 0's 2 Hz); on fresh seeds the
  hidden robot 1.16x, its values in the twin's space 1.16x, the winners 1.22/1.24/1.17x.
  With ``--calibrate-args=--profile-pairs`` the recovery lines also give the slice alone from
  the same walks, and the pairs of fields the data tie (seeds 0 and 1: every field inside on
  one of two seeds either way, 60-112 pair walks, 2,005-3,074 s a seed). Lost on seed 0: a
  CMA-ES search of the other fields at each value still excluded (8 walks a value, 120 walks)
  and a quadratic surface of the profile's walks freed no hidden value (the hidden values are
  another basin; docs/pages/calibration.md, "Fields that trade off"). These recovery figures
  were read with the profile's normal band (2.77); with Student's for its three walks (6.08,
  ``benchmarks/calibrate_band.py``) seeds 11-13 (2026-12-07, load 1.9-2.0, 872-1,198 s):
  1.26/1.31/1.26x, at the recommended data 1.029/1.041/1.023x a perfect twin, every field
  inside on none of the three (one to three fields out each), the winners 1.26/1.35/1.27x on
  the truth seeds against the hidden values' 1.16x.
  Twice the proposals at half the screening walk (``--calibrate-args="--profile-step 0
  --candidates 96 --screen-share 0.125"``, the same walk budget; 2026-12-07, seeds 11-13,
  605-761 s at load 1.7-1.9): 1.34/1.25/1.20x, the winners 1.30/1.24/1.22x on the truth seeds,
  at the recommended data 0.999/1.028/1.008x a perfect twin (the defaults' 1.029/1.041/1.023x;
  read before the recommendation was kept at the smallest size measured),
  self share at the robot's visits 0.204/0.216/0.208 against 0.203: on each seed's own
  screening walk the hidden values would rank 3rd-11th of 49 (``calibrate_screen_noise.py``),
  so the search loses them in its proposals, and more proposals help there. **Lost on the
  ISIR lab** (the same arm, seeds 0-4, 2026-12-07, load 1.2-1.9; the defaults rerun the same
  evening): 1.57/1.60/1.67/1.59/1.67x the matched floor against the defaults'
  1.60/1.57/1.57/1.59/1.64x (mean 1.62 against 1.59, spread 0.10 against 0.07), at the
  recommended data 1.053/1.025/1.094/1.017/1.048x a perfect twin against 1.043/1.040/none/
  1.017/1.039x (seeds 1 and 3 at the 8,012 measured, where the fit had asked 1,321 and 4,459;
  seed 3 the same winner, the 5th candidate, both ways; seed 2 with a twin seed that never
  arrives both ways), seed 2's entropy 0.99 bits against the robot's 1.04, and
  572-833 s against 577-679 s (calibrate's own wall time; the defaults' seed 4: 1,023 s beside
  the test suite). Likely: where the twin's model cannot reach the robot, a
  screening walk half as long gives its noise more chances to promote a lucky candidate. The walks did
  not get dearer per transition with more starts, as first read from one run: a walk of 668
  transitions at calibrate's start costs 4.4 s in one process, one of 1,335 8.1 s, the 38
  starts (a world reset each) 0.43 s of it; what makes a calibration slower is where its
  candidates drive (the screening walked 6.3 ms a transition on seed 0, 9.2-9.9 on seeds
  1, 3 and 4, correlated with ``max_drive_time`` at r 0.46-0.82 over the candidates).

Each seed's line also gives the (s, a) pairs where its twin contradicts the robot beyond
sampling (calibrate's report, ``simlab.calibration.contradictions``), and with several seeds
the pairs every seed lists. Measured on the ISIR lab (seeds 0-4 of the defaults, each winner's
three twin walks of 8,012 transitions pooled; 2026-12-08): 20/21/22/24/24 of 294 pairs
listed (8-10 % of the real transitions, 16-20 % of the distance), 66-76 passing the raw 5 %
test where chance gives 15; listed by every seed: (0, 4), (12, 5), (14, 7), (32, 5), (35, 2),
all at the lab's two ends (seed 0 recalibrated with the test in place listed the
same 20, deterministic by seed).

The level is read against the distance a twin equal to the robot would show (the
perfect-twin floor, ``simlab.calibration.metrics.perfect_twin_floor``) beside the plug-in
matched floor, which reads low: on the synthetic lab the hidden robot walked afresh (four
walks of 8,012 on each of three real tables of 13 h) reads 1.20/1.14/1.17x the plug-in and
1.02/0.98/1.00x the perfect-twin floor. Measured on the ISIR lab (seeds 0-4 of the defaults,
2026-12-08, load 1.3-2.3, 507-785 s): 1.46/1.43/1.45/1.46/1.51x a twin equal to the robot
on the winner's confirming walk, 1.52/1.46/1.55/1.55/1.54x on its two fresh twin walks
(1.60/1.57/1.57/1.59/1.64x the plug-in; the same winners as before); at the recommended data,
with the perfect-twin lines drawn from coverage-adjusted shares over 100 resamples,
1.022/1.032/none/1.001/1.026x a perfect twin (from the plug-in over 20, as before:
1.043/1.040/none/1.017/1.039x). A twin equal to the robot never arrives somewhere on 13-18 %
of the real data's resamples at 8,012 transitions: about 2.4 of the 15 twin seeds by chance,
where the winners lose one.

With ``--seeds`` 2 or more, ``simlab calibrate-pool`` then reads the seeds' calibrations
together (each winner on the same fresh seeds, those within sampling of the best joined, the
union of what they allow; on the synthetic lab the hidden robot against that union).
Measured on the synthetic lab's seeds 0 to 2 (170 s, load 2): seeds 0 and 2 joined, seed 1
left out (+0.017 against a band of 0.008), and the union held every hidden value, which no
single seed's statement did on seeds 0 and 2; on seeds 3 to 5 (none holding every field alone)
only seed 3 joined and the union excluded the hidden 2 Hz: once in two triples.

``--compare-hz HZ`` runs the same calibration a second time with ``HZ`` as the default
physics rate (every walk of it, in every worker: ``benchmarks/rate_arm.py``), right after
the first, and prints both wall times and their ratio (200: the rate before it was a
setting).

Run: ``python benchmarks/calibrate_twin.py --lab isir [--keep DIR] [--reuse] [--workers 2]
[--compare-hz 200]`` or ``--lab synthetic [--quick]``. ``--quick`` shrinks every budget (a smoke run, not the
benchmark). ``--reuse`` takes the calibration and policy data already in ``--keep``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

#: The synthetic lab's hidden robot (see the module docstring): what the real lab taught
#: (a localization error that drifts between decisions, a stop at the localization's rate,
#: slides and back-offs at walls), then what the twin cannot represent.
HIDDEN = dict(mode="until_state_change", fast_speed=0.18, max_drive_time=7.0,
              detector_margin=0.06, pose_noise_xy=0.04, pose_noise_persistence=0.8,
              localization_hz=2.0, wall_slide=0.4, wall_back=0.05,
              wheel_noise_tick=0.02, slip=0.08)
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


#: The real lab's data: ``../shared/real-lab`` beside the repository.
REAL_LAB = Path(__file__).resolve().parents[2] / "shared" / "real-lab"
REAL_FILES = ("realisticNavWorld.json", "realisticNavWorld_newGoal.json", "mymap.yaml",
              "mymap.pgm", "voronoiCenters_exp.dat")


def simlab(*argv: object, log: Path | None = None,
           env: dict[str, str] | None = None) -> tuple[str, float]:
    """Run ``simlab ARGV`` in a fresh process (as a user would; ``env``: its environment,
    default this one's); (stdout, wall s). Stops the benchmark with the command's own error
    when it fails."""
    cmd = [sys.executable, "-m", "simlab", *map(str, argv)]
    print("$ simlab " + " ".join(map(str, argv)), flush=True)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, text=True, capture_output=True,
                          env={**os.environ} if env is None else env)
    wall = time.perf_counter() - t0
    if log is not None:
        log.write_text(proc.stdout + proc.stderr)
    if proc.returncode:
        print(proc.stdout + proc.stderr)
        raise SystemExit(proc.returncode)
    for line in proc.stderr.splitlines():
        if "warning" in line:
            print("  " + line)
    return proc.stdout, wall


def run_calibrate(real: Path, states: Path, arena: Path, hours: str, out: Path,
                  args: argparse.Namespace, *, reuse: bool, env: dict[str, str] | None = None,
                  seed: int = 0) -> tuple[dict, float, float]:
    """``simlab calibrate`` as the README gives it (8 ccw-east actions at the fast speed);
    (its report.json, wall s, load average over the run); an earlier run's report with
    ``reuse``. ``env``: the subprocess's environment (another default rate)."""
    timing = out.parent / f"{out.name}_time.json"
    if reuse and (out / "report.json").is_file() and timing.is_file():
        t = json.loads(timing.read_text())
        return json.loads((out / "report.json").read_text()), t["wall"], t["load"]
    extra = ["--candidates", "6", "--confirm-top", "1", "--transfer-seeds", "2",
             "--confirm-hours", "1"] if args.quick else []
    extra += ["--seed", seed]
    extra += args.calibrate_args.split()
    load0 = os.getloadavg()[0]
    stdout, wall = simlab("calibrate", "--real", real, "--states", states, "--arena", arena,
                          "--n-actions", 8, "--convention", "ccw-east", "--speed", "fast",
                          "--real-hours", hours, "--out", out, "--workers", args.workers,
                          "--no-progress", "--overwrite", *extra,
                          log=out.parent / f"{out.name}.log", env=env)
    load = (load0 + os.getloadavg()[0]) / 2
    print(stdout.strip())
    timing.write_text(json.dumps({"wall": wall, "load": load}))
    return json.loads((out / "report.json").read_text()), wall, load


def print_calibration(rep: dict, wall: float, load: float) -> None:
    """The calibration's figures against the targets."""
    d = rep["distance"]["distance"]
    fl, mf = rep["floor"]["median"], rep["matched_floor"]["median"]
    cov = rep["coverage"]
    pf = (rep.get("perfect_twin_floor") or {}).get("median")
    against = (f"{d / pf:.2f} x the distance of a twin equal to the robot {pf:.3f} (the "
               "perfect-twin floor; target <= 1.5), " if pf else "")
    print(f"\nTV distance {d:.3f}: {against}{d / mf:.2f} x the plug-in matched floor {mf:.3f}, "
          f"{d / fl:.2f} x the bootstrap floor {fl:.3f}")
    print(f"coverage: the twin tried {cov['real_pairs_tried']} of {cov['real_pairs']} real "
          f"pairs ({100 * cov['real_weight_tried']:.1f} % of the real transitions), reached "
          f"{cov['states_reached']} of {cov['states']} states")
    print(f"self-transition share twin / real {rep['sim']['self_transition_share']:.3f} / "
          f"{rep['real']['self_transition_share']:.3f}; mean entropy per action twin / real "
          f"{rep['sim']['mean_entropy_bits']:.2f} / {rep['real']['mean_entropy_bits']:.2f} "
          f"bits; twin moves refused by the detector {100 * rep['sim']['blocked_rate']:.1f} %")
    for row in rep.get("regions") or []:
        r, t = row["real"], row["sim"]
        print(f"  {row['region']:8s} {r['transitions']:5d} real transitions, TV "
              f"{row['tv']:.3f}; stay {r['stay']:.2f}/{t['stay']:.2f}, ahead "
              f"{r['ahead']:.2f}/{t['ahead']:.2f}, side {r['side']:.2f}/{t['side']:.2f}, "
              f"behind {r['behind']:.2f}/{t['behind']:.2f} (real/twin)")
    if rep.get("contradictions"):
        from simlab.calibration.contradictions import Contradictions

        print(Contradictions.from_json(rep["contradictions"]).summary())
    tr = rep.get("transfer")
    if tr:
        print(f"transfer ({tr['overview']['goals']} goals), as calibrate's report says: "
              f"{tr['headline']}")
        for row in tr["data_curve"]:
            print(f"  {row['transitions']} transitions: {_r(row['mean_ratio'])} (worst "
                  f"{_r(row['worst_ratio'])}), a perfect twin {_r(row.get('perfect_ratio'))}")
    searched = [x["name"] for x in rep["space"]]
    print("calibrated: " + ", ".join(f"{k}={rep['params'][k]:.4g}" if not isinstance(
        rep["params"][k], str) else f"{k}={rep['params'][k]}" for k in searched))
    print(f"wall time of calibrate: {wall:.0f} s on {os.cpu_count()} cores at load "
          f"{load:.1f} (target < 900 s)")


def seed_row(seed: int, rep: dict, wall: float, load: float) -> dict[str, Any]:
    """One seed's figures against the targets (the per-seed table's row)."""
    d, mf = rep["distance"]["distance"], rep["matched_floor"]["median"]
    gap = rep.get("signature_gap") or {}
    tr = rep.get("transfer") or {}
    ov = tr.get("overview") or {}
    twins = [t.get("ratio") for t in ov.get("twins", [])]
    need = tr.get("data_need") or {}
    at_need = tr.get("perfect_twin_at_need") or {}
    fit = (need["limit"] + need["c"] / need["transitions"]) if need else None
    perfect = at_need.get("ratio_median")
    pf = (rep.get("perfect_twin_floor") or {}).get("median")
    return {"seed": seed, "tv_over_matched": d / mf,
            "tv_over_perfect": d / pf if pf else None,
            "fresh_over_perfect": ((rep.get("level") or {}).get("fresh") or {}).get(
                "perfect_twin"), "self_twin": rep["sim"][
                "self_transition_share"], "self_real": rep["real"]["self_transition_share"],
            "self_visits_twin": gap.get("self_share"), "self_visits_real":
                gap.get("self_share_real"),
            "h_twin": rep["sim"]["mean_entropy_bits"], "h_real": rep["real"][
                "mean_entropy_bits"], "h_matched_twin": gap.get("entropy_bits"),
            "h_matched_real": gap.get("entropy_bits_real"), "regions_tv": gap.get("regions_tv"),
            "blocked": rep["sim"]["blocked_rate"],
            "twin_ratios": twins, "never": sum(x is None for x in twins),
            "perfect_never": (tr.get("perfect_twin_line") or {}).get("never_share"),
            "masked": tr.get("masked_ratios"),
            "fit_at_need": fit, "perfect_at_need": perfect,
            "at_need_over_perfect": fit / perfect if fit and perfect else None,
            "ensemble": len((rep.get("ensemble") or {}).get("members", [])),
            "ensemble_vs_winner": tr.get("ensemble_against_winner"),
            "contradictions": rep.get("contradictions"),
            "wall": wall, "load": load, "params": {x["name"]: rep["params"][x["name"]]
                                                   for x in rep["space"]}}


def _f(x: Any, fmt: str = "{:.3f}") -> str:
    return "n/a" if x is None else fmt.format(x)


def print_seeds(rows: list[dict[str, Any]]) -> None:
    """The per-seed table, then the spread across seeds of every figure that moves."""
    print("\nper seed (targets: TV <= 1.5x the distance of a twin equal to the robot, the "
          "perfect-twin floor, spread <= 0.1x; self share "
          "within +-0.03 and entropy within +-0.05 bits of the robot's; at the recommended "
          "data <= 1.03x the perfect twin; every twin arrives; <= 900 s quiet):")
    print("seed | TV/perfect twin (confirming walk; fresh twin walks) | TV/matched (plug-in) | "
          "self twin/robot (own walk; at robot's visits) | entropy "
          "twin/robot (plug-in; matched draws) | regions TV | blocked | twin ratios | "
          "at need / perfect | ensemble | wall s (load)")
    for r in rows:
        ratios = ", ".join(_f(x) if x is not None else "never" for x in r["twin_ratios"])
        if r.get("masked"):
            ratios += " (planned among the pairs the robot moved in: " + ", ".join(
                _f(x) if x is not None else "never" for x in r["masked"]) + ")"
        print(f"{r['seed']} | {_f(r['tv_over_perfect'], '{:.2f}')}; "
              f"{_f(r['fresh_over_perfect'], '{:.2f}')} | "
              f"{r['tv_over_matched']:.2f} | {_f(r['self_twin'])}/"
              f"{_f(r['self_real'])}; {_f(r['self_visits_twin'])}/{_f(r['self_visits_real'])}"
              f" | {_f(r['h_twin'], '{:.2f}')}/{_f(r['h_real'], '{:.2f}')}; "
              f"{_f(r['h_matched_twin'], '{:.2f}')}/{_f(r['h_matched_real'], '{:.2f}')} | "
              f"{_f(r['regions_tv'])} | {_f(r['blocked'])} | {ratios} | "
              f"{_f(r['at_need_over_perfect'])} | {r['ensemble']} | {r['wall']:.0f} "
              f"({r['load']:.1f})")
    for r in rows:
        e = r["ensemble_vs_winner"]
        if e:
            print(f"  seed {r['seed']}: ensemble of {e['members']} pooled "
                  f"{_f(e['ensemble_ratio'])} against the winner's walks "
                  f"{_f(e['winner_ratio'])} x the real optimum")
    if len(rows) < 2:
        return
    listed = [r["contradictions"] for r in rows if r["contradictions"]]
    if len(listed) == len(rows):
        from simlab.calibration.contradictions import Contradictions, common_pairs

        runs = [Contradictions.from_json(c) for c in listed]
        print(f"\npairs the twin contradicts beyond sampling (FDR {100 * runs[0].alpha:.0f} %): "
              + ", ".join(f"seed {r['seed']} {len(c.pairs)}" for r, c in zip(rows, runs,
                                                                              strict=True))
              + f"; listed by every seed: {common_pairs(runs) or 'none'}")
    shares = [r["perfect_never"] for r in rows if r["perfect_never"] is not None]
    if shares:  # the target "every twin seed arrives" against what a perfect twin does
        n_twins = sum(len(r["twin_ratios"]) for r in rows)
        expected = sum(r["perfect_never"] * len(r["twin_ratios"]) for r in rows
                       if r["perfect_never"] is not None)
        print(f"\ntwin seeds whose policy never arrives somewhere: "
              f"{sum(r['never'] for r in rows)} of {n_twins}; a twin equal to the robot at the "
              f"same data never arrives on {100 * min(shares):.0f}-{100 * max(shares):.0f} % of "
              f"the real data's resamples (the perfect-twin line's), about {expected:.1f} of "
              f"{n_twins} twin seeds by chance alone")
    print("\nspread across seeds (min - max, max - min):")
    for key, label in (("tv_over_perfect", "TV / perfect-twin floor"),
                       ("fresh_over_perfect", "TV / perfect-twin floor, fresh twin walks"),
                       ("tv_over_matched", "TV / plug-in matched floor"),
                       ("self_twin", "self share, own walk"),
                       ("self_visits_twin", "self share at the robot's visits"),
                       ("h_twin", "entropy per action, plug-in (bits)"),
                       ("h_matched_twin", "entropy per action, matched draws (bits)"),
                       ("regions_tv", "outcomes per region TV"),
                       ("at_need_over_perfect", "at the recommended data / perfect twin"),
                       ("wall", "wall s")):
        v = [r[key] for r in rows if r[key] is not None]
        if v:
            print(f"  {label}: {min(v):.3f} - {max(v):.3f} ({max(v) - min(v):.3f})")
    print("  calibrated fields (min - max):")
    for name in rows[0]["params"]:
        v = [r["params"][name] for r in rows]
        if isinstance(v[0], str):
            print(f"    {name}: {sorted(set(v))}")
        else:
            print(f"    {name}: {min(v):.4g} - {max(v):.4g}")


def compare_rate(args: argparse.Namespace, calibrate: Any, root: Path, rep: dict,
                 wall: float) -> None:
    """With ``--compare-hz``: the same calibration at that default physics rate, its wall
    time against the default rate's (``calibrate(out, env)`` runs it)."""
    if not args.compare_hz:
        return
    from rate_arm import default_rate_env

    from simlab.physics.rate import DEFAULT_HZ

    load0 = os.getloadavg()[0]
    other, wall_hz, _ = calibrate(root / f"cal-{args.compare_hz:g}hz",
                                  default_rate_env(args.compare_hz, root))
    print(f"\ncalibrate at the default {DEFAULT_HZ:g} Hz: {wall:.0f} s wall, TV "
          f"{rep['distance']['distance']:.3f}; at {args.compare_hz:g} Hz: {wall_hz:.0f} s "
          f"({wall_hz / wall:.2f}x), TV {other['distance']['distance']:.3f}; load "
          f"{load0:.2f} before, {os.getloadavg()[0]:.2f} after")


def _r(x: float | None) -> str:
    return "never" if x is None else f"{x:.3f}"


def spliced_counts(real_lab: Path, out: Path) -> Path:
    """The 13-hour model with state 18's real moves: its rows from ``_newGoal.json`` (in the
    13-hour model they are the reset to a start). A CSV of counts."""
    import warnings

    from simlab.data.counts import load_counts

    with warnings.catch_warnings():  # the published files repeat one (s, a, s') row
        warnings.simplefilter("ignore")
        base = load_counts(real_lab / "realisticNavWorld.json", n_actions=8).counts
        moves = load_counts(real_lab / "realisticNavWorld_newGoal.json", n_actions=8).counts
    base[18] = moves[18]
    s, a, s2 = np.nonzero(base)
    out.write_text("s,a,s_next,count\n" + "".join(
        f"{i},{j},{k},{base[i, j, k]}\n" for i, j, k in zip(s, a, s2, strict=True)))
    return out


def isir(args: argparse.Namespace) -> None:
    """The real ISIR lab through the README's commands (module docstring)."""
    lab = Path(args.real_lab)
    missing = [f for f in REAL_FILES if not (lab / f).is_file()]
    if missing:
        raise SystemExit(f"calibrate_twin.py: error: the real lab's data are not in {lab} "
                         f"(missing {', '.join(missing)}); give --real-lab DIR, or run "
                         "--lab synthetic")
    root = args.keep or Path(tempfile.mkdtemp(prefix="simlab-isir-"))
    root.mkdir(parents=True, exist_ok=True)
    states, arena, model = root / "states.json", root / "lab.toml", root / "robot.npz"
    if not (args.reuse and model.is_file()):
        simlab("discretize", "--map", lab / "mymap.yaml", "--centres",
               lab / "voronoiCenters_exp.dat", "--out", states, "--flip-y", "--overwrite")
        simlab("arena-from-map", lab / "mymap.yaml", "--states", states, "--out", arena,
               "--flip-y", "--overwrite")
        simlab("estimate", "--counts", lab / "realisticNavWorld.json", "--n-actions", 8,
               "--convention", "ccw-east", "--speed", "fast", "--states", states, "--arena",
               arena, "--out", model, "--no-plot", "--overwrite")
    rows = []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        out = root / ("cal" if args.seeds == 1 else f"cal-seed{seed}")
        rep, wall, load = run_calibrate(lab / "realisticNavWorld.json", states, arena, "13",
                                        out, args, reuse=args.reuse, seed=seed)
        print_calibration(rep, wall, load)
        rows.append(seed_row(seed, rep, wall, load))
        print_seeds(rows)
    if args.seeds > 1:
        run_pool(root, [root / f"cal-seed{r['seed']}" for r in rows],
                 lab / "realisticNavWorld.json", states, arena, args)
        print(f"files in {root}")
        return
    compare_rate(args, lambda out, env: run_calibrate(
        lab / "realisticNavWorld.json", states, arena, "13", out, args, reuse=args.reuse,
        env=env), root, rep, wall)
    policy_transfer(args, lab, root, rep, states, arena)
    print(f"files in {root}")


def policy_transfer(args: argparse.Namespace, lab: Path, root: Path, rep: dict,
                    states: Path, arena: Path) -> None:
    """README step 5: the recommended policy data, and step 5b: its policy on the real
    model with state 18's real moves, against the perfect twin at the same data."""
    need = (rep.get("transfer") or {}).get("data_need")
    if not need:
        print("no policy-data figure in the report: step 5 skipped")
        return
    if need.get("flat"):
        print(f"the report's policy data: {need['transitions']:,} transitions, its largest "
              "pool (more data do not improve the twin's policies)")
    data, mdp = root / "policy_data", root / "sim.npz"
    size = ["--hours", str(max(1, round(need["hours"])))] if need.get("hours") else [
        "--transitions", str(need["transitions"])]
    if args.quick:
        size = ["--transitions", "3000"]
    if not (args.reuse and mdp.is_file()):
        shutil.rmtree(data, ignore_errors=True)  # the benchmark's own folder
        _, wall = simlab("collect", "--arena", arena, "--states", states, "--primitives",
                         root / "cal" / "primitives.toml", "--n-actions", 8, "--convention",
                         "ccw-east", "--speed", "fast", "--start-states", "all", *size,
                         "--workers", args.workers, "--out", data, "--no-progress")
        print(f"  policy data collected in {wall:.0f} s")
        simlab("estimate", data, "--out", mdp, "--no-plot", "--overwrite")
    real18 = root / "robot18.npz"
    simlab("estimate", "--counts", spliced_counts(lab, root / "robot18.csv"), "--n-actions",
           8, "--convention", "ccw-east", "--speed", "fast", "--states", states, "--arena",
           arena, "--out", real18, "--no-plot", "--overwrite")
    # the policy data are scored under calibrate's own rule for pairs the real robot never
    # tried or never left (its report's config; "stay" is calibrate's default)
    untried = (rep.get("config") or {}).get("untried", "stay")
    for real, name in ((real18, "with state 18's real moves"),
                       (root / "robot.npz", "the 13-hour model (state 18 a reset)")):
        out = root / f"transfer_{real.stem}"
        simlab("transfer", "--real", real, "--sim", mdp, "--states", states,
               "--out", out, "--n-boot", 30, "--no-plot", "--overwrite",
               "--untried", untried)
        res = json.loads((out / "transfer.json").read_text())
        ov = res["over_goals"]["twins"][0]
        never = sum(t["never_share"] > 0 for g in res["goals"] for t in g["twins"])
        gap = "n/a" if ov["gap"] is None else f"{100 * ov['gap']:+.1f} %"
        print(f"twin policy from the recommended policy data ({need['transitions']:,} "
              f"transitions), {len(res['goals'])} goals, on {name}: {_r(ov['ratio'])} x the "
              f"real optimum's steps against a perfect twin's "
              f"{_r(ov['perfect_twin_same_data'])} at the same data "
              f"({gap}; target "
              f"<= +5 %); goals with a start that never arrives: {never}")


#: The profile's move on the synthetic lab, as a share of each field's range: the spread the
#: report states is what the moves of this size leave (simlab.calibration.profile).
PROFILE_STEP = 0.25


def recovery(rep: dict) -> list[dict[str, Any]]:
    """Per searched field: the hidden robot's value (its :data:`HIDDEN` setting, else the
    primitives' default it walked with), the twin's, and whether the hidden value lies in
    the spread calibrate's report states for it (the profile's allowed values)."""
    from simlab.calibration.pool import report_profile
    from simlab.calibration.profile import FieldProfile
    from simlab.calibration.space import ParameterSpace
    from simlab.physics.motion import PrimitiveParams

    robot = PrimitiveParams(**HIDDEN)
    space = ParameterSpace.from_json(rep["space"])
    prof, _ = report_profile(rep)  # a kept report of an older calibrate: today's band
    found = {} if prof is None else {f.name: f for f in prof.fields}
    out = []
    for spec in space.specs:
        name = spec.name
        truth = getattr(robot, name)
        field = found.get(name) or FieldProfile(name, rep["params"][name], (), None)
        # the slice alone (each field moved with the others at the winner's values): what
        # the report states without --profile-pairs, from the same walks
        slice_ = field.sliced(spec, math.nan if prof is None else prof.limit)
        out.append({"field": name, "hidden": truth, "twin": field.value,
                    "allowed": None if field.allowed is None else list(field.allowed),
                    "open": field.open, "told": field.told,
                    "inside": field.admits(truth), "past_range": field.past_range(truth),
                    "inside_slice": slice_.admits(truth),
                    "width": _width(spec, field), "width_slice": _width(spec, slice_)})
    return out


def _width(spec: Any, field: Any) -> float:
    """The share of the searched range (in the unit cube) a numeric field's allowed values
    span, an open side counted to the range's end; a named field: the share of choices left."""
    if field.allowed is None:
        return math.nan
    if spec.categorical:
        return len(field.allowed) / len(spec.choices)
    return float(spec.unit(field.allowed[1]) - spec.unit(field.allowed[0]))


def print_recovery(found: list[list[dict[str, Any]]]) -> None:
    """The last seed's hidden fields against the stated spread, then the count over seeds."""
    def v(x: Any) -> str:
        return x if isinstance(x, str) else f"{x:.4g}"

    print("\nhidden robot against the spread the report states (the profile's allowed "
          "values; target: every field inside):")
    print("field | hidden | twin | told | allowed | inside")
    for r in found[-1]:
        a, (lo, hi) = r["allowed"], r["open"]
        shown = "n/a" if a is None else (", ".join(a) if isinstance(r["hidden"], str) else
                                         f"{'(open) ' * lo}{v(a[0])} - {v(a[1])}"
                                         f"{' (open)' * hi}")
        where = " (past the searched range, on a side the data leave open)" * bool(
            r["past_range"])
        print(f"{r['field']} | {v(r['hidden'])} | {v(r['twin'])} | {r['told']} | {shown} | "
              f"{r['inside']}{where}")
    fields = [r["field"] for r in found[0]]
    tally = ", ".join(f"{n} {sum(bool(f[k]['inside']) for f in found)}/{len(found)}"
                      for k, n in enumerate(fields))
    every = sum(all(r["inside"] for r in f) for f in found)
    print(f"inside, seeds: {tally}; every field inside on {every} of {len(found)} seeds")
    alone = ", ".join(f"{n} {sum(bool(f[k]['inside_slice']) for f in found)}/{len(found)}"
                      for k, n in enumerate(fields))
    every_alone = sum(all(r["inside_slice"] for r in f) for f in found)

    def mean_width(key: str) -> str:
        return f"{np.nanmean([r[key] for f in found for r in f]):.2f}"

    print(f"the slice alone (each field moved with the others at the winner's): {alone}; "
          f"every field inside on {every_alone} of {len(found)} seeds; mean width of the "
          f"allowed values as a share of the range: {mean_width('width_slice')} alone, "
          f"{mean_width('width')} as stated")


def print_ties(rep: dict) -> None:
    """The pairs of fields the profile's pairs find tied (``--profile-pairs``), and the walks
    the profile took."""
    from simlab.calibration.profile import Profile

    if not rep.get("profile"):
        return
    prof = Profile.from_json(rep["profile"])
    walks = sum(len(f.alone) for f in prof.fields) + prof.pair_walks
    ties = "; ".join(f"{a} with {b}" for a, b in prof.ties()) or "none"
    print(f"profile: {walks} walks of {prof.transitions:,} transitions (pairs: {prof.pairs}); "
          f"tied by the data: {ties}")


def print_held(rep: dict) -> None:
    """The fields calibrate did not search whose value differs from the hidden robot's: what
    the twin holds (its defaults) and what it cannot represent."""
    from simlab.physics.motion import PrimitiveParams

    robot = PrimitiveParams(**HIDDEN)
    searched = {x["name"] for x in rep["space"]} | {"decision_latency"}
    held = {k: (getattr(robot, k), v) for k, v in rep["params"].items()
            if k not in searched and hasattr(robot, k) and getattr(robot, k) != v}
    print("not searched, hidden robot / twin: " + ", ".join(
        f"{k} {h:.4g} / {t:.4g}" if not isinstance(h, str) else f"{k} {h} / {t}"
        for k, (h, t) in held.items()))


def run_pool(root: Path, runs: list[Path], real: Path, states: Path, arena: Path,
             args: argparse.Namespace) -> dict:
    """``simlab calibrate-pool`` of the seeds' calibrations: each winner on the same fresh
    seeds, the runs within sampling of the best, the union of what they allow; pool.json."""
    out = root / "pool"
    if not (args.reuse and (out / "pool.json").is_file()):
        stdout, wall = simlab("calibrate-pool", "--runs", *runs, "--real", real, "--states",
                              states, "--arena", arena, "--seeds", 2 if args.quick else 3,
                              "--workers", args.workers, "--out", out, "--no-progress",
                              "--overwrite", log=root / "pool.log")
        print(f"\n$ simlab calibrate-pool ({wall:.0f} s)\n{stdout.strip()}")
    rep = json.loads((out / "pool.json").read_text())
    mf = rep["matched_floor"]
    print(f"pool: {len(rep['joined'])} of {len(rep['runs'])} calibrate seeds within sampling "
          f"of the best (band {rep['limit']:.4f}, score sd {rep['sigma']:.4f}); winners on "
          f"the pool's seeds: " + ", ".join(
              f"seed {r['seed']} {r['distance'] / mf:.2f}x{' (joined)' * r['joined']}"
              for r in rep["runs"]))
    t = rep.get("transfer")
    if t is not None:
        def ratio(x: float | None) -> str:
            return "never" if x is None else f"{x:.3f}"
        line = t["perfect_twin"]
        print(f"pool: policies on the real model at {t['transitions']:,} transitions, steps over "
              "the real optimum's: " + ", ".join(
                  f"seed {r['seed']} {ratio(x)}" for r, x in zip(rep["runs"], t["ratios"],
                                                                 strict=True))
              + (f"; the ensemble across the joined seeds {ratio(t['ensemble_ratio'])}"
                 if t["ensemble_runs"] else "")
              + f"; a perfect twin {ratio(line['ratio_median'])} (95 % "
              f"{ratio(line['ratio_low_2.5'])}-{ratio(line['ratio_high_97.5'])})")
    return rep


def print_pool_recovery(rep: dict) -> None:
    """The hidden robot against the pool's union of the joined seeds' allowed values."""
    from simlab.calibration.pool import OPEN_SHARE, PooledField
    from simlab.physics.motion import PrimitiveParams

    robot = PrimitiveParams(**HIDDEN)
    marks = []
    for f in rep["fields"]:
        allowed = f["allowed"]
        cat = allowed is not None and bool(allowed) and isinstance(allowed[0], str)
        field = PooledField(f["field"], cat, tuple(f["values"]), (), None if allowed is None
                            else tuple(a if cat else tuple(a) for a in allowed))
        marks.append((f["field"], field.admits(getattr(robot, f["field"]))))
    print("hidden robot against the pool's union (target: every field inside): " + ", ".join(
        f"{n} {'in' if ok else 'OUT' if ok is False else 'n/a'}" for n, ok in marks)
        + f"; every field inside: {all(ok for _, ok in marks)}")
    print(f"the union's share of each field's searched range (a field at {OPEN_SHARE} or more "
          "is left open: the statement holds it by saying little): " + ", ".join(
              f"{f['field']} {'n/a' if f.get('share') is None else format(f['share'], '.2f')}"
              for f in rep["fields"]))


#: The walk seeds of the truth check (common random numbers for every robot it walks).
TRUTH_SEEDS = (101, 102)


def _truth_walk(job: tuple[str, Path, Path, Any, int, int]) -> tuple[str, int, Any]:
    """One walk of the truth check: ``(name, seed, counts)``."""
    from simlab.base.actions import parse_action_set
    from simlab.calibration.walks import simulate_counts

    name, arena, states, params, rows, seed = job
    t = simulate_counts(arena, states, params, transitions=rows, seed=seed,
                        action_set=parse_action_set(8, "ccw-east", "fast"), start_states="all")
    return name, seed, t.counts


def hidden_in_space(rep: dict) -> dict[str, Any]:
    """The hidden robot's value of each field a calibration searched (``rep``: its
    report.json); a field the hidden robot leaves at its default, the default."""
    from simlab.physics.motion import PrimitiveParams

    default = PrimitiveParams()
    return {x["name"]: HIDDEN.get(x["name"], getattr(default, x["name"]))
            for x in rep["space"]}


def truth_check(reps: list[dict], seeds: list[int], arena: Path, states: Path,
                counts: np.ndarray, workers: int) -> None:
    """Where the search stopped against the truth, on common walk seeds: each seed's winner,
    the hidden robot's searched values in that twin (its held fields kept: the best the
    search space holds, as far as the hidden values are best there), and the hidden robot
    itself, each walked at the confirming size on :data:`TRUTH_SEEDS`; their TV distance to
    the real table (the mean over the seeds) against the matched floor."""
    from concurrent.futures import ProcessPoolExecutor
    from dataclasses import fields, replace

    from simlab.calibration.metrics import tv_distance
    from simlab.physics.motion import PrimitiveParams

    known = {f.name for f in fields(PrimitiveParams)}
    jobs = []
    for k, rep in enumerate(reps):
        twin = PrimitiveParams(**{n: v for n, v in rep["params"].items() if n in known})
        truth = replace(twin, **hidden_in_space(rep))
        rows = int(rep["confirmed"][0]["rows"]) if rep.get("confirmed") else 8037
        jobs += [(f"winner {k}", arena, states, twin, rows, s) for s in TRUTH_SEEDS]
        jobs += [(f"in space {k}", arena, states, truth, rows, s) for s in TRUTH_SEEDS]
    hidden = PrimitiveParams(**HIDDEN, decision_latency=float(reps[0]["params"]
                                                              ["decision_latency"]))
    jobs += [("hidden robot", arena, states, hidden, jobs[0][4], s) for s in TRUTH_SEEDS]
    tv: dict[str, list[float]] = {}
    with ProcessPoolExecutor(max(1, workers)) as pool:
        for name, _seed, c in pool.map(_truth_walk, jobs):
            tv.setdefault(name, []).append(tv_distance(c, counts, unvisited="max").distance)
    matched = float(reps[0]["matched_floor"]["median"])
    perfect = (reps[0].get("perfect_twin_floor") or {}).get("median")

    def cell(name: str) -> str:
        d = float(np.mean(tv[name]))
        return (f"{d:.4f} ({d / matched:.2f}x" + (f"; {d / perfect:.2f}x)" if perfect else ")"))

    print(f"\nthe search against the truth (TV, mean of walk seeds {TRUTH_SEEDS}, / plug-in "
          f"matched floor {matched:.4f}" + (f"; / perfect-twin floor {perfect:.4f}, which the "
                                             "hidden robot itself should read about 1.00x"
                                             if perfect else "")
          + f"; the same seeds for every robot): the hidden robot itself "
          f"{cell('hidden robot')}")
    print("calibrate seed | winner | the hidden values in the twin's space")
    for k, seed in enumerate(seeds):
        print(f"{seed} | {cell(f'winner {k}')} | {cell(f'in space {k}')}")


def synthetic(args: argparse.Namespace) -> None:
    """The synthetic lab (module docstring)."""
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
    if "--profile-step" not in args.calibrate_args:   # the spread the report states
        args.calibrate_args += f" --profile-step {PROFILE_STEP}"
    rows, found, reps = [], [], []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        out = root / ("cal" if args.seeds == 1 else f"cal-seed{seed}")
        rep, wall, load = run_calibrate(real_csv, states, arena, f"{info['hours']:.4f}", out,
                                        args, reuse=args.reuse, seed=seed)
        print_calibration(rep, wall, load)
        rows.append(seed_row(seed, rep, wall, load))
        print_seeds(rows)
        found.append(recovery(rep))
        print_recovery(found)
        print_ties(rep)
        print_held(rep)
        reps.append(rep)
    truth_check(reps, list(range(args.first_seed, args.first_seed + args.seeds)), arena,
                states, counts, args.workers)
    if args.seeds > 1:
        seeds = range(args.first_seed, args.first_seed + args.seeds)
        pooled = run_pool(root, [root / f"cal-seed{k}" for k in seeds], real_csv, states,
                          arena, args)
        print_pool_recovery(pooled)
        print(f"files in {root}")
        return
    compare_rate(args, lambda out, env: run_calibrate(
        real_csv, states, arena, f"{info['hours']:.4f}", out, args, reuse=args.reuse,
        env=env), root, rep, wall)
    print(f"files in {root}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--lab", choices=("isir", "synthetic"), default="isir",
                        help="the real ISIR lab (default) or the synthetic one")
    parser.add_argument("--real-lab", type=Path, default=REAL_LAB,
                        help="the real lab's data folder (default ../shared/real-lab)")
    parser.add_argument("--quick", action="store_true", help="small budgets (smoke run)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=7, help="seed of the hidden walk")
    parser.add_argument("--seeds", type=int, default=1,
                        help="calibrate seeds to run (per-seed table and spread; with more "
                             "than one the policy-data and rate steps are skipped)")
    parser.add_argument("--first-seed", type=int, default=0, help="first calibrate seed")
    parser.add_argument("--keep", type=Path, default=None, help="keep the files here")
    parser.add_argument("--reuse", action="store_true",
                        help="reuse the files already in --keep (lab, calibration, data)")
    parser.add_argument("--compare-hz", type=float, default=0.0,
                        help="also calibrate with this default physics rate (0: no)")
    parser.add_argument("--calibrate-args", default="",
                        help="extra calibrate options (quoted), e.g. '--candidates 20'; "
                             "a lone flag as "
                             "--calibrate-args=--policy-data")
    args = parser.parse_args()
    if args.lab == "isir":
        isir(args)
    else:
        synthetic(args)


if __name__ == "__main__":
    main()
