"""Replay of Q-tables in another action convention (issue 12): 8 actions numbered
counter-clockwise from East drive the physical robot the right way; mismatches are refused;
masked actions are never chosen."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from simlab.agents.planning import reward_on_arrival, value_iteration
from simlab.agents.storage import save_q_table
from simlab.base.actions import CONVENTIONS, parse_action_set
from simlab.base.errors import ConfigError
from simlab.replay.replay import greedy_action, replay

CCW8 = parse_action_set(8, "ccw-east")


def _write_ccw8(root: Path, chain, valid: np.ndarray | None = None) -> tuple[Path, Path]:
    """The chain's slow actions renumbered ccw-east: an 8-action mdp.npz and Q-tables."""
    root.mkdir(parents=True, exist_ok=True)
    with np.load(chain.mdp, allow_pickle=False) as m:
        arrays = {k: m[k] for k in m.files if k != "meta_json"}
    perm = np.array(CONVENTIONS["ccw-east"])  # ccw action a = simlab direction perm[a]
    for key in ("T", "counts"):
        arrays[key] = arrays[key][:, perm]
    for key in ("visited", "entropy"):
        arrays[key] = arrays[key][:, perm]
    arrays["R"] = arrays["R"][:, :, perm]
    arrays["mean_entropy"] = arrays["mean_entropy"][perm]
    meta = {"action_set": CCW8.to_json(), "unvisited": "mask"}
    mdp = root / "mdp.npz"
    np.savez_compressed(mdp, **arrays, meta_json=np.array(json.dumps(meta)))
    qdir = root / "q"
    T = arrays["T"]
    for g, mask in zip(chain.goal_names, chain.goal_masks, strict=True):
        Q, _, _ = value_iteration(T, reward_on_arrival(T, mask.astype(float)), 0.9)
        extra = {} if valid is None else {"valid": valid}
        save_q_table(qdir / f"q_{g}.npz", Q, arrays=extra,
                     metadata={"mdp": str(mdp), "goal": g, "action_set": CCW8.to_json()})
    return mdp, qdir


def test_eight_action_ccw_east_qtables_drive_the_robot_their_way(chain, tmp_path) -> None:
    mdp, qdir = _write_ccw8(tmp_path / "ccw", chain)
    res = replay("table", chain.states, qdir, hours=0.04, seed=2, out=tmp_path / "out",
                 baseline_hours=0, progress=False)
    summary = res.summary
    assert summary.action_set == CCW8.to_json()
    assert summary.mdp == str(mdp)
    log = res.run.log
    assert log.n > 10 and set(np.unique(log.a)) <= set(range(8))
    # Each unblocked move goes along its action's ccw-east heading (0 = East, 2 = North).
    moved = ~log.blocked
    d = log.truth_after[moved, :2] - log.truth_before[moved, :2]
    ok = np.hypot(d[:, 0], d[:, 1]) > 0.02
    assert ok.sum() >= 5
    bearing = np.arctan2(d[ok, 1], d[ok, 0])
    heading = np.array([CCW8.heading(a) for a in log.a[moved][ok]])
    err = np.abs((bearing - heading + math.pi) % (2 * math.pi) - math.pi)
    assert err.max() < 0.35
    # The greedy policy: the choice of the Q-tables (ties at random), so the greedy rate is
    # predicted with the 8-action model.
    assert summary.prediction["greedy"]["rate_per_hour"] > 0


def test_mismatched_action_sets_are_refused(chain, tmp_path) -> None:
    _, qdir = _write_ccw8(tmp_path / "ccw", chain)
    # ccw-east Q-tables against the chain's 16-action simlab MDP.
    with pytest.raises(ConfigError, match="Q-tables 8 actions"):
        replay("table", chain.states, qdir, hours=0.01, mdp=chain.mdp, out=tmp_path / "o1",
               progress=False)
    # 8-action in-memory tables need their action set.
    tables = {g: np.zeros((chain.discretizer.n_states, 8)) for g in chain.goal_names}
    with pytest.raises(ConfigError, match="no action_set record"):
        replay("table", chain.states, tables, hours=0.01, out=tmp_path / "o2", progress=False)
    assert not (tmp_path / "o1").exists() and not (tmp_path / "o2").exists()


def test_greedy_action_never_picks_a_masked_action() -> None:
    rng = np.random.default_rng(0)
    q = np.array([5.0, 1.0, 5.0, 0.0])
    valid = np.array([False, True, False, True])
    picks = {greedy_action(q, rng, valid=valid) for _ in range(50)}
    assert picks == {1}
    # A blocked (excluded) valid action falls back to the other valid one, never to a
    # masked one; with every valid action excluded the exclusion is dropped.
    assert greedy_action(q, rng, np.array([False, True, False, False]), valid=valid) == 3
    assert greedy_action(q, rng, np.array([False, True, False, True]), valid=valid) == 1
    # No valid action in a state: all are allowed (ties among the best two at random).
    assert greedy_action(q, rng, valid=np.zeros(4, bool)) in (0, 2)


def test_replay_never_executes_a_masked_action(chain, tmp_path) -> None:
    S = chain.discretizer.n_states
    valid = np.ones((S, 8), dtype=bool)
    valid[:, [0, 2]] = False  # East and North masked everywhere
    valid[::3, 0] = True  # ... except East in every third state
    _, qdir = _write_ccw8(tmp_path / "ccw", chain, valid=valid)
    res = replay("table", chain.states, qdir, hours=0.04, seed=4, out=tmp_path / "out",
                 baseline_hours=0, progress=False)
    log = res.run.log
    assert log.n > 10
    assert valid[log.s, log.a].all()
    assert res.summary.masked_pairs == int((~valid).sum()) * len(chain.goal_names)
