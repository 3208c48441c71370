"""Visit-the-lab social task: steps per second of env + Q-learning, fused vs plain Python.

Two versions of the same loop (epsilon-greedy Q-learning on
``simlab/VisitLab-Social-v0``, thesis settings, easy human, 40-step trials):

* **fused** — :func:`simlab.visitlab.training.train`: one numba loop runs the social
  dynamics kernel and the agent kernels (no Python per step);
* **python** — :func:`simlab.visitlab.reference.train_python`: the Gymnasium env's
  ``step`` (which calls the same dynamics kernel and builds ``info``) plus a Python
  Q-learning update and epsilon-greedy selection, one Python iteration per step.

Both consume the same random streams, so on the same seed they produce the same
curve; the script checks this before timing. Each figure is the best of
``--repeats`` runs, with the worst beside it (the machine is shared). It also
times the model-based epsilon-greedy agent (thesis planning: 50 sweeps every
10,000 steps) and projects the thesis workload, 10 seeds x 100,000 trials.

Usage::

    python benchmarks/visitlab_speed.py [--fused-trials 20000] [--python-trials 400]
                                        [--repeats 3]

For scale: the paper's own pure-Python code runs about 27,000 social steps/s with
a Q-learner on this machine (figure given in the task description, not measured
here).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from simlab.visitlab.reference import train_python
from simlab.visitlab.training import loop_agent_config, make_env, seed_generators, train

STEPS = 40


def fused_run(trials: int, seed: int, agent: str = "q-learning") -> tuple[float, np.ndarray]:
    start = time.perf_counter()
    res = train("social", agent, trials=trials, seeds=1, seed=seed, human="easy", progress=False)
    return time.perf_counter() - start, res.returns[0]


def python_run(trials: int, seed: int) -> tuple[float, np.ndarray]:
    env = make_env("social", human="easy")
    cfg = loop_agent_config("q-learning", "social")
    env_rng, agent_rng = seed_generators(seed, 1)[0]
    start = time.perf_counter()
    returns, _ = train_python(env, cfg, trials, env_rng, agent_rng)
    return time.perf_counter() - start, returns


def best_of(fn, repeats: int) -> tuple[float, float]:
    times = [fn()[0] for _ in range(repeats)]
    return min(times), max(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--fused-trials", type=int, default=20_000)
    parser.add_argument("--python-trials", type=int, default=400)
    parser.add_argument("--mb-trials", type=int, default=20_000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()

    # compile (or load the numba cache) and check that both loops agree
    _, fused = fused_run(args.python_trials, seed=0)
    _, plain = python_run(args.python_trials, seed=0)
    same = bool(np.array_equal(fused, plain))
    print(f"same curve from both loops on {args.python_trials} trials: {same}")

    f_best, f_worst = best_of(lambda: fused_run(args.fused_trials, 1), args.repeats)
    p_best, p_worst = best_of(lambda: python_run(args.python_trials, 1), args.repeats)
    f_rate = args.fused_trials * STEPS / f_best
    p_rate = args.python_trials * STEPS / p_best
    print(f"fused  numba loop   : {f_rate:12,.0f} steps/s  (best of {args.repeats}; worst "
          f"{args.fused_trials * STEPS / f_worst:,.0f})  [{args.fused_trials * STEPS:,} steps]")
    print(f"python gymnasium    : {p_rate:12,.0f} steps/s  (best of {args.repeats}; worst "
          f"{args.python_trials * STEPS / p_worst:,.0f})  [{args.python_trials * STEPS:,} steps]")
    print(f"ratio fused/python  : {f_rate / p_rate:12.1f} x   (target >= 20 x)")

    fused_run(200, 2, agent="mb-egreedy")  # compile
    m_best, m_worst = best_of(lambda: fused_run(args.mb_trials, 2, agent="mb-egreedy"),
                              args.repeats)
    m_rate = args.mb_trials * STEPS / m_best
    print(f"fused mb-egreedy    : {m_rate:12,.0f} steps/s  (first {args.mb_trials:,} trials, "
          f"planning included; worst {args.mb_trials * STEPS / m_worst:,.0f})")
    work = 10 * 100_000 * STEPS
    print(f"10 seeds x 100,000 trials x {STEPS} steps = {work:,} steps: Q-learning "
          f"{work / f_rate / 60:.1f} min fused vs {work / p_rate / 3600:.1f} h plain Python "
          f"(one core); model-based about {work / m_rate / 60:.0f} min at its early-trial rate "
          f"(planning grows with the model; see summary.json wall times of full runs)")


if __name__ == "__main__":
    main()
