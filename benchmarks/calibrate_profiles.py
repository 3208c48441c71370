"""What can the real table tell? Each searched field moved alone from a calibrated twin, on the
ISIR lab.

From a twin (``--primitives``, a ``primitives.toml`` of ``simlab calibrate`` on the ISIR lab),
every field of calibrate's default space is moved alone to ``--step`` of its searched range
below and above its calibrated value (clipped to the range), and each point walks
``--transitions`` from every state on the same seed (common random numbers: the walks differ
by the field, not by their luck). For each move the benchmark prints the change of the TV
distance and of calibrate's default score (distance plus the signature penalty), beside the
yardstick of sampling: the same twin on ``--seeds`` other seeds (the spread of its score from
walk to walk). A field whose moves change the score by less than 2.77 times that spread (the 95 %
half-width of a difference of two walks) is one the table cannot tell at this size of walk:
calibrate's value for it is the search's luck, not a measurement. The moves and the verdict
are :mod:`simlab.calibration.profile`'s (``simlab calibrate --profile-step`` runs the same
from its winner). With ``--pairs`` the told fields are then moved two at a time too
(``--profile-pairs``: both diagonals, the same step and seed), and the benchmark prints, per
field, the values the data allow from the slice alone and with the pairs, and the pairs of
fields the table ties (each told alone, not together).

Run: ``python benchmarks/calibrate_profiles.py --primitives CAL/primitives.toml
[--transitions 8012] [--step 0.25] [--seeds 2] [--workers 2] [--pairs]``.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
import warnings
from pathlib import Path

REAL_LAB = Path(__file__).resolve().parents[2] / "shared" / "real-lab"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--primitives", type=Path, required=True,
                        help="a calibrated primitives.toml of the ISIR lab")
    parser.add_argument("--real-lab", type=Path, default=REAL_LAB)
    parser.add_argument("--transitions", type=int, default=8012)
    parser.add_argument("--step", type=float, default=0.25,
                        help="move of each field, as a share of its searched range")
    parser.add_argument("--seeds", type=int, default=2, help="other seeds of the twin")
    parser.add_argument("--seed", type=int, default=100)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--pairs", action="store_true",
                        help="also move the told fields in pairs (calibrate's --profile-pairs)")
    args = parser.parse_args()
    if not (args.real_lab / "mymap.yaml").is_file():
        raise SystemExit(f"calibrate_profiles.py: error: no ISIR lab data in {args.real_lab}")

    from walk_scheduling import isir_lab

    from simlab.base.actions import parse_action_set
    from simlab.calibration.config import CalibrationConfig, RealTable
    from simlab.calibration.profile import moves, profile_stage
    from simlab.calibration.report import _allowed
    from simlab.calibration.search import evaluate_points, walk_context
    from simlab.calibration.stages import prepare_calibration
    from simlab.calibration.walks import WalkRunner
    from simlab.data.counts import load_counts
    from simlab.physics.motion import PrimitiveParams

    aset = parse_action_set(8, "ccw-east", "fast")
    twin = PrimitiveParams.from_toml(args.primitives)
    with tempfile.TemporaryDirectory(prefix="simlab-profiles-") as tmp, \
            warnings.catch_warnings():
        warnings.simplefilter("ignore")
        arena, states, _name = isir_lab(Path(tmp), args.real_lab)
        counts = load_counts(args.real_lab / "realisticNavWorld.json", n_actions=8).counts
        config = CalibrationConfig(progress=False, workers=args.workers)
        setup = prepare_calibration(RealTable(counts, aset, hours=13.0), arena, states, None,
                                    None, config)
        real = setup.real
        ref = setup.reference()
        space = setup.space
        ctx = walk_context(real, setup.arena, setup.disc, space, twin, config, args.seed,
                           reference=ref)
        budget = (None, args.transitions)
        u0 = space.unit({n: getattr(twin, n) for n in space.names})
        n_walks = args.seeds + 1 + len(moves(space, u0, args.step))
        print(f"ISIR lab, {n_walks} walks of {args.transitions:,} transitions on "
              f"{args.workers} workers (load {os.getloadavg()[0]:.1f})", flush=True)
        t0 = time.perf_counter()
        runner = WalkRunner(args.workers)
        try:
            walks = evaluate_points(runner, [u0] * (args.seeds + 1), "twin", 0, ctx,
                                    seeds=[args.seed + k for k in range(args.seeds + 1)],
                                    budget=budget)
            prof = profile_stage(runner, walks[0], walks, ctx, budget, args.step, args.pairs)
        finally:
            runner.close()
        wall = time.perf_counter() - t0
    print(f"the twin: TV {prof.distance:.4f}, score {prof.score:.4f} on seed {prof.seed}; "
          f"on {args.seeds} other seeds " + ", ".join(f"{w.score:.4f}" for w in walks[1:])
          + f" (score's spread from walk to walk {prof.sigma:.4f}; told beyond "
          f"{prof.band:.2f} x that)")
    print(f"field | calibrated | moved to: TV change / score change | told at "
          f"{args.transitions:,}?")
    for f in prof.fields:
        text = "; ".join(f"{m.value:.4g}: {m.distance_change:+.4f} / {m.score_change:+.4f}"
                         for m in f.alone)
        print(f"{f.name} | {f.value:.4g} | {text} | "
              f"{'yes' if f.told else 'no: within sampling'}")
    if args.pairs:
        limit = prof.limit
        print("\nfield | values the data allow: the slice alone | with the pairs | pair "
              "points within the band")
        for spec, f in zip(space.specs, prof.fields, strict=True):
            s = f.sliced(spec, limit)
            within = "; ".join(f"{m.value:.4g} with {m.partner} {m.partner_value:.4g}: "
                               f"{m.score_change:+.4f}" for m in f.moves
                               if m.partner is not None and m.score_change <= limit)
            print(f"{f.name} | {_allowed(s.allowed, s.open)} | {_allowed(f.allowed, f.open)} "
                  f"| {within or 'none'}")
        print(f"{prof.pair_walks} pair walks; tied by the data: "
              + ("; ".join(f"{a} with {b}" for a, b in prof.ties()) or "none"))
    print(f"{wall:.0f} s of walks")


if __name__ == "__main__":
    main()
