"""The command configs of collect, estimate, train and map: generated CLI, TOML, checks."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from simlab.base.actions import parse_action_set
from simlab.base.errors import ConfigError
from simlab.data.collect import CollectConfig
from simlab.data.estimate import EstimateConfig
from simlab.orchestration.mapping import MapConfig
from simlab.training.train import TrainConfig, TrainTask


def _parse(cls, argv):
    parser = argparse.ArgumentParser()
    cls.add_arguments(parser)
    return cls.from_args(parser.parse_args(argv)), parser.format_help()


def test_collect_flags_toml_and_primitive_group(tmp_path: Path) -> None:
    cfg, text = _parse(CollectConfig, ["--states", "s.json", "--out", "d", "--hours", "2",
                                       "--drive-time", "0.7", "--no-progress"])
    assert (cfg.states, cfg.out, cfg.hours, cfg.progress) == ("s.json", Path("d"), 2.0, False)
    assert cfg.part_size == 250 and "(default 250)" in text and "--max-drive-time" in text
    assert cfg.resolved_params().drive_time == 0.7
    toml = tmp_path / "c.toml"
    toml.write_text('states = "s.json"\nout = "d"\nhours = 2.0\ndrive_time = 0.7\n'
                    'progress = false\n')
    assert CollectConfig.from_toml(toml) == cfg
    with pytest.raises(ConfigError, match="exactly one budget"):
        CollectConfig(states="s.json", out="d", hours=1.0, transitions=10)
    with pytest.raises(ConfigError, match="physics simulator only"):
        CollectConfig(states="s.json", out="d", hours=1.0, simulator="kinematic", slow_speed=0.1)


def test_estimate_action_set_group() -> None:
    cfg, _ = _parse(EstimateConfig, ["--counts", "c.csv", "--out", "m.npz", "--n-actions", "8",
                                     "--convention", "ccw-east"])
    assert cfg.table_action_set() == parse_action_set(8, "ccw-east")
    assert EstimateConfig(counts="c.csv", out="m.npz").table_action_set().n_actions == 16
    with pytest.raises(ConfigError) as info:  # a dataset records its own action set
        EstimateConfig(dataset="d", out="m.npz", n_actions=8)
    assert info.value.key == "n_actions"
    with pytest.raises(ConfigError, match="unknown rule"):
        EstimateConfig(counts="c.csv", out="m.npz", unvisited="stay")


def test_train_task_fields_become_a_train_task() -> None:
    cfg, text = _parse(TrainConfig, ["--mdp", "m.npz", "--out", "o", "--task", "episodic",
                                     "--goal-states", "18,19", "--bounds", "0", "0", "1", "1"])
    assert cfg.task == TrainTask(mode="episodic", goal_states=(18, 19))
    assert cfg.bounds == (0.0, 0.0, 1.0, 1.0) and "(default 2000)" in text
    with pytest.raises(ConfigError, match="goals or goal_states"):
        TrainConfig(mdp="m.npz", goals="C", goal_states="3")
    with pytest.raises(ConfigError):
        TrainConfig(mdp="m.npz", bounds=(0.0, 1.0))


def test_map_out_defaults_to_the_arena_stem() -> None:
    cfg, _ = _parse(MapConfig, ["--arena", "arenas/lab.toml", "--minutes", "2"])
    assert cfg.out == Path("maps/lab") and cfg.minutes == 2.0
    with pytest.raises(ConfigError, match="minutes"):
        MapConfig(minutes=0.0)
