"""``simlab pipeline`` end to end on a tiny budget, and its resume rules."""

from __future__ import annotations

import json

import pytest

from simlab.cli import main
from simlab.errors import ConfigError
from simlab.pipeline import STAGES, PipelineConfig, pipeline

TINY = ["--map-minutes", "2", "--hours", "0.3", "--workers", "1", "--episodes", "60",
        "--runs", "1", "--replay-hours", "0.05", "--pose-source", "truth", "--no-video",
        "--no-progress"]


def test_pipeline_cli_end_to_end_and_resume(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["pipeline", "--out", str(out), *TINY]) == 0
    log = capsys.readouterr().out
    assert all(f"{name}:" in log for name in STAGES)
    state = json.loads((out / "pipeline.json").read_text())
    assert list(state["stages"]) == list(STAGES)
    assert state["stages"]["states"]["states"] == 41
    replay = state["stages"]["replay"]
    assert replay["reward_rate_per_hour"] >= 0
    report = (out / "report.md").read_text()
    for needle in ("Markov states", "random-walk transitions", "mean transition entropy",
                   "states/states.png", "mdp/mdp_entropy.png", "replay/cumulative_reward.png"):
        assert needle in report
    for rel in ("map/map.yaml", "states/states.json", "mdp/mdp.npz", "qtables/q_C.npz",
                "replay/replay.json", "replay/cumulative_reward.png", "states/states_visits.png"):
        assert (out / rel).is_file(), rel

    # a second run into the same folder is refused; --resume skips every finished stage
    assert main(["pipeline", "--out", str(out), *TINY]) == 2
    assert "--resume" in capsys.readouterr().err
    before = (out / "mdp" / "mdp.npz").stat().st_mtime_ns
    assert main(["pipeline", "--out", str(out), "--resume", *TINY]) == 0
    assert capsys.readouterr().out.count("done earlier, skipped") == len(STAGES)
    assert (out / "mdp" / "mdp.npz").stat().st_mtime_ns == before
    # resuming with other settings would mix two experiments
    changed = [*TINY]
    changed[changed.index("--hours") + 1] = "0.4"
    assert main(["pipeline", "--out", str(out), "--resume", *changed]) == 2
    assert "hours" in capsys.readouterr().err


def test_pipeline_settings_are_validated(tmp_path):
    with pytest.raises(ConfigError, match="hours: expected a number > 0"):
        PipelineConfig(hours=0)
    with pytest.raises(ConfigError, match="pose_source"):
        PipelineConfig(pose_source="gps")
    with pytest.raises(ConfigError, match="unexpected keyword"):
        pipeline("table", tmp_path / "x", log=None, hourz=1)
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "keep.txt").write_text("user data")
    with pytest.raises(ConfigError, match="not empty"):
        pipeline("table", tmp_path / "full", log=None)
    assert (tmp_path / "full" / "keep.txt").read_text() == "user data"
