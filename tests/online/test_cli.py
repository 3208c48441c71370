"""``simlab online`` end to end: an ISIR count file -> ``simlab estimate`` -> ``simlab
online``; the Parquet log, the summary and the markdown agree with each other."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from simlab.cli import main
from simlab.online.synthetic import corridor_counts, corridor_positions, isir_document


@pytest.fixture(scope="module")
def mdp_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("online")
    counts = corridor_counts(np.random.default_rng(0))
    (root / "transitionModel").write_text(json.dumps(isir_document(counts)))
    assert main(["-q", "estimate", "--counts", str(root / "transitionModel"), "--n-actions",
                 "8", "--convention", "ccw-east", "--out", str(root / "mdp.npz"),
                 "--no-plot"]) == 0
    return root / "mdp.npz"


def test_synthetic_model_has_the_published_layout() -> None:
    xy = corridor_positions()
    assert xy.shape == (38, 2) and len({tuple(p) for p in xy}) == 38
    for u, v in ((6, 7), (20, 21)):  # the doors are neighbours
        assert np.abs(xy[u] - xy[v]).sum() == 1
    counts = corridor_counts(np.random.default_rng(0))
    assert counts.shape == (38, 8, 38) and np.all(counts.sum(axis=2) >= 8)
    assert counts[6, 0, 7] > 0 and counts[7, 4, 6] > 0  # east through the top door, west back


def test_online_cli_end_to_end(mdp_file: Path, tmp_path: Path, capsys) -> None:
    import pyarrow.parquet as pq

    out = tmp_path / "run"
    argv = ["online", str(mdp_file), "--out", str(out), "--decisions", "400", "--seeds", "2",
            "--criteria", "mb", "mf", "entropy_and_cost", "--kappas", "1", "3",
            "--change", "goal", "--change-at", "200", "--workers", "1", "--no-progress"]
    assert main(argv) == 0
    assert "entropy_and_cost_k3" in capsys.readouterr().out
    names = {p.name for p in out.iterdir()}
    assert names == {"decisions.parquet", "cumulative_reward.png", "cumulative_cost.png",
                     "mb_share.png", "summary.json", "summary.md"}
    table = pq.read_table(out / "decisions.parquet").to_pandas()
    assert len(table) == 4 * 2 * 400
    summary = json.loads((out / "summary.json").read_text())
    assert summary["command"] == "simlab online" and summary["states"] == 38
    for arm, rec in summary["arms"].items():
        rows = table[table.arm == arm]
        per_seed = rows.groupby("seed").reward.sum()
        assert rec["reward"]["mean"] == pytest.approx(per_seed.mean())
        assert rec["mb_share"] == pytest.approx((rows.expert == "MB").mean())
        assert rec["reward_after"]["mean"] == pytest.approx(
            rows[rows.t >= 200].groupby("seed").reward.sum().mean())
    arms = summary["arms"]
    assert arms["mb"]["mb_share"] == 1.0 and arms["mf"]["mb_share"] == 0.0
    assert arms["mb"]["cost_vs_mb"] == 1.0
    assert arms["mf"]["cost_vs_mb"] == pytest.approx(
        800 / table[table.arm == "mb"].backups.sum())  # 1 backup per MF decision
    assert set(table[table.t >= 200].phase) == {1}
    assert "| entropy_and_cost_k1 |" in (out / "summary.md").read_text()
    # the same seed gives the same log (deterministic cost), the file is refused again ...
    before = (out / "decisions.parquet").read_bytes()
    assert main(argv) == 2
    assert "already exists" in capsys.readouterr().err
    # ... and --overwrite replaces it with identical decisions
    assert main([*argv, "--overwrite"]) == 0
    again = pq.read_table(out / "decisions.parquet").to_pandas()
    cols = [c for c in again.columns if c != "seconds"]
    assert again[cols].equals(table[cols])
    assert len(before) > 0


def test_the_published_reward_and_first_visit_rules_can_be_switched_off(
        mdp_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "off"
    argv = ["online", str(mdp_file), "--out", str(out), "--decisions", "120", "--seeds", "1",
            "--criteria", "entropy", "--workers", "1", "--no-progress", "--no-plots"]
    assert main([*argv, "--no-state-reward", "--no-plan-both-first"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["state_reward"] is False and summary["plan_both_first"] is False
    assert main([*argv[:3], str(tmp_path / "on"), *argv[4:]]) == 0
    on = json.loads((tmp_path / "on" / "summary.json").read_text())
    assert on["state_reward"] is True and on["plan_both_first"] is True
    # an MF decision costs 1 backup, but at a first visit (after the first decision, when
    # MB knows a pair) MB plans too; switched off, every MF decision costs 1
    import pyarrow.parquet as pq

    for folder, both in ((tmp_path / "on", True), (out, False)):
        rows = pq.read_table(folder / "decisions.parquet").to_pandas()
        first = ~rows.s.duplicated() & (rows.t > 0)
        mf = rows.expert == "MF"
        assert (rows.backups[mf & ~first] == 1).all()
        assert (rows.backups[mf & first] > 1).all() if both else \
            (rows.backups[mf & first] == 1).all()
        assert (mf & first).sum() >= 3
