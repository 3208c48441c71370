"""Online learning speed: decisions per second on an empirical MDP and in physics.

    python benchmarks/online_speed.py [--decisions 3200] [--physics-decisions 150] [--repeats 3]

1. **Empirical MDP** (the 38-state, 8-action model of ``simlab.online.synthetic``, goal 18,
   starts 0 and 32): decisions per wall second of the fused loop (``simlab.online.loop``)
   for MB alone, MF alone and entropy_and_cost (kappa 1), and of the same agent steps
   called once per decision from Python (``meta.decide`` / ``meta.learn``), in the same run.
2. **Physics** (table arena, 25-state lattice, 16 primitives, truth pose): decisions per
   wall second of the online meta-controlled agent (``simlab.online.physics``) against
   the replay's decision step measured in the same run and world: the same
   ``DecisionDriver`` driving a frozen greedy Q-table (what ``simlab replay`` does per
   decision, without its recorder and video).

   The physics part runs at the default physics rate and, in turn with it (repeat by
   repeat), at ``--compare-hz`` (default 200, the rate before it was a setting; 0: none):
   the lab's world is built at that rate (``PhysicsLab.physics_hz``).

Each figure is the best of ``--repeats`` runs (the machine is shared; the spread is
printed), and the median; the load average is printed. Numba compilation is paid before
the timing (one warm-up run).
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def _experts():
    from simlab.online.command import MB_DEFAULTS, MF_DEFAULTS, _expert_config

    return (_expert_config("q-softmax", MF_DEFAULTS, None, "mf"),
            _expert_config("sliding-window", MB_DEFAULTS, None, "mb"))


def _best(values: list[float]) -> str:
    return f"best {max(values):12.0f}  spread {min(values):.0f}-{max(values):.0f}"


def bench_mdp(decisions: int, repeats: int) -> None:
    from simlab.data.estimate import empirical_mdp
    from simlab.online import meta
    from simlab.online.loop import run_online
    from simlab.online.synthetic import corridor_counts
    from simlab.online.task import OnlineTask

    T = empirical_mdp(corridor_counts(np.random.default_rng(0))).T
    task = OnlineTask(goal=(18,), start_states=(0, 32)).compile(T)
    mf, mb = _experts()
    print(f"\n== empirical MDP, 38 states x 8 actions, {decisions} decisions per run "
          f"(decisions / wall s, best of {repeats}) ==")
    for crit in ("mf", "mb", "entropy_and_cost"):
        fused, python = [], []
        for rep in range(repeats + 1):
            ag = meta.make_meta_agent(mf, mb, 38, 8, meta.Arbitration(criterion=crit))
            t0 = time.perf_counter()
            log = run_online(ag, task, decisions, np.random.default_rng(rep),
                             np.random.default_rng(100 + rep))
            if rep:
                fused.append(decisions / (time.perf_counter() - t0))
            ag = meta.make_meta_agent(mf, mb, 38, 8, meta.Arbitration(criterion=crit))
            env, arng = np.random.default_rng(rep), np.random.default_rng(100 + rep)
            from simlab.agents.kernels import sample_from_cdf

            s = sample_from_cdf(task.start_cdf, env)
            t0 = time.perf_counter()
            for _ in range(decisions):
                a, *_ = meta.decide(ag, s, arng)
                s2 = sample_from_cdf(task.cdf[0, s, a], env)
                r = task.reward_next[0, s2]
                meta.learn(ag, s, a, r, s2)
                s = sample_from_cdf(task.start_cdf, env) if r > 0 else s2
            if rep:
                python.append(decisions / (time.perf_counter() - t0))
        print(f"{crit:17s} fused {_best(fused)} | per-call from Python {_best(python)} | "
              f"fused/python {max(fused) / max(python):.1f} | reward {log.reward.sum():.0f}, "
              f"MB share {log.expert.mean():.2f}")


def _physics_run(lab, rep: int, decisions: int, mf, mb) -> tuple[float, ...]:
    """(online decisions/s, replay-step decisions/s, their stepped robot-s per wall s) of
    one repeat on ``lab`` (a :class:`~simlab.online.physics.PhysicsLab` at its rate)."""
    from simlab.online import meta
    from simlab.online.physics import PhysicsTask, RunStreams, run_physics_online
    from simlab.physics.driver import DecisionDriver

    ag = meta.make_meta_agent(mf, mb, 25, 16, meta.Arbitration(criterion="entropy_and_cost"))
    t0 = time.perf_counter()
    run = run_physics_online(ag, lab, PhysicsTask((12,), (0, 24), decisions),
                             RunStreams.from_seed(np.random.SeedSequence(rep)))
    wall = time.perf_counter() - t0
    Q = ag.mf.Q.copy()  # a frozen table for the replay-style loop
    walker = lab.walker("truth")
    try:
        world = walker.world
        disc = lab.discretizer
        driver = DecisionDriver(world, lab.params, state_of=lambda p: int(
            disc.state_of(np.asarray(p[:2], dtype=float)[None])[0]))
        rng = np.random.default_rng(rep + 3)
        t_robot = world.time
        t1 = time.perf_counter()
        greedy = Q.argmax(axis=1)
        for _ in range(decisions):
            driver.step(lambda _pose, s, g=greedy: int(g[s]), rng)
        wall_replay = time.perf_counter() - t1
        robot_replay = world.time - t_robot
    finally:
        walker.close()
    return (decisions / wall, decisions / wall_replay, run.robot_seconds / wall,
            robot_replay / wall_replay)


def bench_physics(decisions: int, repeats: int, compare_hz: float) -> None:
    import dataclasses
    import os
    import statistics

    from simlab.online.experiments import lattice_states
    from simlab.online.physics import PhysicsLab
    from simlab.physics.arena import load_arena
    from simlab.physics.motion import PrimitiveParams
    from simlab.physics.rate import DEFAULT_HZ

    arena = load_arena("table")
    base = PhysicsLab(arena, lattice_states(arena, 5), PrimitiveParams())
    mf, mb = _experts()
    rates = [DEFAULT_HZ] + ([compare_hz] if compare_hz and compare_hz != DEFAULT_HZ else [])
    print(f"\n== physics, table, 25 states x 16 primitives, {decisions} decisions per run "
          f"(best of {repeats}; rates {', '.join(f'{r:g}' for r in rates)} Hz in turn) ==")
    load0 = os.getloadavg()[0]
    res: dict[float, list[tuple[float, ...]]] = {hz: [] for hz in rates}
    labs = {hz: dataclasses.replace(base, physics_hz=hz) for hz in rates}
    for rep in range(repeats + 1):
        for hz in rates:
            r = _physics_run(labs[hz], rep, decisions, mf, mb)
            if rep:  # the first is the warm-up
                res[hz].append(r)
    for hz in rates:
        online = [r[0] for r in res[hz]]
        replay = [r[1] for r in res[hz]]
        print(f"{hz:5g} Hz: online (entropy_and_cost) decisions/s {_best(online)} median "
              f"{statistics.median(online):.0f}; stepped robot-s/wall-s "
              f"{max(r[2] for r in res[hz]):.1f}")
        print(f"{hz:5g} Hz: replay step (frozen Q)    decisions/s {_best(replay)} median "
              f"{statistics.median(replay):.0f}; online / replay {max(online) / max(replay):.2f}")
    if len(rates) == 2:
        a = statistics.median(r[0] for r in res[rates[0]])
        b = statistics.median(r[0] for r in res[rates[1]])
        print(f"online decisions/s at {rates[0]:g} Hz / at {rates[1]:g} Hz (medians): {a / b:.2f}x")
    print(f"load average {load0:.2f} before, {os.getloadavg()[0]:.2f} after")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--decisions", type=int, default=3200)
    parser.add_argument("--physics-decisions", type=int, default=150)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--skip-physics", action="store_true")
    parser.add_argument("--skip-mdp", action="store_true")
    parser.add_argument("--compare-hz", type=float, default=200.0,
                        help="second physics rate of the physics part (0: none)")
    args = parser.parse_args()
    if not args.skip_mdp:
        bench_mdp(args.decisions, args.repeats)
    if not args.skip_physics:
        bench_physics(args.physics_decisions, args.repeats, args.compare_hz)


if __name__ == "__main__":
    main()
