"""The fault corpus, part 4: the cases found by trying the newer commands as a new user
would (seeds, count tables, model files, pose logs, options files, outputs that must be
replaced only when they are the command's own).

Same promise as parts 1-3: exit 2 (130 for Ctrl-C), one line naming the user's file or
field with a fix that works, no traceback, nothing that existed before changed.
"""

from __future__ import annotations

import errno
import json
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from .conftest import assert_refused, failing, run_cli, tree_hashes
from .conftest import writes_file as _write


def _nan_counts(w: Path) -> None:
    with np.load(w / "mdp.npz", allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    counts = arrays["counts"].astype(np.float64)
    counts[0, 0, 0] = np.nan
    arrays["counts"] = counts
    np.savez(w / "nan.npz", **arrays)


_DIGITS = "7" * 5000
_ISIR = json.dumps({"transitionActions": [{"state": 0, "transitions": [
    {"action": 1, "state": 1, "prob": 3}]}], "actioncount": 1})

NO = None
# (id, setup, argv ({w}: the work folder), words the one error line must contain)
CASES: list[tuple[str, Callable[[Path], None] | None, str, tuple[str, ...]]] = [
    # ---- seeds: checked once, in the options layer, for every command and every source
    ("drive-seed-negative", NO, "drive --seed -5 --steps 1 --no-progress", ("seed", "-5")),
    ("drive-seed-negative-in-config", _write("c.toml", "seed = -5\n"),
     "drive --config {w}/c.toml --steps 1 --no-progress", ("c.toml", "seed", "-5")),
    ("train-seed-negative-in-config", _write("c.toml", "seed = -1\n"),
     "train --mdp {w}/mdp.npz --config {w}/c.toml --out {w}/t --no-progress",
     ("c.toml", "seed")),
    ("collect-seed-negative", NO, "collect --states {w}/states.json --transitions 10 "
     "--seed -3 --simulator kinematic --out {w}/o --no-progress", ("seed",)),
    # ---- count tables: a number too long for Python's int(), the action-width hint
    ("counts-isir-5000-digits", _write("isir", _ISIR.replace('"prob": 3',
                                                             f'"prob": {_DIGITS}')),
     "estimate --counts {w}/isir --n-actions 8 --out {w}/m.npz --no-plot",
     ("isir", "transitions[0].prob", "5000-digit")),
    ("counts-csv-5000-digits", _write("c.csv", f"s,a,s_next,count\n0,0,1,{_DIGITS}\n"),
     "estimate --counts {w}/c.csv --out {w}/m.npz --no-plot", ("c.csv", "line 2", "5000")),
    ("counts-16-actions-read-as-8", NO, "estimate --counts {w}/counts.csv --n-actions 8 "
     "--out {w}/m.npz --no-plot", ("counts.csv", "--n-actions 16")),
    ("estimate-counts-states-of-another-arena", NO, "estimate --counts {w}/counts.csv "
     "--states {w}/other_states.json --arena table --out {w}/m.npz --no-plot",
     ("other_states.json", "centres", "table")),
    # ---- model files
    ("train-mdp-nan-counts", _nan_counts, "train --mdp {w}/nan.npz --episodes 2 --runs 1 "
     "--out {w}/t --no-progress", ("nan.npz", "counts", "simlab estimate")),
    # ---- social-pipeline: bad options and outputs in the way, before any work
    ("social-pipeline-arena-missing", NO, "social-pipeline --arena {w}/nope.toml --out {w}/sp",
     ("nope.toml",)),
    ("social-pipeline-seed-negative", NO, "social-pipeline --seed -2 --out {w}/sp", ("seed",)),
    ("social-pipeline-out-is-file", _write("sp", "mine"), "social-pipeline --out {w}/sp",
     ("sp", "not a directory")),
    ("social-pipeline-outputs-exist", _write("sp/summary.json", "{}"),
     "social-pipeline --out {w}/sp", ("summary.json", "--overwrite")),
    # ---- a Ray cluster that is not there: refused within seconds, not after minutes
    ("collect-ray-address-refused", NO, "collect --states {w}/states.json --transitions 10 "
     "--simulator kinematic --backend ray --address 127.0.0.1:1 --out {w}/o --no-progress",
     ("address", "127.0.0.1:1", "ray start --head")),
    # ---- a directory where a file belongs, a file where a directory belongs
    ("drive-config-is-a-directory", NO, "drive --config {w}/q --steps 1 --no-progress",
     ("q", "found a directory")),
    ("estimate-counts-is-a-directory", NO, "estimate --counts {w}/q --out {w}/m.npz",
     ("q", "found a directory")),
    ("import-log-log-is-a-directory", NO, "import-log {w}/q --states {w}/states.json "
     "--out {w}/il", ("q", "found a directory")),
    # ---- arena-from-map: said of the user's option or file, never of the check file
    ("arena-from-map-goal-radius-too-big", NO, "arena-from-map {w}/map/map.yaml --out "
     "{w}/a.toml --goal-radius 5", ("goal_radius", "smaller --goal-radius")),
    ("arena-from-map-states-of-another-arena", NO, "arena-from-map {w}/map/map.yaml --out "
     "{w}/a.toml --states {w}/other_states.json", ("other_states.json", "centre 0")),
    ("arena-from-map-start-in-a-wall", NO, "arena-from-map {w}/map/map.yaml --out "
     "{w}/a.toml --start 0.74,0.74,0", ("start", "wall", "--start")),
    ("arena-from-map-start-outside", NO, "arena-from-map {w}/map/map.yaml --out "
     "{w}/a.toml --start 50,0,0", ("start", "outside the map")),
    ("arena-from-map-start-state-without-states", NO, "arena-from-map {w}/map/map.yaml "
     "--out {w}/a.toml --start-state 3", ("start_state", "--states")),
    ("arena-from-map-start-state-beyond", NO, "arena-from-map {w}/map/map.yaml --out "
     "{w}/a.toml --states {w}/states.json --start-state 25", ("start_state", "[0, 24]")),
    # ---- import-log: outputs in the way, an output that is an input
    ("import-log-out-is-a-file", NO, "import-log {w}/log.txt --states {w}/states.json "
     "--out {w}/counts.csv", ("counts.csv", "not a directory")),
    ("import-log-out-is-the-log", NO, "import-log {w}/log.txt --states {w}/states.json "
     "--out {w}/log.txt --overwrite", ("log.txt",)),
    ("import-log-out-holds-the-inputs", NO, "import-log {w}/log.txt --states {w}/states.json "
     "--out {w} --overwrite", ("not a dataset",)),
    ("import-log-out-has-a-dataset", NO, "import-log {w}/log.txt --states {w}/states.json "
     "--out {w}/data", ("data", "--overwrite")),
    # ---- a count of states the arena cannot hold: before the mapping
    ("pipeline-states-beyond-the-floor", NO, "pipeline --states 100000 --out {w}/p "
     "--no-progress", ("states", "100000", "pixels")),
    # ---- options files: long option names work as keys (train's repeatable --param)
    ("train-param-in-config-bad", _write("c.toml", 'param = ["tau"]\n'),
     "train --mdp {w}/mdp.npz --config {w}/c.toml --episodes 2 --runs 1 --out {w}/t "
     "--no-progress", ("c.toml", "param", "KEY=VALUE")),
]


@pytest.mark.parametrize(("case", "setup", "argv", "needles"), CASES,
                         ids=[c[0] for c in CASES])
def test_bad_input_is_one_line_exit_2_and_nothing_changes(
        case: str, setup: Callable[[Path], None] | None, argv: str, needles: tuple[str, ...],
        work: Path, capsys: pytest.CaptureFixture[str]) -> None:
    if setup is not None:
        setup(work)
    before = tree_hashes(work)
    res = run_cli(argv.format(w=work).split(), capsys)
    assert_refused(res, *needles)
    assert ".check" not in res.stderr and ".simlab-staging" not in res.stderr  # ours, hidden
    assert tree_hashes(work) == before
    assert not [p for p in work.rglob(".*") if p.name != ".gitkeep"]  # no hidden leftovers


def test_train_overwrite_retires_its_own_stale_goals_and_nothing_else(work: Path,
                                                                       capsys) -> None:
    (work / "q" / "q_mine.npz").write_bytes(b"the user's")  # not listed by train's summary
    res = run_cli(f"train --mdp {work}/mdp.npz --goals N,S --episodes 2 --runs 1 --no-plots "
                  f"--out {work}/q --overwrite --no-progress".split(), capsys)
    assert res.code == 0, res.stderr
    assert sorted(p.name for p in (work / "q").glob("q_*.npz")) == ["q_N.npz", "q_S.npz",
                                                                     "q_mine.npz"]
    assert (work / "q" / "q_mine.npz").read_bytes() == b"the user's"


def test_train_overwrite_with_a_relative_out_retires_the_stale_goals_too(
        work: Path, capsys, monkeypatch) -> None:
    """``--out q`` from the folder that holds it (the way a user types it): the first run's
    Q-tables of the goals not trained again went unretired (the summary lists ``q/q_C.npz``,
    which was taken relative to ``q`` a second time)."""
    monkeypatch.chdir(work)
    res = run_cli("train --mdp mdp.npz --goals N,S --episodes 2 --runs 1 --no-plots "
                  "--out q --overwrite --no-progress".split(), capsys)
    assert res.code == 0, res.stderr
    assert sorted(p.name for p in (work / "q").glob("q_*.npz")) == ["q_N.npz", "q_S.npz"]
    res = run_cli("train --mdp mdp.npz --goals N --episodes 2 --runs 1 --no-plots "
                  "--out ./q --overwrite --no-progress".split(), capsys)
    assert res.code == 0, res.stderr
    assert sorted(p.name for p in (work / "q").glob("q_*.npz")) == ["q_N.npz"]


def test_a_failed_overwrite_retires_nothing(work: Path, capsys, monkeypatch) -> None:
    before = tree_hashes(work)
    real = os.fsync
    monkeypatch.setattr(os, "fsync", failing(errno.ENOSPC, 1, real))
    res = run_cli(f"train --mdp {work}/mdp.npz --goals N --episodes 2 --runs 1 --no-plots "
                  f"--out {work}/q --overwrite --no-progress".split(), capsys)
    monkeypatch.setattr(os, "fsync", real)
    assert_refused(res, "no space left")
    assert tree_hashes(work) == before


def test_train_reads_param_from_an_options_file_like_the_command_line(work: Path,
                                                                      capsys) -> None:
    (work / "c.toml").write_text('param = ["tau=0.25"]\n')
    res = run_cli(f"train --mdp {work}/mdp.npz --config {work}/c.toml --goals N --episodes 2 "
                  f"--runs 1 --no-plots --out {work}/t --no-progress".split(), capsys)
    assert res.code == 0, res.stderr
    summary = json.loads((work / "t" / "summary.json").read_text())
    assert summary["config"]["tau"] == 0.25


def test_import_log_on_a_full_disk_leaves_no_parts_and_the_rerun_works(
        work: Path, capsys, monkeypatch) -> None:
    argv = f"import-log {work}/log.txt --states {work}/states.json --out {work}/il".split()
    (work / "il").mkdir()  # the user's empty folder stays, and stays empty
    real = os.fsync
    monkeypatch.setattr(os, "fsync", failing(errno.ENOSPC, 2, real))
    # the log's 8 decisions in parts of 10 rows: one part, then the manifest fails
    assert_refused(run_cli(argv, capsys), "no space left")
    monkeypatch.setattr(os, "fsync", real)
    assert list((work / "il").iterdir()) == []
    res = run_cli(argv, capsys)
    assert res.code == 0, res.stderr
    assert (work / "il" / "_manifest.json").is_file()


@pytest.mark.parametrize("nth", [1, 3])
def test_social_pipeline_on_a_full_disk_names_the_file_and_keeps_the_old_outputs(
        nth: int, work: Path, capsys, monkeypatch) -> None:
    argv = (f"social-pipeline --out {work}/sp --hours 0.002 --runs 1 --trials 200 "
            "--gif-decisions 2 --overwrite").split()
    (work / "sp").mkdir()
    (work / "sp" / "summary.json").write_text("{}")  # the previous run's, to be kept
    before = tree_hashes(work)
    real = os.fsync
    monkeypatch.setattr(os, "fsync", failing(errno.ENOSPC, nth, real))
    res = run_cli(argv, capsys)
    monkeypatch.setattr(os, "fsync", real)
    assert_refused(res, "no space left", f"{work}/sp/")
    assert tree_hashes(work) == before
    assert [p.name for p in (work / "sp").iterdir()] == ["summary.json"]


def test_import_log_rerun_after_a_kill_removes_the_killed_runs_parts(work: Path,
                                                                     capsys) -> None:
    argv = f"import-log {work}/log.txt --states {work}/states.json --out {work}/il".split()
    assert run_cli(argv, capsys).code == 0
    (work / "il" / "_manifest.json").unlink()  # killed after its parts, before its manifest
    assert list((work / "il" / "parts").iterdir())
    res = run_cli(argv, capsys)
    assert res.code == 0, res.stderr
    assert (work / "il" / "_manifest.json").is_file()
    (work / "il" / "_manifest.json").unlink()
    (work / "il" / "notes.txt").write_text("mine")  # not only parts: not ours to remove
    res = run_cli(argv, capsys)
    assert_refused(res, "notes.txt", "not replacing it")
    assert "--overwrite" not in res.stderr  # the hint is given only when it would work
    assert (work / "il" / "notes.txt").read_text() == "mine"
