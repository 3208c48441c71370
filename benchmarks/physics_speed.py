"""Physics speed: bare stepping vs the full primitive loop, on one core.

(a) ``stepSimulation`` of the table arena with the robot driving a circle (motors on, no
    Python control), steps/s and real-time factor;
(b) the full loop of uniformly random motion primitives with their obstacle checks
    (rotation, LIDAR cone scan, drive, brake), real-time factor over the *stepped*
    simulated time, and the same including the idle decision latency (dataset view);
and the ratio b/a. Each figure is the best of ``--repeats`` runs (the machine is shared).
Targets (issue 2): (b) >= 300x real time per core, b/a >= 0.85.

    python benchmarks/physics_speed.py [--seconds 60] [--primitives 300] [--repeats 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from simlab.physics.motion import PrimitiveParams, execute_primitive
from simlab.physics.world import World


def bare(seconds: float) -> tuple[float, float]:
    with World("table") as world:
        world.reset((0.0, -0.3, 0.0))
        world.drive.command(0.15, 0.5)  # a 0.3 m circle inside the table
        world.step(round(world.physics_hz))
        n = round(seconds * world.physics_hz)
        step = world.client.stepSimulation
        t = time.perf_counter()
        for _ in range(n):
            step()
        wall = time.perf_counter() - t
        return n / wall, seconds / wall


def primitives(n: int, seed: int) -> tuple[float, float, float]:
    params = PrimitiveParams()
    rng = np.random.default_rng(seed)
    with World("table") as world:
        execute_primitive(world, 0, rng, params)  # warm-up
        stepped = 0.0
        t = time.perf_counter()
        for _ in range(n):
            stepped += execute_primitive(world, int(rng.integers(16)), rng, params).duration
        wall = time.perf_counter() - t
    return stepped / wall, (stepped + n * params.decision_latency) / wall, stepped / n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0, help="simulated seconds for (a)")
    ap.add_argument("--primitives", type=int, default=300, help="primitives for (b)")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    a = max((bare(args.seconds) for _ in range(args.repeats)), key=lambda r: r[1])
    b = max((primitives(args.primitives, s) for s in range(args.repeats)), key=lambda r: r[0])
    print(f"(a) bare stepSimulation, robot driving: {a[0]:,.0f} steps/s = {a[1]:.0f}x real time")
    print(f"(b) primitive loop with obstacle checks: {b[0]:.0f}x real time (stepped time; "
          f"{b[1]:.0f}x counting the {PrimitiveParams().decision_latency} s idle latency; "
          f"mean primitive {b[2]:.2f} s)")
    print(f"b/a = {b[0] / a[1]:.2f}   (targets: b >= 300x per core, b/a >= 0.85)")


if __name__ == "__main__":
    main()
