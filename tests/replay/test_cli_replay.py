"""``simlab replay`` end to end through the CLI, and its one-line errors."""

from __future__ import annotations

import json
import shutil

from simlab.cli import main


def test_cli_replay_runs_and_writes_the_summary(chain, tmp_path, capsys) -> None:
    out = tmp_path / "out"
    code = main(["replay", "--arena", "table", "--states", str(chain.states), "--qtables",
                 str(chain.qtables), "--hours", "0.02", "--baseline-hours", "0.02",
                 "--seed", "1", "--out", str(out), "--no-progress"])
    assert code == 0
    printed = capsys.readouterr().out
    summary = json.loads((out / "replay.json").read_text())
    assert f"{summary['result']['rewards']} goals" in printed
    assert "MDP-predicted" in printed and "random policy" in printed
    assert (out / "cumulative_reward.png").is_file()


def test_cli_missing_goal_is_one_line_and_exit_2(chain, tmp_path, capsys) -> None:
    qdir = tmp_path / "q"
    shutil.copytree(chain.qtables, qdir)
    (qdir / "q_NW.npz").unlink()
    code = main(["replay", "--states", str(chain.states), "--qtables", str(qdir),
                 "--hours", "0.01", "--out", str(tmp_path / "o"), "--no-progress"])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1
    assert err.startswith("simlab replay: error:") and "q_NW.npz" in err
    assert not (tmp_path / "o").exists()


def test_cli_missing_states_file(tmp_path, capsys) -> None:
    code = main(["replay", "--states", str(tmp_path / "none.json"), "--random",
                 "--hours", "0.01", "--out", str(tmp_path / "o"), "--no-progress"])
    assert code == 2
    assert "none.json" in capsys.readouterr().err


def test_cli_summary_with_no_predicted_reward_prints_instead_of_crashing(monkeypatch, tmp_path,
                                                                        capsys) -> None:
    """An under-trained Q-table makes the MDP predict 0 goals/h: the ratio is undefined (None)."""
    from types import SimpleNamespace

    import simlab.replay.replay as replay_module

    summary = {
        "policy": "greedy", "pose_source": "truth",
        "result": {"rewards": 0, "robot_seconds": 360.0, "transitions": 80,
                   "rate_per_hour": 0.0, "wall_seconds": 1.0},
        "comparison": {"predicted_rate_per_hour": 0.0, "measured_over_predicted": None},
        "localization": {}, "files": {"summary": "replay.json", "plot": "plot.png"},
    }
    monkeypatch.setattr(replay_module, "replay", lambda **kw: SimpleNamespace(summary=summary))
    code = main(["replay", "--states", "s.json", "--out", str(tmp_path / "o"), "--no-progress"])
    assert code == 0
    assert "measured/predicted: undefined" in capsys.readouterr().out
