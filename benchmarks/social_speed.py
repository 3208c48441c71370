"""Social walk speed vs navigation walk speed, in the same run.

Both walks run headless on the ``table`` arena, one process, uniform random actions:

* **social**: :func:`simlab.social.walk.social_walk` (the 22 social actions, the human,
  perception with ray tests, GO_TO_HUMAN's drives; restarts every 40 decisions);
* **navigation**: :class:`simlab.data.walkers.PhysicsWalker` (``simlab collect``'s physics
  walk, the 16 primitives, true pose).

Prints, per walk, decisions, simulated hours (stepped time plus the decision latency or
the signal time, as each walk's clock counts it), wall and CPU seconds, simulated hours per
wall second and per CPU second, and the social / navigation ratio. The machine is shared:
the CPU figures are the load-independent ones; run 2-3 times and report best and spread.

Run: ``python benchmarks/social_speed.py [--steps 600] [--seed 0] [--repeat 1]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def social(steps: int, seed: int) -> tuple[float, float, float]:
    """(simulated s, wall s, CPU s) of a social walk of ``steps`` decisions."""
    from simlab.social.walk import WalkConfig, social_walk

    w0, c0 = time.perf_counter(), time.process_time()
    walks = social_walk(WalkConfig(steps=steps, seed=seed))
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    return float(sum(w.duration.sum() for w in walks)), wall, cpu


def navigation(steps: int, seed: int) -> tuple[float, float, float]:
    """(simulated s, wall s, CPU s) of the navigation walk of ``steps`` primitives."""
    from simlab.data.walkers import PhysicsWalker
    from simlab.physics.motion import N_ACTIONS, PrimitiveParams

    params = PrimitiveParams()
    act_seq, noise_seq, src_seq = np.random.SeedSequence(seed).spawn(3)
    act, noise = np.random.default_rng(act_seq), np.random.default_rng(noise_seq)
    w0, c0 = time.perf_counter(), time.process_time()
    walker = PhysicsWalker("table", params, "truth", {})
    try:
        walker.reset(None, np.random.default_rng(src_seq))
        sim = 0.0
        for _ in range(steps):
            out = walker.step(int(act.integers(0, N_ACTIONS)), noise)
            sim += out.duration + walker.decision_latency
    finally:
        walker.close()
    return sim, time.perf_counter() - w0, time.process_time() - c0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=600, help="decisions per walk")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeat", type=int, default=1, help="timed repetitions of each walk")
    args = parser.parse_args()
    rates: dict[str, tuple[float, float]] = {}
    for name, fn in (("social", social), ("navigation", navigation)):
        best = None
        for _ in range(args.repeat):
            sim, wall, cpu = fn(args.steps, args.seed)
            if best is None or cpu < best[2]:
                best = (sim, wall, cpu)
        sim, wall, cpu = best  # type: ignore[misc]
        rates[name] = (sim / 3600 / wall, sim / 3600 / cpu)
        print(f"{name:>10}: {args.steps} decisions, {sim / 3600:.3f} simulated h, "
              f"wall {wall:.1f} s, CPU {cpu:.1f} s -> {rates[name][0]:.3f} sim h / wall s, "
              f"{rates[name][1]:.3f} sim h / CPU s")
    print(f"ratio social / navigation: {rates['social'][0] / rates['navigation'][0]:.2f} "
          f"(wall), {rates['social'][1] / rates['navigation'][1]:.2f} (CPU)")


if __name__ == "__main__":
    main()
