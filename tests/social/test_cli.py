"""``simlab social-pipeline`` end to end on a tiny budget, and its refusals."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from simlab.cli import main

TINY = ["--hours", "0.02", "--runs", "1", "--trials", "500", "--gif-decisions", "3"]


def test_social_pipeline_cli_writes_its_outputs_and_refuses_to_overwrite(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "social"
    assert main(["social-pipeline", "--out", str(out), *TINY]) == 0
    printed = capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    combined = summary["pooled"]["combined"]
    assert f"combined: {combined['goals']} goal areas" in printed
    assert summary["config"]["runs"] == 1 and summary["config"]["hours"] == 0.02
    assert combined["hours"] == pytest.approx(0.02, rel=0.2)
    for name in ("summary.json", "cumulative_goals.png", "closed_loop.gif", "social_q.npy"):
        assert (out / name).is_file(), name
    before = (out / "summary.json").read_bytes()
    assert main(["social-pipeline", "--out", str(out), *TINY]) == 2
    assert "overwrite" in capsys.readouterr().err
    assert (out / "summary.json").read_bytes() == before


@pytest.mark.parametrize(("argv", "needle"), [
    (["--hours", "-1"], "hours"),
    (["--runs", "0"], "runs"),
    (["--human", "nosuch"], "nosuch"),
])
def test_social_pipeline_bad_options_are_one_line_exit_2(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], needle: str) -> None:
    out = tmp_path / "x"
    assert main(["social-pipeline", "--out", str(out), *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and len(err.splitlines()) == 1
    assert not out.exists()
