"""Peak memory of a model-based agent on the paper's navigation task (5,184 states, 25 actions).

The task: a 24 x 24 grid (9 rooms of 8 x 8) whose state is the robot's cell plus
the current goal room label (9 labels): 5,184 states; 25 actions (8 directions x 3
speeds + STAY, thesis Table 2.1 order). Moves are clipped at the border and are
noisy, so a pair has a few successors: with probability 0.2 a move stops one cell
short, with 0.1 it veers 45 degrees. Reward 1 on arriving in the goal room.

The agent is the model-based epsilon-greedy agent with the sparse count model
(one backup per step, the paper's one value-iteration sweep every 1,000 steps),
run in a fused njit loop. ``--epsilon 1`` (default) makes it a uniform random
walk, the worst case for the model: it visits (almost) every pair and successor.

Printed: distinct (s, a, s') triples and visited pairs, the model's own bytes,
the process's resident memory (current and peak, from /proc; the peak is reset
after the warm-up when the kernel allows it), and beside them the 5.4 GB a dense
float64 S x A x S table would need. Target: <= 200 MB.

Usage::

    python benchmarks/agent_memory.py [--steps 3000000] [--epsilon 1.0]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from numba import njit

from simlab.agents import kernels as K

SIDE, ROOM, LABELS, A = 24, 8, 9, 25
CELLS = SIDE * SIDE
S = CELLS * LABELS
# thesis Table 2.1: 0 UP, 1 DOWN, 2 LEFT, 3 RIGHT (+4 speed 2, +8 speed 3);
# 12 UP-LEFT, 13 UP-RIGHT, 14 DOWN-LEFT, 15 DOWN-RIGHT (+4, +8); 24 STAY.
# (drow, dcol) per direction; row 0 is the top, so UP is drow = -1.
_CARD = np.array([[-1, 0], [1, 0], [0, -1], [0, 1]])
_DIAG = np.array([[-1, -1], [-1, 1], [1, -1], [1, 1]])
MOVES = np.zeros((A, 2), dtype=np.int64)  # unit direction per action
SPEED = np.zeros(A, dtype=np.int64)
for _a in range(24):
    _block, _d = divmod(_a, 4)
    MOVES[_a] = (_CARD if _block in (0, 1, 2) else _DIAG)[_d]
    SPEED[_a] = (_block % 3) + 1
# 45-degree neighbours of each of the 8 unit directions (for the veer noise)
_DIRS = np.array([[-1, 0], [-1, 1], [0, 1], [1, 1], [1, 0], [1, -1], [0, -1], [-1, -1]])


@njit(cache=True)
def _veer(dr, dc, side):
    for i in range(8):
        if _DIRS[i, 0] == dr and _DIRS[i, 1] == dc:
            j = (i + side) % 8
            return _DIRS[j, 0], _DIRS[j, 1]
    return dr, dc


@njit(cache=True)
def env_step(s, a, rng):
    label = s // CELLS
    cell = s - label * CELLS
    r, c = cell // SIDE, cell % SIDE
    if a < 24:
        dr, dc = MOVES[a, 0], MOVES[a, 1]
        k = SPEED[a]
        u = rng.random()
        if u < 0.2:
            k -= 1
        elif u < 0.3:
            dr, dc = _veer(dr, dc, 1 if rng.random() < 0.5 else 7)
        r = min(max(r + k * dr, 0), SIDE - 1)
        c = min(max(c + k * dc, 0), SIDE - 1)
    s2 = label * CELLS + r * SIDE + c
    room = (r // ROOM) * (SIDE // ROOM) + c // ROOM
    return s2, 1.0 if room == label else 0.0


@njit(cache=True)
def run(model, Q, steps, epsilon, gamma, plan_every, sweeps, horizon, env_rng, agent_rng):
    s = env_rng.integers(0, S)
    total = 0.0
    for t in range(steps):
        if t % horizon == 0:
            s = env_rng.integers(0, S)
        a = K.epsilon_greedy_action(Q[s], epsilon, agent_rng)
        s2, r = env_step(s, a, env_rng)
        K.model_based_update(model, Q, s, a, r, s2, gamma, 1, True, False, 0, 0.0)
        if plan_every > 0 and (t + 1) % plan_every == 0:
            K.model_value_iteration(model, Q, gamma, sweeps, 1e-6, 1)
        total += r
        s = s2
    return total


def _proc_kb(field: str) -> int | None:
    status = Path("/proc/self/status")
    if not status.exists():
        return None
    for line in status.read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1])
    return None


def _reset_peak() -> bool:
    try:
        Path("/proc/self/clear_refs").write_text("5")
        return True
    except OSError:
        return False


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--steps", type=int, default=3_000_000)
    parser.add_argument("--epsilon", type=float, default=1.0, help="1.0: uniform random walk")
    parser.add_argument("--plan-every", type=int, default=1000)
    parser.add_argument("--sweeps", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    env_seq, agent_seq = np.random.SeedSequence(args.seed).spawn(2)
    env_rng, agent_rng = np.random.default_rng(env_seq), np.random.default_rng(agent_seq)
    # warm-up: compile on a tiny run so compilation memory is not counted
    run(K.count_model_new(S, A, 16), np.zeros((S, A)), 2000, 1.0, 0.9, 1000, 1, 20,
        np.random.default_rng(1), np.random.default_rng(2))  # fmt: skip
    rss0 = _proc_kb("VmRSS")
    peak_reset = _reset_peak()
    model = K.count_model_new(S, A, 4096)
    Q = np.full((S, A), 1.0 / (1 - 0.9))  # optimistic, as the library's default
    t0 = time.perf_counter()
    run(model, Q, args.steps, args.epsilon, 0.9, args.plan_every, args.sweeps, 20,
        env_rng, agent_rng)  # fmt: skip
    wall = time.perf_counter() - t0
    rss1, hwm = _proc_kb("VmRSS"), _proc_kb("VmHWM")

    mb = 1024 * 1024
    dense = S * A * S * 8
    model_bytes = K.count_model_memory_bytes(model)
    n_pairs, n_entries = int(model.n_pairs), int(model.n_entries)
    print(
        f"task: {SIDE}x{SIDE} grid x {LABELS} goal labels = {S} states, {A} actions; "
        f"{args.steps:,} steps (epsilon {args.epsilon}) in {wall:.1f} s "
        f"({args.steps / wall / 1e6:.2f} M steps/s incl. a VI sweep every {args.plan_every})"
    )
    print(
        f"visited pairs {n_pairs:,} of {S * A:,}; distinct (s, a, s') triples {n_entries:,} "
        f"({n_entries / max(n_pairs, 1):.2f} successors per pair)"
    )
    print(
        f"model arrays:              {model_bytes / mb:10.1f} MB  (pool capacity "
        f"{int(model.capacity):,} entries)"
    )
    print(f"Q table:                   {Q.nbytes / mb:10.1f} MB")
    if rss0 is not None and rss1 is not None:
        print(
            f"process RSS before / after:{rss0 / 1024:10.1f} / {rss1 / 1024:.1f} MB "
            f"(growth {(rss1 - rss0) / 1024:.1f} MB)"
        )
    if hwm is not None:
        what = "since the warm-up" if peak_reset else "of the whole process, compilation included"
        print(f"peak RSS ({what}): {hwm / 1024:.1f} MB   target <= 200 MB")
    print(
        f"dense float64 S x A x S table: {dense / 1e9:.2f} GB ({dense / max(model_bytes, 1):,.0f}x "
        f"the sparse model)"
    )


if __name__ == "__main__":
    main()
