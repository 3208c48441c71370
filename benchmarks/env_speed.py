"""Steps per second of every registered simlab env, single and in a 2-env AsyncVectorEnv.

Each env is built with ``gym.make`` (registered wrappers included) from small fixed
inputs: the 41-state synthetic arena MDP for ``EmpiricalMDP-v0`` (goal ``g0``), a 5 x 5
lattice of Voronoi centres over the table for ``TableArenaStates-v0``, defaults for the
others. Uniform random actions from a seeded action space; episodes reset on truncation.
Single: ``--steps`` steps after one warm-up episode. Vector: ``AsyncVectorEnv`` of 2
copies (one subprocess each), ``--steps`` vector steps (so 2x env steps), throughput in
env steps per second. Physics envs take ``--physics-steps`` (they are ~1,000x slower).

Usage::

    python benchmarks/env_speed.py [--steps 2000] [--physics-steps 100]
"""

from __future__ import annotations

import argparse
import time
from functools import partial

import gymnasium as gym
import numpy as np

import simlab  # noqa: F401  (registers the environments)
from simlab.envs import ENV_ENTRY_POINTS

PHYSICS = ("simlab/TableArena-v0", "simlab/TableArenaStates-v0")


def _kwargs(env_id: str) -> dict:
    if env_id == "simlab/EmpiricalMDP-v0":
        from simlab.training.synthetic import synthetic_arena_mdp

        return {"mdp": synthetic_arena_mdp(np.random.default_rng(0)), "goal": 0}
    if env_id == "simlab/TableArenaStates-v0":
        g = np.linspace(-0.6, 0.6, 5)
        return {"states": [[float(x), float(y)] for y in g[::-1] for x in g]}
    return {}


def _make(env_id: str) -> gym.Env:
    return gym.make(env_id, **_kwargs(env_id))


def single(env_id: str, steps: int) -> float:
    env = _make(env_id)
    env.reset(seed=0)
    env.action_space.seed(0)
    t0 = time.perf_counter()
    for _ in range(steps):
        *_, term, trunc, _ = env.step(env.action_space.sample())
        if term or trunc:
            env.reset()
    rate = steps / (time.perf_counter() - t0)
    env.close()
    return rate


def vector(env_id: str, steps: int) -> float:
    envs = gym.vector.AsyncVectorEnv([partial(_make, env_id)] * 2)
    envs.reset(seed=0)
    envs.action_space.seed(0)
    t0 = time.perf_counter()
    for _ in range(steps):
        envs.step(envs.action_space.sample())  # autoreset inside
    rate = 2 * steps / (time.perf_counter() - t0)
    envs.close()
    return rate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000, help="steps per tabular env")
    parser.add_argument("--physics-steps", type=int, default=100,
                        help="steps per physics env")
    args = parser.parse_args()
    print(f"{'env':32s} {'single steps/s':>15s} {'2-env async steps/s':>20s}")
    for env_id in ENV_ENTRY_POINTS:
        n = args.physics_steps if env_id in PHYSICS else args.steps
        print(f"{env_id:32s} {single(env_id, n):15.1f} {vector(env_id, n):20.1f}", flush=True)


if __name__ == "__main__":
    main()
