"""``simlab pipeline`` end to end on a tiny budget, and its resume rules."""

from __future__ import annotations

import json

import pytest

from simlab.base.errors import ConfigError
from simlab.cli import main
from simlab.orchestration.pipeline import STAGES, pipeline
from simlab.orchestration.stages import PhysicsSettings

TINY = ["--map-minutes", "2", "--hours", "0.3", "--workers", "1", "--episodes", "60",
        "--runs", "1", "--replay-hours", "0.05", "--pose-source", "truth", "--no-video",
        "--no-progress"]


def _state(out):
    return json.loads((out / "pipeline.json").read_text())


@pytest.mark.slow
def test_pipeline_cli_end_to_end_and_resume(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["pipeline", "--out", str(out), *TINY]) == 0
    log = capsys.readouterr().out
    assert all(f"{name}:" in log for name in STAGES) and "report.md" in log
    state = _state(out)
    assert list(state["stages"]) == list(STAGES)
    assert all(rec["built"] for rec in state["stages"].values())
    assert state["stages"]["states"]["n_states"] == 41
    # the stage record carries the replay's own rate: rewards over robot hours
    replay_result = json.loads((out / "replay" / "replay.json").read_text())["result"]
    hours = replay_result["robot_seconds"] / 3600.0
    assert hours > 0 and replay_result["transitions"] > 0
    # ... and the rewards it counts are the goal rewards of the replay's own transition log
    import pyarrow.parquet as pq

    log = pq.read_table(out / "replay" / "transitions.parquet", columns=["reward"])
    assert log.num_rows == replay_result["transitions"]
    assert replay_result["rewards"] == int(log.column("reward").to_numpy().sum())
    assert state["stages"]["replay"]["reward_rate_per_hour"] == pytest.approx(
        replay_result["rewards"] / hours)
    report = (out / "report.md").read_text()
    for needle in ("Markov states", "random-walk transitions", "mean transition entropy",
                   "states/states.png", "mdp/mdp_entropy.png", "replay/cumulative_reward.png"):
        assert needle in report
    for rel in ("map/map.yaml", "states/states.json", "mdp/mdp.npz", "qtables/q_C.npz",
                "replay/replay.json", "replay/cumulative_reward.png", "dataset/data",
                "figures/states_visits.png"):
        assert (out / rel).exists(), rel
    # the visits figure was drawn by the lent warm-up worker: the same image as drawn here
    from simlab.orchestration.pipeline import _visits_figure

    png = out / "figures" / "states_visits.png"
    drawn_by_worker = png.read_bytes()
    _visits_figure(out)
    assert png.read_bytes() == drawn_by_worker and drawn_by_worker[:4] == b"\x89PNG"
    assert state["warmup"]["ok"] and state["warmup"]["wait_seconds"] >= 0

    # a second run into the same folder is refused; --resume reuses every stage
    assert main(["pipeline", "--out", str(out), *TINY]) == 2
    assert "--resume" in capsys.readouterr().err
    mdp_before = (out / "mdp" / "mdp.npz").stat().st_mtime_ns
    assert main(["pipeline", "--out", str(out), "--resume", *TINY]) == 0
    assert capsys.readouterr().out.count("(reused)") == len(STAGES)
    assert (out / "mdp" / "mdp.npz").stat().st_mtime_ns == mdp_before

    # changing the walk's length rebuilds the walk and what depends on it, not the map
    changed = [*TINY]
    changed[changed.index("--hours") + 1] = "0.4"
    assert main(["pipeline", "--out", str(out), "--resume", *changed]) == 0
    built = {name: rec["built"] for name, rec in _state(out)["stages"].items()}
    assert built == {"map": False, "states": False, "dataset": True, "mdp": True,
                     "train": True, "replay": True}
    assert _state(out)["stages"]["dataset"]["simulated_hours"] == pytest.approx(0.4, rel=0.05)


def test_pipeline_settings_are_validated(tmp_path):
    with pytest.raises(ConfigError, match="hours: expected a finite number > 0"):
        PhysicsSettings.create(hours=0)
    with pytest.raises(ConfigError, match="pose_source"):
        PhysicsSettings.create(pose_source="gps")
    with pytest.raises(ConfigError, match=r"unknown option.*hourz"):
        pipeline("table", tmp_path / "x", log=None, hourz=1)
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "keep.txt").write_text("user data")
    with pytest.raises(ConfigError, match="not empty"):
        pipeline("table", tmp_path / "full", log=None)
    assert (tmp_path / "full" / "keep.txt").read_text() == "user data"


def test_pipeline_primitives_file_is_read_checked_and_part_of_the_dataset_key(tmp_path):
    good = tmp_path / "primitives.toml"
    good.write_text("[primitives]\ndrive_time = 0.8\nwheel_noise = 0.05\n")
    s = PhysicsSettings.create(primitives=str(good))
    params = s.primitive_params()
    assert params.drive_time == 0.8 and params.wheel_noise == 0.05
    assert PhysicsSettings.create().primitive_params() is None  # built-in primitives
    bad = tmp_path / "bad.toml"
    bad.write_text("[primitives]\nwarp = 9\n")
    with pytest.raises(ConfigError, match="warp"):
        PhysicsSettings.create(primitives=str(bad))
    # refused before any work: nothing is created
    with pytest.raises(ConfigError, match="warp"):
        pipeline("table", tmp_path / "run", log=None, primitives=str(bad))
    assert not (tmp_path / "run").exists()
    assert main(["pipeline", "--out", str(tmp_path / "run2"), "--primitives",
                 str(tmp_path / "nope.toml")]) == 2
    assert not (tmp_path / "run2").exists()
