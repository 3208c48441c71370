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
    schema = pq.read_schema(out / "decisions.parquet")  # units as in the datasets
    for col in table.columns:
        assert {b"unit", b"description"} <= set(schema.field(col).metadata), col
    assert schema.field("seconds").metadata[b"unit"] == b"s"
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


# ------------------------------------------------------------------ the published protocol
def _tiny(root: Path, name: str, trap: bool = False, states: int = 4) -> Path:
    """A ring 0 -> 1 -> 2 -> 0 (all 8 actions) with a trap 3, as simlab estimate writes it
    from an ISIR counts file; ``trap``: from 0 every action leads to 3."""
    counts = np.zeros((states, 8, states), dtype=np.int64)
    for s, s2 in ((0, 3 if trap else 1), (1, 2), (2, 0)):
        counts[s, :, s2] = 5
    for s in range(3, states):
        counts[s, :, s] = 5
    (root / f"{name}-counts.json").write_text(json.dumps(isir_document(counts)))
    assert main(["-q", "estimate", "--counts", str(root / f"{name}-counts.json"),
                 "--n-actions", "8", "--convention", "ccw-east", "--out",
                 str(root / f"{name}.npz"), "--no-plot"]) == 0
    return root / f"{name}.npz"


def test_online_cli_with_the_published_protocol(tmp_path: Path, capsys) -> None:
    """--protocol published on a tiny model: the goal's decision, the more used of two
    --after models, the rules in the summary, units in the Parquet log."""
    import pyarrow.parquet as pq

    ring, trap = _tiny(tmp_path, "ring"), _tiny(tmp_path, "trap", trap=True)
    out = tmp_path / "pub"
    argv = ["online", str(ring), "--out", str(out), "--protocol", "published", "--goal", "2",
            "--start-states", "0", "--decisions", "30", "--seeds", "2", "--criteria", "mb",
            "entropy_and_cost", "--change", "model", "--change-at", "12", "--after", str(trap),
            str(ring), "--use-states", "0", "1", "--workers", "1", "--no-progress",
            "--no-plots"]
    assert main(argv) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["protocol"]["name"] == "published" and summary["protocol"]["overridden"] == []
    assert summary["protocol"]["rules"]["reset"] == "goal-decision"
    rows = pq.read_table(out / "decisions.parquet").to_pandas()
    # the published reset: 0 -> 1 -> 2 (rewarded) -> a decision in 2 -> 0 ...; before the
    # change at 12, 4 decisions in 0 and 4 in 1: a tie, the first --after model (the trap)
    # happens
    for arm, rec in summary["arms"].items():
        run = rows[(rows.arm == arm) & (rows.seed == 0)]
        np.testing.assert_array_equal(run.s[:12], [0, 1, 2] * 4)
        assert run.reward[:12].sum() == 4 and (run.s_next[12:] == 3).all()
        assert rec["chosen"] == [str(trap)] * 2
        assert rec["use_counts"] == [{str(trap): 4, str(ring): 4}] * 2
    meta = pq.read_schema(out / "decisions.parquet")
    assert meta.field("backups").metadata[b"unit"] == b"backups"
    assert meta.field("c_mb").metadata[b"unit"] == b"backups"
    assert b"normalised entropy" in meta.field("h_mf").metadata[b"description"]
    assert set(json.loads(meta.metadata[b"simlab.columns"])) == set(rows.columns)
    assert "Protocol: published" in (out / "summary.md").read_text()
    # a rule given beside the switch wins over it, and is recorded
    assert main([*argv, "--overwrite", "--change-pays", "--reset", "teleport"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["protocol"]["overridden"] == ["reset", "change_pays"]
    run = pq.read_table(out / "decisions.parquet").to_pandas()
    assert not (run.s == 2).any()  # teleported after each reward
    assert main([*argv[:3], str(tmp_path / "simlab"), *argv[6:], "--no-change-pays"]) == 0
    rules = json.loads((tmp_path / "simlab" / "summary.json").read_text())["protocol"]
    assert rules["name"] == "simlab" and rules["overridden"] == ["change_pays"]


def test_after_must_be_a_model_of_the_same_states(tmp_path: Path, capsys) -> None:
    ring, other = _tiny(tmp_path, "ring"), _tiny(tmp_path, "big", states=5)
    argv = ["online", str(ring), "--out", str(tmp_path / "o"), "--goal", "2", "--start-states",
            "0", "--decisions", "20", "--seeds", "1", "--criteria", "mb", "--workers", "1",
            "--no-progress", "--no-plots", "--change", "model", "--change-at", "5"]
    assert main([*argv, "--after", str(other)]) == 2
    err = capsys.readouterr().err
    assert "big.npz" in err and "5 states x 8 actions" in err and "4 x 8" in err
    assert main([*argv[:-4], "--after", str(ring)]) == 2  # an --after needs a change
    assert "--change model" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_a_text_file_given_as_the_mdp_is_named(tmp_path: Path, capsys) -> None:
    (tmp_path / "notes.npz").write_text("state 0 -> 1\n")
    assert main(["online", str(tmp_path / "notes.npz"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "not an mdp.npz written by simlab estimate" in err and "pickle" not in err


def test_overwrite_without_plots_removes_the_earlier_figures(tmp_path: Path) -> None:
    ring = _tiny(tmp_path, "ring")
    out = tmp_path / "o"
    argv = ["online", str(ring), "--out", str(out), "--goal", "2", "--start-states", "0",
            "--decisions", "20", "--seeds", "1", "--criteria", "mb", "--workers", "1",
            "--no-progress"]
    assert main(argv) == 0 and (out / "mb_share.png").exists()
    (out / "mine.txt").write_text("not online's")
    assert main([*argv, "--overwrite", "--no-plots"]) == 0
    assert {p.name for p in out.iterdir()} == {"decisions.parquet", "summary.json",
                                               "summary.md", "mine.txt"}


def test_ray_backend_accepts_workers_as_collect_does(tmp_path: Path, monkeypatch) -> None:
    """--backend ray --workers 2: the runs go to Ray (its cluster's CPUs); --workers is for
    the local pool and not passed to Ray, whose executor refuses it."""
    import simlab.base.parallel as parallel

    real, calls = parallel.make_executor, []

    def fake(backend="local", *, workers=None, address=None, in_process_single=False):
        calls.append((backend, workers))
        if backend == "ray" and workers is None:  # stands in for a Ray runtime
            return parallel.InProcessExecutor()
        return real(backend, workers=workers, address=address,
                    in_process_single=in_process_single)

    monkeypatch.setattr(parallel, "make_executor", fake)
    ring = _tiny(tmp_path, "ring")
    assert main(["online", str(ring), "--out", str(tmp_path / "o"), "--goal", "2",
                 "--start-states", "0", "--decisions", "20", "--seeds", "2", "--criteria",
                 "mb", "--backend", "ray", "--workers", "2", "--no-progress",
                 "--no-plots"]) == 0
    assert calls == [("ray", None)]


def test_out_of_memory_names_online_options(tmp_path: Path, monkeypatch, capsys) -> None:
    import simlab.online.command as command

    def oom(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(command, "run_arm", oom)
    ring = _tiny(tmp_path, "ring")
    assert main(["online", str(ring), "--out", str(tmp_path / "o"), "--goal", "2",
                 "--start-states", "0", "--seeds", "1", "--workers", "1",
                 "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "out of memory" in err and "--seeds" in err and "hours" not in err
