"""Physics speed: bare stepping vs the full primitive loop, on one core.

(a) ``stepSimulation`` of the table arena with the robot driving a circle (motors on, no
    Python control), steps/s and real-time factor;
(a') ``stepSimulation`` of exactly the motions of (b), replayed from a recorded schedule of
    wheel commands with no Python control, LIDAR or obstacle check: the same contacts, so
    b/a' is the share of the loop's time spent in physics (b/a also carries the difference
    between a circle and the primitives' mix of turning, driving and resting);
(b) the full loop of uniformly random motion primitives with their obstacle checks
    (rotation, LIDAR cone scan, drive, brake), real-time factor over the *stepped*
    simulated time, and the same including the idle decision latency (dataset view);
and the ratio b/a. Each figure is the best of ``--repeats`` runs (the machine is shared).
Targets: (b) >= 300x real time per core, b/a >= 0.85.

    python benchmarks/physics_speed.py [--seconds 60] [--primitives 300] [--repeats 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pybullet

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


def same_motions(n: int, seed: int, arena: str = "table",
                 hz: float | None = None) -> tuple[float, float]:
    """Bare stepping of exactly the motions of the primitive loop, without its Python
    (in ``arena`` at ``hz``, None: the default rate).

    The loop of ``primitives(n, seed)`` is run once while recording its wheel-motor
    commands and the number of physics steps between them; a fresh world then replays
    that schedule with nothing but ``setJointMotorControlArray`` and ``stepSimulation``
    (no control ticks, no LIDAR, no obstacle checks). Its rate is the ceiling the loop
    could reach on the same contacts (turning in place steps ~6 % slower than the
    circle of (a); resting ~12 % faster).
    """
    params = PrimitiveParams()
    schedule: list[tuple[int, list[float], list[float]]] = []
    with World(arena, physics_hz=hz) as world:
        drive = world.drive
        set_motors, step = drive._set_motors, world.step
        pending = [0]

        def record_motors(body, joints, mode, targetVelocities, forces):
            schedule.append((pending[0], list(targetVelocities), list(forces)))
            pending[0] = 0
            set_motors(body, joints, mode, targetVelocities=targetVelocities, forces=forces)

        def record_step(k: int = 1) -> None:
            pending[0] += k
            step(k)

        rng = np.random.default_rng(seed)
        execute_primitive(world, 0, rng, params)  # the warm-up of primitives()
        drive._set_motors, world.step = record_motors, record_step
        for _ in range(n):
            execute_primitive(world, int(rng.integers(16)), rng, params)
        schedule.append((pending[0], [], []))
        end = world.pose()
        joints = drive._joints
    total = sum(k for k, _, _ in schedule)
    with World(arena, physics_hz=hz) as world:  # the same start and warm-up as recorded
        execute_primitive(world, 0, np.random.default_rng(seed), params)
        c, body = world.client, world.body
        set_motors, stepper = c.setJointMotorControlArray, c.stepSimulation
        mode = pybullet.VELOCITY_CONTROL
        # schedule[i] = (steps before command i, command i); the last entry has no command
        t = time.perf_counter()
        for k, target, forces in schedule:
            for _ in range(k):
                stepper()
            if target:
                set_motors(body, joints, mode, targetVelocities=target, forces=forces)
        wall = time.perf_counter() - t
        # PyBullet is deterministic: the replay must end where the loop did.
        assert np.allclose(world.pose(), end, atol=1e-9), (world.pose(), end)
        hz = world.physics_hz
    return total / wall, total / hz / wall


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
    a2 = max((same_motions(args.primitives, s) for s in range(args.repeats)), key=lambda r: r[1])
    b = max((primitives(args.primitives, s) for s in range(args.repeats)), key=lambda r: r[0])
    print(f"(a) bare stepSimulation, robot driving a circle: {a[0]:,.0f} steps/s = "
          f"{a[1]:.0f}x real time")
    print(f"(a') bare stepSimulation of the primitive loop's own motions (replayed schedule): "
          f"{a2[0]:,.0f} steps/s = {a2[1]:.0f}x real time")
    print(f"(b) primitive loop with obstacle checks: {b[0]:.0f}x real time (stepped time; "
          f"{b[1]:.0f}x counting the {PrimitiveParams().decision_latency} s idle latency; "
          f"mean primitive {b[2]:.2f} s)")
    print(f"b/a = {b[0] / a[1]:.2f}, b/a' = {b[0] / a2[1]:.2f}   "
          "(targets: b >= 300x per core, b/a >= 0.85)")


if __name__ == "__main__":
    main()
