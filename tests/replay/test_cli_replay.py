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
    from simlab.physics.rate import DEFAULT_HZ
    from simlab.replay.summary import Comparison

    summary = SimpleNamespace(
        policy="greedy", pose_source="truth",
        result=SimpleNamespace(rewards=0, robot_seconds=360.0, transitions=80,
                               rate_per_hour=0.0, wall_seconds=1.0),
        comparison=Comparison(rate_per_hour=0.0, predicted_rate_per_hour=0.0,
                              measured_over_predicted=None),
        localization={}, files={"summary": "replay.json", "plot": "plot.png"},
        physics={"hz": DEFAULT_HZ, "solver_iterations": 5, "source": "default"},
    )
    seen = []
    monkeypatch.setattr(replay_module, "replay",
                        lambda cfg: seen.append(cfg) or SimpleNamespace(summary=summary))
    code = main(["replay", "--states", "s.json", "--qtables", "q", "--out",
                 str(tmp_path / "o"), "--no-progress"])
    assert code == 0
    assert "measured/predicted: undefined" in capsys.readouterr().out
    assert seen[0].states == "s.json" and seen[0].progress is False


def test_cli_options_are_the_config_fields(tmp_path) -> None:
    """--random is --policy random; --config FILE gives options, the command line wins;
    the primitive flags become params."""
    import argparse
    from pathlib import Path

    from simlab.cli.replay import add_arguments, config_from_args
    from simlab.replay.config import ReplayConfig

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    toml = tmp_path / "replay.toml"
    toml.write_text('states = "s.json"\nout = "o"\nhours = 0.5\npose-source = "mcl"\n'
                    'epsilon = 0.1\n')
    cfg = config_from_args(parser.parse_args(["--config", str(toml), "--random",
                                              "--hours", "2", "--decision-latency", "1.5"]))
    assert (cfg.states, cfg.out, cfg.hours, cfg.pose_source, cfg.policy, cfg.epsilon) == (
        "s.json", Path("o") if isinstance(cfg.out, Path) else "o", 2.0, "mcl", "random", 0.1)
    assert cfg.params.decision_latency == 1.5
    assert cfg.baseline == 0.0  # a random replay has no random baseline
    plain = config_from_args(parser.parse_args(["--states", "s.json", "--qtables", "q",
                                                "--out", "o"]))
    assert plain == ReplayConfig(states="s.json", qtables="q", out="o")
    assert plain.policy == "greedy" and plain.params is None and plain.baseline == 3.0


def test_cli_requires_states_and_out(tmp_path, capsys) -> None:
    code = main(["replay", "--qtables", "q", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "--states" in err
    code = main(["replay", "--states", "s.json", "--random"])
    assert code == 2 and "--out" in capsys.readouterr().err


def test_cli_replay_records_its_primitives_file_and_predicts_no_rate_when_driving_back(
        chain, tmp_path, capsys) -> None:
    from simlab.physics.motion import PrimitiveParams

    prims = tmp_path / "robot.toml"
    prims.write_text(PrimitiveParams().toml_text())
    out = tmp_path / "out"
    code = main(["replay", "--states", str(chain.states), "--qtables", str(chain.qtables),
                 "--primitives", str(prims), "--return-to-start", "--hours", "0.02",
                 "--baseline-hours", "0", "--out", str(out), "--no-progress"])
    assert code == 0
    printed = capsys.readouterr().out
    summary = json.loads((out / "replay.json").read_text())
    assert summary["primitives_file"] == str(prims)
    assert summary["primitive_params_source"] == "given"  # the chain's data record none
    assert "not_predicted" in summary["prediction"] and "greedy" not in summary["prediction"]
    assert "predicted_rate_per_hour" not in summary
    assert "MDP-predicted: none" in printed and "measured/predicted" not in printed
