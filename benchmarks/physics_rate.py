"""CPU cost of a simulated second at other physics rates than the default 200 Hz.

A lower rate takes fewer steps per simulated second, but the question is what the job pays:
for each rate this prints, on one core, best of ``--repeats`` runs interleaved across the
rates (the machine's speed drifts from minute to minute):

* bare: ``stepSimulation`` of the robot driving a circle on the table, CPU microseconds per
  step and CPU seconds per simulated second;
* primitives: ``--primitives`` uniformly random motion primitives from the table's start
  (the dataset's workload: turns, obstacle checks, drives, brakes), CPU seconds per
  simulated second and simulated seconds per primitive (a primitive brakes until the robot
  is at rest, which takes longer at some rates);

each with its ratio to the 200 Hz run. Each rate steps with the solver settings it needs
(:func:`simlab.physics.rate.settings_for`): a coarse step needs more iterations, so a step
is not a fixed cost (``benchmarks/step_size.py`` measures which settings each rate needs and
what its transitions cost).

    python benchmarks/physics_rate.py [--rates 250,200,180,150,120] [--primitives 400]
                                      [--repeats 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from simlab.physics.motion import PrimitiveParams, execute_primitive
from simlab.physics.world import World


def bare(hz: float, seconds: float = 20.0) -> float:
    """CPU seconds per bare step (the robot driving a circle)."""
    with World("table", physics_hz=hz) as world:
        world.reset((0.0, -0.3, 0.0))
        world.drive.command(0.15, 0.5)  # a 0.3 m circle inside the table
        world.step(round(hz))
        n = round(seconds * hz)
        step = world.client.stepSimulation
        t = time.process_time()
        for _ in range(n):
            step()
        return (time.process_time() - t) / n


def primitives(hz: float, n: int, seed: int = 7) -> tuple[float, float]:
    """(CPU seconds, simulated seconds) of ``n`` random primitives."""
    rng = np.random.default_rng(seed)
    params = PrimitiveParams()
    with World("table", physics_hz=hz) as world:
        t, sim = time.process_time(), 0.0
        for _ in range(n):
            sim += execute_primitive(world, int(rng.integers(16)), rng, params).duration
        return time.process_time() - t, sim


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rates", default="250,200,180,150,120", help="physics rates (Hz)")
    ap.add_argument("--primitives", type=int, default=400, help="random primitives per run")
    ap.add_argument("--repeats", type=int, default=3, help="runs per rate (best kept)")
    args = ap.parse_args()
    rates = [float(r) for r in args.rates.split(",")]
    if 200.0 not in rates:
        rates.append(200.0)
    step_cpu: dict[float, float] = {}
    prim: dict[float, tuple[float, float]] = {}
    for _ in range(args.repeats):
        for hz in rates:
            step_cpu[hz] = min(step_cpu.get(hz, np.inf), bare(hz))
            cpu, sim = primitives(hz, args.primitives)
            if hz not in prim or cpu < prim[hz][0]:
                prim[hz] = (cpu, sim)
    ref_bare = step_cpu[200.0] * 200.0
    ref_prim = prim[200.0][0] / prim[200.0][1]
    print(f"{'rate Hz':>8} {'us/step':>8} {'bare CPU/sim s':>15} {'x 200 Hz':>9} "
          f"{'prim CPU/sim s':>15} {'x 200 Hz':>9} {'sim s/primitive':>16}")
    for hz in sorted(rates, reverse=True):
        b = step_cpu[hz] * hz
        cpu, sim = prim[hz]
        print(f"{hz:8.0f} {step_cpu[hz] * 1e6:8.1f} {b:15.4f} {b / ref_bare:9.2f} "
              f"{cpu / sim:15.4f} {cpu / sim / ref_prim:9.2f} {sim / args.primitives:16.3f}")


if __name__ == "__main__":
    main()
