"""How well does one screening walk tell candidates apart, and what makes it noisy?

The search ranks its first rung by one small walk per candidate (a quarter of the real
transitions) and its sampler learns from those scores. This script takes a kept calibration
of the synthetic lab (``benchmarks/calibrate_twin.py --lab synthetic --keep DIR``: a
``cal-seedN`` folder beside the lab's ``real.csv``, ``states.json`` and ``lab.toml``) and
walks, on the run's own screening seed and ``--walks - 1`` fresh ones, at the screening size
(or ``--size``), common random numbers for all: the hidden robot's values in the twin's space
(its searched fields at the hidden values, the held ones at calibrate's), the run's winner
and its ``--others`` best screening candidates (3 by default). It prints, per
point, the mean and spread of the distance, of each signature term's share of the penalty,
and of the score; then the paired difference of every point against the hidden values, for
the distance alone and for the score (mean, walk-to-walk sd, t over the walks); at the
screening size, where the hidden values' score on the run's own screening walk ranks among
the run's candidates.

Measured (2-core VM, 2026-12-07, calibrate seed 13 of the synthetic lab, 10 walks of 1,340
transitions, 246 s; ``--size 8037 --walks 4 --others 0``: the hidden values and the winner,
213 s):
at the screening size the paired sd of two candidates' scores is 0.024-0.040, of their
distances 0.013-0.017: the signature penalty more than doubles a screening walk's noise (its
entropy term most: sd of the gap 0.03 bits against a tolerance of 0.05). The hidden values
are nearer in distance than every other point (+0.005 to +0.013, t 1.0-2.9 over ten walks)
but not in score (-0.001 to +0.021, t -0.1 to 1.7). At the confirming size they beat the
winner by the score (+0.015, paired sd 0.007, t 4.1 over four walks) and by the distance
(+0.016, t 7.6): the objective prefers the truth, the screening walks barely see it. Yet
they would keep it: on each run's own screening walk (``--walks 1 --others 0``, seeds 11, 12
and 13 of the synthetic lab) the hidden values rank 4th, 3rd and 11th of 49 among that run's
candidates, inside the best 16 the search promotes. What the search misses is a proposal
near them: the sampler never puts a candidate in their basin.

**Lost: the penalty ramped with the walk's size.** Charging a walk
``weight * min(1, rows / confirming rows)`` (a sixth at the screening walks, two thirds at the
second rung, in full at the confirmation) keeps the screening ranking on the distance. On the
4-field kinematic lab of ``calibrate_samplers.py`` it won (20 seeds: median 1.18x against 1.22x
the matched floor, 14 seeds better and 4 worse, Wilcoxon p 0.025). On the synthetic physics lab
it lost (seeds 11-13, 2026-12-07, without the profile, 684-756 s a seed at load 2.0-2.5): on
the truth seeds its winners walk 1.29/1.31/1.30x against the default's 1.26/1.35/1.27x (the
hidden values 1.16x), all three stay more than the robot (0.220-0.225 against 0.203; the
default's 0.180/0.215/0.207) with less entropy (1.22-1.25 against 1.27 bits; the default's
1.26-1.28), and the twins' policies at the recommended data take 1.105/1.051/1.015x a perfect
twin's steps against the default's 1.029/1.041/1.023x. The penalty at the screening walks is
noisy but steers the sampler away from twins more certain than the robot, as the objective's
module docstring says the plain distance would not: it stays in full at every size.

Run: ``python benchmarks/calibrate_screen_noise.py --run DIR/cal-seed13 [--walks 10]
[--size N] [--others 3] [--workers 2]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import fields
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

#: Best screening candidates walked besides the hidden values and the winner.
OTHERS = 3


def points(rep: dict, space, others: int) -> dict[str, np.ndarray]:
    """The walked points in the unit cube, by name."""
    from calibrate_twin import hidden_in_space

    cands = rep["candidates"]
    out = {"hidden values": space.unit(hidden_in_space(rep)),
           f"winner #{rep['best_candidate']}": space.unit(cands[rep["best_candidate"]]
                                                          ["values"])}
    taken = {rep["best_candidate"]}
    for c in sorted(cands, key=lambda c: (c["score"], c["index"])):
        if len(out) == 2 + others:
            break
        if c["index"] not in taken:
            taken.add(c["index"])
            out[f"screening #{c['index']}"] = space.unit(c["values"])
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--run", type=Path, required=True,
                        help="a calibrate run of the synthetic lab (its report.json)")
    parser.add_argument("--walks", type=int, default=10)
    parser.add_argument("--size", type=int, default=None,
                        help="transitions a walk (default: the run's screening size)")
    parser.add_argument("--others", type=int, default=OTHERS)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()

    from simlab.base.actions import parse_action_set
    from simlab.calibration.command import read_real_table
    from simlab.calibration.config import CalibrationConfig
    from simlab.calibration.objective import TOLERANCES
    from simlab.calibration.search import evaluate_points, walk_context
    from simlab.calibration.space import ParameterSpace
    from simlab.calibration.stages import prepare_calibration
    from simlab.calibration.walks import WalkRunner
    from simlab.physics.motion import PrimitiveParams

    rep = json.loads((args.run / "report.json").read_text())
    lab = args.run.parent
    cfg = CalibrationConfig(**{**rep["config"], "workers": args.workers, "progress": False})
    screen = int(rep["budgets"]["screen_transitions"])
    size = args.size or screen
    aset = parse_action_set(8, "ccw-east", "fast")
    real = read_real_table(lab / "real.csv", 38, aset, None)
    space = ParameterSpace.from_json(rep["space"])
    known = {f.name for f in fields(PrimitiveParams)}
    base = PrimitiveParams(**{n: v for n, v in rep["base_params"].items() if n in known})
    setup = prepare_calibration(real, lab / "lab.toml", lab / "states.json", space, base, cfg)
    ctx = walk_context(setup.real, setup.arena, setup.disc, setup.space, setup.base, cfg,
                       cfg.seed, (None, size), setup.reference())
    pts = points(rep, space, args.others)
    names = list(pts)
    seeds = [cfg.seed] + [cfg.seed + 500 + k for k in range(args.walks - 1)]
    terms = ("self_share", "entropy", "regions")
    rows: dict[str, list[list[float]]] = {n: [] for n in names}
    runner = WalkRunner(args.workers, None)
    t0 = time.perf_counter()
    try:
        for s in seeds:
            for n, c in zip(names, evaluate_points(runner, [pts[n] for n in names], "noise",
                                                   0, ctx, seeds=[s] * len(names),
                                                   budget=(None, size)), strict=True):
                g = c.gap.gaps() if c.gap is not None else dict.fromkeys(terms, np.nan)
                rows[n].append([c.distance, *(cfg.signature_weight
                                              * (g[t] / TOLERANCES[t]) ** 2 for t in terms),
                                c.score])
            print(f"walk seed {s} done ({time.perf_counter() - t0:.0f} s)", flush=True)
    finally:
        runner.close()
    print(f"\n{args.run}: {len(seeds)} walks of {size:,} transitions a point, common seeds "
          f"{seeds[0]}, {seeds[1] if len(seeds) > 1 else ''}...; mean (sd over the walks)")
    print("point | distance | penalty: self share | entropy | regions | score")
    arr = {n: np.array(v) for n, v in rows.items()}
    sd = (lambda x: float(np.std(x, ddof=1))) if len(seeds) > 1 else (lambda x: float("nan"))
    for n, a in arr.items():
        print(f"{n} | " + " | ".join(f"{a[:, j].mean():.4f} ({sd(a[:, j]):.4f})"
                                     for j in range(5)))
    h = arr[names[0]]
    print("\npaired against the hidden values (point - hidden): mean, walk-to-walk sd, t")
    print("point | distance | score")
    for n in names[1:]:
        cells = []
        for j in (0, 4):
            d = arr[n][:, j] - h[:, j]
            t = d.mean() / sd(d) * np.sqrt(len(d))
            cells.append(f"{d.mean():+.4f} (sd {sd(d):.4f}, t {t:.1f})")
        print(f"{n} | " + " | ".join(cells))
    if size == screen:
        # the first walk seed is the run's own screening seed: its candidates' scores are
        # on the same walks, so the hidden values can be ranked among them
        own = h[0, 4]
        scores = sorted(c["score"] for c in rep["candidates"])
        rank = 1 + sum(x < own for x in scores)
        promoted = len(rep["search"]["rungs"][1]["candidates"]) if len(
            rep["search"]["rungs"]) > 1 else len(scores)
        print(f"on the run's own screening walk the hidden values score {own:.4f}: "
              f"{rank} of {len(scores) + 1} among its candidates (the best {promoted} were "
              f"promoted)")
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
