"""The replay's recorder, typed summary and config, without physics."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.replay.config import ReplayConfig
from simlab.replay.loop import Recorder
from simlab.replay.summary import BaselineStats, Comparison, comparison, run_stats


def _step(i: int, blocked: bool = False) -> SimpleNamespace:
    pose = np.array([0.1 * i, 0.0, 0.0])
    res = SimpleNamespace(duration=0.5 + i, blocked=blocked, pose_after=pose + 0.1,
                          odom_after=pose + 0.2)
    return SimpleNamespace(result=res, action=i, state_before=i, state_after=i + 1,
                           truth_before=pose, pose_before=pose + 0.3, pose_after=pose + 0.4)


def test_recorder_owns_the_columns() -> None:
    rec = Recorder()
    empty = rec.log(latency=3.0)
    assert empty.n == 0 and empty.truth_after.shape == (0, 3) and empty.s.dtype == np.int64
    for i in range(3):
        rec.record(t=10.0 * i, step=_step(i, blocked=i == 1), goal=2, reward=int(i == 2),
                   s_true_next=i + 1)
    log = rec.log(latency=3.0)
    assert len(rec) == log.n == 3
    np.testing.assert_array_equal(log.a, [0, 1, 2])
    np.testing.assert_array_equal(log.s_next, log.s + 1)
    np.testing.assert_array_equal(log.blocked, [False, True, False])
    np.testing.assert_allclose(log.est_after[:, 0], [0.4, 0.5, 0.6])
    np.testing.assert_allclose(log.odom_after[:, 0], [0.2, 0.3, 0.4])
    np.testing.assert_allclose(log.reward_times, [20.0 + 2.5 + 3.0])  # t + duration + latency
    assert log.t.dtype == np.float64 and log.truth_before.shape == (3, 3)


def test_summary_numbers_and_comparison_keys() -> None:
    rec = Recorder()
    for i in range(4):
        rec.record(t=float(i), step=_step(i), goal=0, reward=int(i % 2), s_true_next=i + 1)
    run = SimpleNamespace(log=rec.log(1.0), robot_seconds=1800.0, stepped_seconds=1000.0,
                          wall_seconds=0.0, blocked_retries=1, escapes=0, returns_to_start=0)
    stats = run_stats(run, ("C",))
    assert (stats.rewards, stats.rate_per_hour, stats.reward_per_transition) == (2, 4.0, 0.5)
    assert stats.goals_reached == {"C": 2} and stats.real_time_factor_robot is None
    alone = comparison(stats, None, None)
    assert alone.to_json() == {"rate_per_hour": 4.0}
    base = BaselineStats("physics", 0.5, dataclasses.replace(stats, rate_per_hour=0.0))
    pred = {"rate_per_hour": 5.0, "reward_per_transition": 0.25, "n_closed_classes": 1,
            "expected_rewards_over_horizon": 0.0}
    full = comparison(stats, base, pred)
    assert full.ratio_to_random is None  # a random rate of 0: undefined, not infinite
    assert full.measured_over_predicted == pytest.approx(0.8) and full.within_25_percent
    assert list(full.to_json()) == [
        "rate_per_hour", "random_rate_per_hour", "ratio_to_random",
        "predicted_rate_per_hour", "measured_over_predicted", "within_25_percent",
        "reward_per_transition_measured_over_predicted",
        "rewards_measured_over_expected_over_horizon"]
    assert full.to_json()["rewards_measured_over_expected_over_horizon"] is None
    assert "warning" in comparison(stats, None, {**pred, "n_closed_classes": 2}).to_json()
    assert Comparison(rate_per_hour=1.0).random_rate_per_hour is None


def test_config_from_toml_names_the_file(tmp_path: Path) -> None:
    good = tmp_path / "replay.toml"
    good.write_text('states = "s.json"\nqtables = "q"\nhours = 1\npose-source = "odometry"\n')
    cfg = ReplayConfig.from_toml(good)
    assert (cfg.hours, cfg.pose_source, cfg.baseline) == (1.0, "odometry", 1.0)
    for text, key in (('qtables = "q"\nhours = 0\n', "hours"),
                      ('qtables = "q"\npose_source = "gps"\n', "pose_source"),
                      ('qtables = "q"\nepsilon = 2.0\n', "epsilon"),
                      ('qtables = "q"\nseed = 1.5\n', "seed"),
                      ('hours = 1.0\n', "qtables"),  # a greedy replay needs Q-tables
                      ('qtables = "q"\nhour = 1.0\n', "hour")):
        bad = tmp_path / "bad.toml"
        bad.write_text(text)
        with pytest.raises(ConfigError) as info:
            ReplayConfig.from_toml(bad)
        assert info.value.key == key and "bad.toml" in str(info.value)
