"""Bad input to ``simlab online``: one error line naming the file or field, exit 2, and
nothing written or changed."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from .conftest import assert_refused, run_cli, tree_hashes


@pytest.fixture()
def ws(tmp_path: Path) -> Path:
    """A workspace with a valid 4-state mdp.npz (chain, goal 3)."""
    from simlab.agents.storage import load_npz  # noqa: F401  (the reader the command uses)
    from simlab.base.io import atomic_write

    T = np.zeros((4, 2, 4))
    for s in range(4):
        T[s, 1, min(s + 1, 3)] = 1.0
        T[s, 0, max(s - 1, 0)] = 1.0
    with atomic_write(tmp_path / "mdp.npz", "wb") as fh:
        np.savez(fh, T=T, meta_json=np.array(json.dumps({})))
    return tmp_path


def _ok_args(ws: Path) -> list[str]:
    return ["online", str(ws / "mdp.npz"), "--goal", "3", "--start-states", "0",
            "--decisions", "20", "--seeds", "1", "--workers", "1", "--no-progress",
            "--no-plots"]


def test_the_workspace_runs(ws: Path, capsys) -> None:
    res = run_cli([*_ok_args(ws), "--out", str(ws / "out")], capsys)
    assert res.code == 0, res.stderr
    assert (ws / "out" / "summary.json").is_file()


@pytest.mark.parametrize(("setup", "extra", "needles"), [
    # an unknown key of the options file
    (lambda ws: (ws / "o.toml").write_text('decisionz = 5\n'),
     ["--config", "o.toml"], ["o.toml", "decisionz"]),
    # a bad value in the options file
    (lambda ws: (ws / "o.toml").write_text('criteria = ["coin"]\n'),
     ["--config", "o.toml"], ["o.toml", "criteria"]),
    # an expert override the agent does not have
    (lambda ws: (ws / "o.toml").write_text('[mb_params]\nbeta = 50\n'),
     ["--config", "o.toml"], ["mb_params.beta"]),
    # a goal state outside the MDP
    (None, ["--goal", "9"], ["mdp.npz", "goal"]),
    # a change after the end of the run
    (None, ["--change", "goal", "--change-at", "50", "--new-goal", "0"], ["change_at"]),
    # a passage written wrong
    (None, ["--change", "passages", "--change-at", "5", "--passages", "1_2"], ["passages"]),
    # a passage between states the chain never moves between: closing it would change nothing
    (None, ["--change", "passages", "--change-at", "5", "--passages", "0-3"],
     ["mdp.npz", "passages", "no passage 0-3", "neighbouring"]),
])
def test_bad_options_are_refused_before_anything_is_written(ws, monkeypatch, capsys, setup,
                                                            extra, needles) -> None:
    monkeypatch.chdir(ws)
    if setup is not None:
        setup(ws)
    before = tree_hashes(ws)
    res = run_cli([*_ok_args(ws), "--out", str(ws / "out"), *extra], capsys)
    assert_refused(res, *needles)
    assert tree_hashes(ws) == before and not (ws / "out").exists()


def test_missing_model_file(ws: Path, capsys) -> None:
    before = tree_hashes(ws)
    args = _ok_args(ws)
    args[1] = str(ws / "nope.npz")
    res = run_cli([*args, "--out", str(ws / "out")], capsys)
    assert_refused(res, "nope.npz")
    assert tree_hashes(ws) == before and not (ws / "out").exists()


def test_broken_model_file(ws: Path, capsys) -> None:
    (ws / "mdp.npz").write_bytes(b"not a zip")
    before = tree_hashes(ws)
    res = run_cli([*_ok_args(ws), "--out", str(ws / "out")], capsys)
    assert_refused(res, "mdp.npz")
    assert tree_hashes(ws) == before


def test_output_in_the_way(ws: Path, capsys) -> None:
    (ws / "out").write_text("a file, not a directory")
    before = tree_hashes(ws)
    res = run_cli([*_ok_args(ws), "--out", str(ws / "out")], capsys)
    assert_refused(res, "out")
    assert tree_hashes(ws) == before


def test_existing_outputs_are_kept_and_overwrite_needs_our_marker(ws: Path, capsys) -> None:
    out = ws / "out"
    out.mkdir()
    (out / "summary.json").write_text('{"someone": "else"}')
    before = tree_hashes(ws)
    res = run_cli([*_ok_args(ws), "--out", str(out)], capsys)
    assert_refused(res, "summary.json", "already exists")
    assert tree_hashes(ws) == before
    res = run_cli([*_ok_args(ws), "--out", str(out), "--overwrite"], capsys)
    assert_refused(res, "overwrite")
    assert tree_hashes(ws) == before


def test_missing_out(ws: Path, capsys) -> None:
    before = tree_hashes(ws)
    res = run_cli(_ok_args(ws), capsys)
    assert_refused(res, "--out")
    assert tree_hashes(ws) == before
