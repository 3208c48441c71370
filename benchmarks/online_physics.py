"""Online learning in physics: decisions per second against the physics step's own rate.

    python benchmarks/online_physics.py [--decisions 300] [--repeats 3] [--lab ../shared/real-lab]

For each world, one process, the same run repeated (best of ``--repeats`` after a warm-up):

* **decisions / wall s** of ``simlab.online.physics.run_physics_online`` (entropy_and_cost,
  kappa 1, simlab's protocol);
* **the floor**: decisions / s if nothing but Bullet's steps took time (the wall time spent
  inside ``World.step`` during the same runs), and the run's rate as a share of it;
* **the shares of a decision**: Bullet's steps, the agent's kernels (``meta.decide`` +
  ``meta.learn``), the discretizer (every state lookup, the 10 Hz ticks of a drive until
  the state changes included), the rest (primitive control, LIDAR scans, pose);
* **the agent's call, both ways, same run**: the kernels through their compiled entry
  points (what the loop does) against the numba dispatcher's own call (which types the
  agent's nested records at every call), per decision.

Worlds: the table (25-state lattice, 16 primitives, 0.5 s drives, truth pose) and, when the
lab folder exists (the ISIR arena's public data), the lab's twin as ``simlab online
--arena`` builds it (its map and 38 states, 8 actions counter-clockwise from East, driving
until the state changes, 2.2 cm of localization error: the last calibration's figures).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np


class _Clock:
    """Wall seconds spent in wrapped callables."""

    def __init__(self) -> None:
        self.seconds = 0.0

    def wrap(self, fn):
        def timed(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                self.seconds += time.perf_counter() - t0
        return timed


def _experts():
    from simlab.online.command import OnlineConfig

    return OnlineConfig(mdp="unused").expert_configs()


def table_lab():
    from simlab.online.experiments import lattice_states
    from simlab.online.physics import PhysicsLab, PhysicsTask
    from simlab.physics.arena import load_arena
    from simlab.physics.motion import PrimitiveParams

    arena = load_arena("table")
    return (PhysicsLab(arena, lattice_states(arena, 5), PrimitiveParams()),
            PhysicsTask((12,), (0, 24), 0))


def isir_lab(folder: Path, work: Path):
    from discretize.command import DiscretizeConfig, discretize_command
    from discretize.voronoi import load_states
    from simlab.base.actions import parse_action_set
    from simlab.online.physics import PhysicsLab, PhysicsTask
    from simlab.physics.arena import load_arena
    from simlab.physics.map_arena import ArenaFromMapConfig, arena_from_map
    from simlab.physics.motion import PrimitiveParams

    discretize_command(DiscretizeConfig(map=folder / "mymap.yaml", out=work / "states.json",
                                        centres=folder / "voronoiCenters_exp.dat",
                                        flip_y=True, progress=False))
    arena_from_map(ArenaFromMapConfig(map_yaml=folder / "mymap.yaml", out=work / "lab.toml",
                                      states=work / "states.json", flip_y=True))
    params = PrimitiveParams(mode="until_state_change", fast_speed=0.194, max_drive_time=7.0,
                             detector_margin=0.111, pose_noise_xy=0.022)
    aset = parse_action_set(8, "ccw-east", "fast")
    return (PhysicsLab(load_arena(work / "lab.toml"), load_states(work / "states.json"), params,
                       tuple(int(p) for p in aset.primitives())),
            PhysicsTask((18,), (0, 32), 0))


def bench(name: str, lab, task0, decisions: int, repeats: int) -> None:
    from simlab.data import walkers
    from simlab.online import meta, physics
    from simlab.online.physics import PhysicsTask, RunStreams, run_physics_online
    from simlab.physics.world import World

    mf, mb = _experts()
    task = PhysicsTask(task0.goal, task0.start_states, decisions)
    step, agent, states = _Clock(), _Clock(), _Clock()
    real_step, real_point = World.step, walkers.point_state_of
    real_decide, real_learn = physics._Agent.decide, physics._Agent.learn
    World.step = step.wrap(real_step)
    physics._Agent.decide = agent.wrap(real_decide)
    physics._Agent.learn = agent.wrap(real_learn)
    walkers.point_state_of = lambda d: states.wrap(real_point(d))
    rows = []
    try:
        for rep in range(repeats + 1):
            for c in (step, agent, states):
                c.seconds = 0.0
            ag = meta.make_meta_agent(mf, mb, lab.n_states, lab.n_actions, meta.Arbitration())
            run = run_physics_online(ag, lab, task, RunStreams.from_seed(
                np.random.SeedSequence(rep)))
            if rep:  # the first run compiles and warms the caches
                rows.append((run.wall_seconds, step.seconds, agent.seconds, states.seconds,
                             run.robot_seconds, run.blocked.mean()))
    finally:
        World.step, walkers.point_state_of = real_step, real_point
        physics._Agent.decide, physics._Agent.learn = real_decide, real_learn
    wall, st, ag_s, disc, robot, blocked = min(rows)  # the best run
    print(f"\n== {name}: {lab.n_states} states x {lab.n_actions} actions, {decisions} "
          f"decisions per run, best of {repeats} ==")
    print(f"decisions / wall s {decisions / wall:8.1f}   floor (Bullet's steps only) "
          f"{decisions / st:8.1f}   run / floor {st / wall:.2f}")
    print(f"shares of a decision: steps {st / wall:.1%}, agent {ag_s / wall:.1%}, "
          f"discretizer {disc / wall:.1%}, rest {(wall - st - ag_s - disc) / wall:.1%}")
    print(f"simulated s per decision {robot / decisions:.2f}, blocked {blocked:.2f}, spread of "
          f"decisions / s over runs {decisions / max(r[0] for r in rows):.1f}-"
          f"{decisions / min(r[0] for r in rows):.1f}")
    _dispatch(lab)


def _dispatch(lab) -> None:
    """The agent's two kernels per decision: compiled entry points against the dispatcher."""
    from simlab.online import meta
    from simlab.online.physics import _Agent

    mf, mb = _experts()
    ag = meta.make_meta_agent(mf, mb, lab.n_states, lab.n_actions, meta.Arbitration())
    rng = np.random.default_rng(0)
    calls = _Agent(ag, rng)
    S, n = lab.n_states, 400
    timings = {}
    for how, decide, learn in (
            ("entry points", calls.decide, calls.learn),
            ("dispatcher", lambda s: meta.decide(ag, s, rng),
             lambda s, a, r, s2: meta.learn(ag, s, a, r, s2))):
        decide(0)
        t0 = time.perf_counter()
        for i in range(n):
            a = int(decide(i % S)[0])
            learn(i % S, a, 0.0, (i + 1) % S)
        timings[how] = (time.perf_counter() - t0) / n * 1e6
    print(f"agent per decision: entry points {timings['entry points']:.0f} us, dispatcher "
          f"{timings['dispatcher']:.0f} us ({timings['dispatcher'] / timings['entry points']:.0f}x)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--decisions", type=int, default=300)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--lab", type=Path, default=Path("../shared/real-lab"))
    args = parser.parse_args()
    import os

    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    bench("table", *table_lab(), args.decisions, args.repeats)
    if (args.lab / "realisticNavWorld.json").is_file():
        with tempfile.TemporaryDirectory() as work:
            bench("ISIR twin", *isir_lab(args.lab, Path(work)), args.decisions, args.repeats)
    else:
        print(f"\n(no lab folder at {args.lab}: the ISIR twin is skipped)")


if __name__ == "__main__":
    main()
