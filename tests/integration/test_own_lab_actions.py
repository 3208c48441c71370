"""Issue 12 items 1 and 4: a real robot's action conventions end to end, masking, goals.

* 8 actions numbered counter-clockwise from East (ccw-east) go through ``estimate --counts``
  -> ``train`` -> the greedy policy and give the same policy, in map headings, as the same
  data renumbered in simlab's order;
* unvisited (s, a) are masked: no greedy policy chooses an untried action, and the
  planner's optimum no longer counts an untried "stay" in the goal as free reward;
* ``--goal-states`` and the episodic task on a hand-built chain give the analytic optimum;
* an 8-action Q-table is replayed in physics on the table.

The world of the first tests is a 3 x 3 grid of cells (state ``row * 3 + col``, row 0 at
the top, UP = +y) where each of the 8 directions moves one cell (a king's move) with
probability 0.8 and stays with probability 0.2; moves off the grid stay.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from simlab.agents.storage import load_npz, save_q_table
from simlab.base.actions import CONVENTIONS, HEADINGS, SIMLAB16, parse_action_set
from simlab.cli import main
from simlab.data.mdp import load_mdp, mdp_from_arrays
from simlab.replay.replay import greedy_action
from simlab.training import harness
from simlab.training.train import TrainTask, train

#: (dx, dy) of each simlab Direction (UP, DOWN, LEFT, RIGHT, UL, UR, DL, DR).
STEPS = [(0, 1), (0, -1), (-1, 0), (1, 0), (-1, 1), (1, 1), (-1, -1), (1, -1)]


def grid_counts(untried: set[tuple[int, int]] = frozenset()) -> np.ndarray:
    """Counts (9, 8, 9) of the 3 x 3 grid, actions in simlab direction order."""
    counts = np.zeros((9, 8, 9), dtype=np.int64)
    for s in range(9):
        row, col = divmod(s, 3)
        for d, (dx, dy) in enumerate(STEPS):
            if (s, d) in untried:
                continue
            r2, c2 = row - dy, col + dx
            target = r2 * 3 + c2 if 0 <= r2 < 3 and 0 <= c2 < 3 else s
            counts[s, d, target] += 8
            counts[s, d, s] += 2
    return counts


def write_counts(path: Path, counts: np.ndarray, numbering: tuple[int, ...]) -> Path:
    """A CSV count table whose action ``i`` is simlab direction ``numbering[i]``."""
    rows = ["s,a,s_next,count"]
    for s, d, t in zip(*np.nonzero(counts), strict=True):
        rows.append(f"{s},{numbering.index(int(d))},{t},{counts[s, d, t]}")
    path.write_text("\n".join(rows) + "\n")
    return path


def estimate_cli(tmp: Path, name: str, counts: np.ndarray, convention: str, *extra: str) -> Path:
    table = write_counts(tmp / f"{name}.csv", counts, CONVENTIONS[convention])
    out = tmp / f"{name}.npz"
    argv = ["estimate", "--counts", str(table), "--out", str(out), "--n-actions", "8",
            "--convention", convention, "--no-plot", *extra]
    assert main(argv) == 0
    return out


def best_headings(Q: np.ndarray, aset, tol: float = 1e-9) -> list[frozenset[float]]:
    """Per state, the map headings (rad, rounded) of every action within ``tol`` of the max."""
    out = []
    for row in np.asarray(Q):
        best = np.flatnonzero(row >= row.max() - tol)
        out.append(frozenset(round(aset.heading(int(a)), 9) for a in best))
    return out


@pytest.mark.slow
def test_ccw_east_gives_the_simlab_policy_in_headings(tmp_path: Path) -> None:
    counts = grid_counts()
    ccw = load_mdp(estimate_cli(tmp_path, "ccw", counts, "ccw-east"))
    sim = load_mdp(estimate_cli(tmp_path, "sim", counts, "simlab"))
    assert ccw.action_set == parse_action_set(8, "ccw-east")
    assert sim.action_set == parse_action_set(8, "simlab")
    # The same model, renumbered: T_sim[:, perm] == T_ccw.
    perm = ccw.action_set.permutation_to(sim.action_set)
    np.testing.assert_array_equal(sim.T[:, perm], ccw.T)
    results = {}
    for name, m in (("ccw", ccw), ("sim", sim)):
        out = tmp_path / f"train_{name}"
        train(m, agent="vi-softmax", episodes=300, runs=2, seed=1, out=out, plots=False,
              progress=False, task=TrainTask(goal_states=(2,)))
        arrays, meta = load_npz(out / "q_s2.npz", ("Q",))
        assert meta["action_set"] == m.action_set.to_json()
        assert meta["task"]["goal_states"] == [2]
        results[name] = (arrays, m.action_set)
    # The optimum of the true model is the same policy in both numberings.
    (a_ccw, s_ccw), (a_sim, s_sim) = results["ccw"], results["sim"]
    np.testing.assert_allclose(a_sim["Q_star"][:, perm], a_ccw["Q_star"], atol=1e-12)
    star = best_headings(a_ccw["Q_star"], s_ccw)
    assert star == best_headings(a_sim["Q_star"], s_sim)
    # From the bottom-left corner (state 6) the goal (top-right, state 2) is straight UR.
    assert star[6] == {round(float(HEADINGS[5]), 9)}  # UP_RIGHT = pi / 4
    # Each learned greedy policy takes an optimal heading in every state (ties aside, the
    # two numberings give the same policy in headings).
    for arrays, aset in results.values():
        learned = best_headings(arrays["Q"], aset, tol=0.0)
        for s in range(9):
            if s != 2:  # the goal itself: every action that stays pays the same
                assert learned[s] <= star[s], (s, learned[s], star[s])


def test_unvisited_pairs_are_masked_and_never_chosen(tmp_path: Path) -> None:
    # In the goal (state 4, the centre) every action is untried except UP (to state 1):
    # under the old rule the untried actions are free stays worth +1 per step.
    untried = {(4, d) for d in range(1, 8)} | {(0, 3), (0, 5)}
    counts = grid_counts(untried)
    path = estimate_cli(tmp_path, "masked", counts, "ccw-east")
    summary = json.loads(path.with_suffix(".json").read_text())
    assert summary["unvisited"] == "mask" and summary["masked_pairs"] == 9
    m = load_mdp(path)
    assert m.unvisited == "mask"
    valid = m.valid
    assert valid is not None and int((~valid).sum()) == 9
    # valid is in the file's (ccw-east) numbering: the tried directions are the valid ones.
    perm = np.array([CONVENTIONS["ccw-east"][a] for a in range(8)])
    np.testing.assert_array_equal(valid, counts.sum(axis=2)[:, perm] > 0)
    with pytest.warns(UserWarning, match="9 unvisited"):
        res = train(m, agent="vi-softmax", episodes=200, runs=2, seed=0, out=tmp_path / "q",
                    plots=False, progress=False, task=TrainTask(goal_states=(4,)))
    arrays, meta = load_npz(tmp_path / "q" / "q_s4.npz", ("Q",))
    np.testing.assert_array_equal(arrays["valid"], valid)
    assert meta["unvisited"] == "mask" and meta["masked_pairs"] == 9
    rng = np.random.default_rng(0)
    for Q in [*arrays["Q_runs"], arrays["Q"], arrays["Q_star"]]:
        for s in range(9):
            for _ in range(5):  # ties are broken at random: try several draws
                assert valid[s, greedy_action(Q[s], rng, valid=valid[s])]
    # The planner's optimum: staying in the goal now costs a round trip through
    # state 1 (UP then DOWN), so it is well below the free-stay optimum.
    free = train(m, agent="vi-softmax", episodes=10, runs=1, seed=0, plots=False,
                 progress=False, task=TrainTask(goal_states=(4,), unvisited="self-loop"))
    assert res.goals[0].optimal_return < 0.8 * free.goals[0].optimal_return
    greedy_star = arrays["Q_star"].argmax(axis=1)
    assert valid[np.arange(9), greedy_star].all()


def test_train_passes_valid_and_terminal_to_the_harness(monkeypatch, tmp_path: Path) -> None:
    """The wiring of train.py: the mask and terminal states each harness call's task holds."""
    calls: list[tuple[str, dict]] = []
    real_train, real_eval = harness.train_runs, harness.evaluate_q

    def fake_train_runs(task, *args, **kwargs):
        calls.append(("train_runs", {"valid": task.valid, "terminal": task.terminal}))
        return real_train(task, *args, **kwargs)

    def fake_evaluate_q(task, *args, **kwargs):
        calls.append(("evaluate_q", {"valid": task.valid, "terminal": task.terminal}))
        return real_eval(task, *args, **kwargs)

    monkeypatch.setattr(harness, "train_runs", fake_train_runs)
    monkeypatch.setattr(harness, "evaluate_q", fake_evaluate_q)
    m = load_mdp(estimate_cli(tmp_path, "w", grid_counts({(0, 1)}), "simlab"))
    with pytest.warns(UserWarning, match="1 unvisited"):
        train(m, episodes=5, runs=1, plots=False, progress=False,
              task=TrainTask(mode="episodic", goal_states=(8,), start_states=(0, 1)))
    assert [c[0] for c in calls] == ["train_runs", "evaluate_q"]
    for _, kw in calls:
        np.testing.assert_array_equal(kw["valid"], m.valid)
        np.testing.assert_array_equal(kw["terminal"], np.arange(9) == 8)
    calls.clear()
    # Full coverage, per-step task: nothing to pass (bit-identical to the old calls).
    full = load_mdp(estimate_cli(tmp_path, "f", grid_counts(), "simlab"))
    train(full, episodes=5, runs=1, plots=False, progress=False, task=TrainTask(goal_states=(8,)))
    assert all(kw == {"valid": None, "terminal": None} for _, kw in calls)


def chain_mdp(n: int = 5):
    """Deterministic chain 0 - 1 - ... - n-1; action 0 steps right, action 1 stays."""
    T = np.zeros((n, 2, n))
    for s in range(n):
        T[s, 0, min(s + 1, n - 1)] = 1.0
        T[s, 1, s] = 1.0
    return mdp_from_arrays(T)


def test_episodic_chain_reaches_the_analytic_optimum(tmp_path: Path) -> None:
    m = chain_mdp(5)
    gamma = 0.9
    res = train(m, agent="vi-softmax", episodes=300, runs=2, seed=0, horizon=10,
                out=tmp_path / "ep", plots=False, progress=False,
                task=TrainTask(mode="episodic", goal_states=(4,), start_states=(0,)))
    arrays, meta = load_npz(tmp_path / "ep" / "q_s4.npz", ("Q",))
    assert meta["task"] == {"mode": "episodic", "goal_states": [4], "start_states": [0]}
    # Reward 1 on arrival, nothing afterwards: Q*(s, right) = gamma^(3 - s) for s < 4.
    np.testing.assert_allclose(arrays["Q_star"][:4, 0], gamma ** (3 - np.arange(4)), atol=1e-8)
    # From state 0 the goal is 4 steps away: one reward per episode, within the horizon.
    assert res.goals[0].optimal_return == pytest.approx(1.0)
    assert (arrays["Q"][:4].argmax(axis=1) == 0).all()


def test_per_step_chain_reaches_the_analytic_optimum(tmp_path: Path) -> None:
    m = chain_mdp(5)
    res = train(m, agent="vi-softmax", episodes=300, runs=2, seed=0, horizon=10,
                out=tmp_path / "ps", plots=False, progress=False,
                task=TrainTask(goal_states=(4,), start_states=(0,)))
    # +1 per step arriving in the goal: from state 0 the first reward comes at step 4,
    # then every step of the 10: 7 rewards.
    assert res.goals[0].goal == "s4"
    assert res.goals[0].optimal_return == pytest.approx(7.0)
    arrays, meta = load_npz(tmp_path / "ps" / "q_s4.npz", ("Q",))
    assert meta["task"]["mode"] == "per-step" and meta["start"] is None
    assert (arrays["Q"][:4].argmax(axis=1) == 0).all()


def test_old_files_still_load(tmp_path: Path) -> None:
    # An mdp.npz and a Q-table written before action sets and rules existed.
    T = np.full((3, 16, 3), 1 / 3)
    np.savez_compressed(tmp_path / "mdp.npz", T=T, visited=np.ones((3, 16), bool))
    m = load_mdp(tmp_path / "mdp.npz")
    assert m.action_set == SIMLAB16 and m.unvisited == "mask" and m.valid is None
    from simlab.replay.inputs import load_qtables

    (tmp_path / "q").mkdir()
    save_q_table(tmp_path / "q" / "q_g1.npz", np.zeros((3, 16)), metadata={"goal": "g1"})
    qt = load_qtables(tmp_path / "q", ("g1",), 3)
    assert qt.action_set == SIMLAB16 and qt.valid is None
    # An old 8-action Q-table (no record) is refused: its numbering is unknown.
    save_q_table(tmp_path / "q" / "q_g1.npz", np.zeros((3, 8)), metadata={"goal": "g1"},
                 overwrite=True)
    from simlab.base.errors import ConfigError

    with pytest.raises(ConfigError, match="no action_set record"):
        load_qtables(tmp_path / "q", ("g1",), 3)
