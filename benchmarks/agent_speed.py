"""Agent updates per second on a 2,560-state, 30-action MDP (the social task's size).

The MDP has random sparse transitions (``--branching`` successors per (s, a),
Dirichlet probabilities) and reward 1 on arriving in 5 % of the states; episodes
of 40 steps (thesis social trials) from a uniform start. Each agent is measured

* **fused**: environment sampling and agent step in one njit loop calling the
  act / learn steps of :mod:`simlab.agents.core` (how the training loops run), and
* **python**: the agent class's ``act`` / ``update`` called per step from Python
  (environment sampled with the same kernel),

and the ratio fused / python is printed (the baseline is measured in the same
run). One "update" is one environment step: action selection, transition,
learning (model-based agents: count update, one Bellman backup, and their
periodic value iteration, included in the time). Model-based agents are shown
with their default planning (the thesis's 50 sweeps every 10,000 steps, stopping
at tol 1e-6), with the paper's (one sweep every 1,000 steps; R-max's default) and
with incremental backups only (the per-step cost of the kernels themselves).

Usage::

    python benchmarks/agent_speed.py [--steps 1000000] [--python-steps 20000] [--warm 300000]
                                     [--repeats 3]

Both paths are timed from the same agent state, reached by ``--warm`` fused steps
(planning cost grows with the model, so a fresh agent would flatter the shorter
Python run).

The machine is shared: each figure is the best of ``--repeats`` with the spread
(worst/best) beside it.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from numba import njit

from simlab.agents import core, make_agent
from simlab.agents import kernels as K
from simlab.agents.agents import PassiveObserverAgent, RMaxAgent

S, A, HORIZON = 2560, 30, 40


def sparse_mdp(rng: np.random.Generator, branching: int):
    succ = np.empty((S, A, branching), dtype=np.int64)
    cdf = np.empty((S, A, branching))
    for s in range(S):
        succ[s] = rng.choice(S, size=(A, branching))
        cdf[s] = np.cumsum(rng.dirichlet(np.ones(branching), size=A), axis=1)
    reward = (rng.random(S) < 0.05).astype(np.float64)
    return succ, cdf, reward


@njit(cache=True)
def fused(succ, cdf, reward, steps, Q, model, p, env_rng, agent_rng):
    """The agent core's act / learn steps (simlab.agents.core), as the training loops run."""
    s = env_rng.integers(0, S)
    total = 0.0
    t = 0
    for i in range(steps):
        if i % HORIZON == 0:
            s = env_rng.integers(0, S)
        a = core.act(Q, s, p, core.NO_MASK, agent_rng)
        s2 = succ[s, a, K.sample_from_cdf(cdf[s, a], env_rng)]
        r = reward[s2]
        t = core.learn(model, Q, s, a, r, s2, p, core.NO_MASK, core.NO_TERMINAL, t)
        total += r
        s = s2
    return total


def run_fused(agent, mdp, steps, env_rng):
    succ, cdf, reward = mdp
    # the planning clock restarts at each call (as before the agent core)
    return fused(succ, cdf, reward, steps, agent.Q, getattr(agent, "model", core.NO_MODEL),
                 agent.params, env_rng, agent.rng)


def run_python(agent, mdp, steps, env_rng):
    succ, cdf, reward = mdp
    s = int(env_rng.integers(0, S))
    total = 0.0
    for t in range(steps):
        if t % HORIZON == 0:
            s = int(env_rng.integers(0, S))
        a = agent.act(s)
        s2 = int(succ[s, a, K.sample_from_cdf(cdf[s, a], env_rng)])
        r = float(reward[s2])
        agent.update(s, a, r, s2)
        total += r
        s = s2
    return total


AGENT_CASES = [
    ("q-learning", {}),
    ("q-softmax", {}),
    ("mb-egreedy", {}),
    ("mb-egreedy (incremental backups only)", {"plan_every": 0}),
    ("vi-softmax", {}),
    ("vi-softmax (paper: 1 sweep / 1000 steps)", {"plan_every": 1000, "max_sweeps": 1}),
    ("rmax", {}),
    ("rmax (m=5, the paper's social setting)", {"m": 5}),
    # classic R-max replans every time a pair becomes known: measured on the first
    # 10,000 steps only (its cost grows with the number of pairs already known)
    (
        "rmax (classic: VI when a pair is known) *",
        {"replan_when_known": True, "plan_every": 0, "max_sweeps": 50},
    ),
    ("sliding-window", {}),
]


def measure(label, overrides, mdp, steps, python_steps, warm, repeats):
    name = label.split(" ")[0]
    if label.endswith("*"):
        steps = python_steps = min(python_steps, 10_000)
        warm = 0
    fused_times, py_times = [], []
    for rep in range(repeats):
        # both paths continue from the same agent state, reached by `warm` fused steps
        # (the model's size, hence the planning cost, grows during exploration)
        agents = []
        for _ in range(2):
            agent = make_agent(name, S, A, np.random.default_rng(rep), **overrides)
            run_fused(agent, mdp, max(warm, 1000), np.random.default_rng(100 + rep))
            agents.append(agent)
        t0 = time.perf_counter()
        run_fused(agents[0], mdp, steps, np.random.default_rng(200 + rep))
        fused_times.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        run_python(agents[1], mdp, python_steps, np.random.default_rng(200 + rep))
        py_times.append(time.perf_counter() - t0)
    f_best, p_best = min(fused_times), min(py_times)
    f_rate, p_rate = steps / f_best, python_steps / p_best
    print(
        f"{label:<50} {f_rate / 1e3:9,.0f} k/s (x{max(fused_times) / f_best:4.2f})"
        f" {p_rate / 1e3:7.1f} k/s (x{max(py_times) / p_best:4.2f}) {f_rate / p_rate:6.0f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=1_000_000, help="fused steps per repeat")
    parser.add_argument("--python-steps", type=int, default=20_000, help="Python steps per repeat")
    parser.add_argument(
        "--warm",
        type=int,
        default=300_000,
        help="fused steps before timing (both paths start from that state)",
    )
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--branching", type=int, default=4, help="successors per (s, a)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    mdp = sparse_mdp(np.random.default_rng(args.seed), args.branching)
    print(
        f"MDP: {S} states, {A} actions, {args.branching} successors per pair, "
        f"{HORIZON}-step episodes; best of {args.repeats} (worst/best in brackets)"
    )
    print(
        f"{'agent (updates per second)':<50} {'fused':>13} {'':>7} {'python':>11} {'':>7}"
        f" {'ratio':>6}"
    )
    for label, overrides in AGENT_CASES:
        measure(label, overrides, mdp, args.steps, args.python_steps, args.warm, args.repeats)
    print("* first 10,000 steps of a fresh agent only, fused and python")
    # the passive observer runs the MB actor plus a Q-learner: shown in Python only
    po = make_agent("passive-observer", S, A, np.random.default_rng(0))
    assert isinstance(po, PassiveObserverAgent) and not isinstance(po, RMaxAgent)
    t0 = time.perf_counter()
    run_python(po, mdp, args.python_steps, np.random.default_rng(1))
    rate = args.python_steps / (time.perf_counter() - t0)
    print(f"{'passive-observer (python path, fresh agent)':<50} {'':>21} {rate / 1e3:7.1f} k/s")


if __name__ == "__main__":
    main()
