"""``simlab calibrate-pool``: read several calibrations of one lab together.

The options are the fields of :class:`simlab.calibration.pool.PoolConfig`.
"""

from __future__ import annotations

import argparse
import math

HELP = ("pool calibrations of one lab made with different seeds: their winners on common "
        "fresh walks, the basins within sampling of the best, what the data allow across them")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from simlab.calibration.pool import PoolConfig

    PoolConfig.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from simlab.calibration.pool import ONE_BASIN, PoolConfig, pool_command

    done = pool_command(PoolConfig.from_args(args))
    res = done.result
    mean = res.distances.mean(axis=1)
    t = res.transfer
    for i, r in enumerate(res.runs):
        mark = "winner" if i == res.best else ("joined" if i in res.joined else "left out")
        steps = "" if t is None else (f", policies {t.ratios[i]:.3f}x the real optimum's steps"
                                      if math.isfinite(t.ratios[i]) else
                                      ", a policy never arrives on the real model")
        print(f"{r.path} (seed {r.seed}): distance {mean[i]:.4f} "
              f"({mean[i] / res.matched_floor:.2f}x the matched floor"
              + (f", {mean[i] / res.perfect_floor:.2f}x a twin equal to the robot"
                 if res.perfect_floor > 0 else "") + "), score "
              f"{res.gaps[i]:+.4f} against the best{steps}: {mark}")
    print(f"{len(res.joined)} of {len(res.runs)} runs within sampling of the best (band "
          f"{res.limit:.4f}); pool.md: what the data allow across them, field by field")
    if len(res.joined) == 1:
        print(ONE_BASIN.strip())
    if res.left_open:
        print("left open across them (the data do not tell these fields): "
              + ", ".join(res.left_open))
    if t is not None:
        e = t.ensemble_ratio
        ens = "" if e is None else "; the ensemble across the joined runs " + (
            f"{e:.3f}x" if math.isfinite(e) else "never arrives")
        print(f"policies on the real model at {t.transitions:,} transitions: a perfect twin "
              f"{t.perfect.median:.3f}x the real optimum's steps{ens}")
    if res.contradictions:
        common = res.common_contradictions
        print("(s, a) pairs every winner contradicts beyond sampling (check the map there): "
              + (", ".join(f"{s} a{a}" for s, a in common) if common else "none")
              + " (pool.md: each run's)")
    print("wrote " + ", ".join(str(p) for p in done.files.values()))
    return 0
