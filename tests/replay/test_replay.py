"""The closed-loop replay in physics (short budgets): bookkeeping, policy, outputs."""

from __future__ import annotations

import json
import math

import numpy as np
import pyarrow.parquet as pq
import pytest

from simlab.base.errors import ConfigError
from simlab.replay.prediction import greedy_ties
from simlab.replay.replay import drive_to_pose, greedy_action, replay


@pytest.fixture(scope="module")
def truth_run(chain, tmp_path_factory):
    out = tmp_path_factory.mktemp("replay") / "truth"
    return replay("table", chain.states, chain.qtables, hours=0.25, pose_source="truth",
                  seed=3, out=out, progress=False)


def test_outputs_and_summary(truth_run) -> None:
    files = truth_run.files
    for key in ("summary", "plot", "transitions"):
        assert files[key].is_file()
    assert files["plot"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    summary = json.loads(files["summary"].read_text())
    assert summary == json.loads(json.dumps(truth_run.summary.to_json()))
    table = pq.read_table(files["transitions"])
    assert table.num_rows == summary["result"]["transitions"] == truth_run.run.log.n
    assert summary["prediction"]["pace_source"] == "dataset"
    assert summary["reward_rate_per_hour"] == summary["result"]["rate_per_hour"]
    assert summary["random_rate_per_hour"] == summary["random_baseline"]["rate_per_hour"]
    assert summary["predicted_rate_per_hour"] == summary["prediction"]["greedy"]["rate_per_hour"]
    assert "position_error_mean_m" not in summary  # truth poses
    greedy = summary["prediction"]["greedy"]
    assert greedy["horizon_transitions"] == summary["result"]["transitions"]
    assert 0 < greedy["expected_rewards_over_horizon"] <= greedy["horizon_transitions"]
    assert summary["primitive_params_source"] == "default"  # kinematic model: no primitives


def test_rewards_goal_switches_and_clock(chain, truth_run) -> None:
    log = truth_run.run.log
    masks = chain.goal_masks
    np.testing.assert_array_equal(log.reward, masks[log.goal, log.s_next].astype(int))
    rewarded = log.reward[:-1] > 0
    # After a reward the goal changes, to another goal; otherwise it stays.
    assert np.all(log.goal[1:][rewarded] != log.goal[:-1][rewarded])
    assert np.all(log.goal[1:][~rewarded] == log.goal[:-1][~rewarded])
    np.testing.assert_array_equal(log.s[1:], log.s_next[:-1])
    # Robot clock: each transition adds its stepped duration and the decision latency.
    np.testing.assert_allclose(log.t[1:], log.t[:-1] + log.duration[:-1] + log.latency)
    run = truth_run.run
    assert run.robot_seconds == pytest.approx(run.stepped_seconds + log.n * log.latency)
    assert log.t[-1] < 0.25 * 3600 <= run.robot_seconds
    # The truth pose source: believed states are the true ones.
    disc = chain.discretizer
    np.testing.assert_array_equal(log.s_next, disc.state_of(log.truth_after[:, :2]))
    np.testing.assert_array_equal(log.s, disc.state_of(log.est_before[:, :2]))


def test_actions_are_greedy_except_counted_deviations(chain, truth_run) -> None:
    log = truth_run.run.log
    Q = np.stack([chain.Q[g] for g in chain.goal_names])
    greedy = greedy_ties(Q[log.goal, log.s])[np.arange(log.n), log.a]
    deviations = truth_run.run.escapes + truth_run.run.blocked_retries
    assert (~greedy).sum() <= deviations
    assert deviations <= 0.1 * log.n


def test_learned_policy_beats_random_by_5x(truth_run) -> None:
    s = truth_run.summary
    rate = s.result.rate_per_hour
    physics_random = s.random_baseline.rate_per_hour
    predicted_random = s.prediction["random"]["rate_per_hour"]
    assert s.random_baseline.stats.transitions > 100
    assert rate >= 5 * max(physics_random, predicted_random)
    assert s.comparison.ratio_to_random is None or s.comparison.ratio_to_random >= 5
    # the headline attributes are the flat numbers of replay.json
    flat = s.to_json()
    assert s.reward_rate_per_hour == flat["reward_rate_per_hour"] == rate
    assert s.random_rate_per_hour == flat["random_rate_per_hour"] == physics_random


def test_mcl_replay_localizes_within_5_cm(chain, tmp_path) -> None:
    res = replay("table", chain.states, chain.qtables, hours=0.08, pose_source="mcl", seed=4,
                 out=tmp_path / "mcl", progress=False, baseline_hours=0)
    loc = res.summary.localization
    assert loc["mcl"]["at_decisions"]["position_mean_m"] < 0.05
    assert res.summary.position_error_mean_m == loc["mcl"]["at_decisions"]["position_mean_m"]
    assert loc["mcl"]["updates"]["n"] > 100
    assert "odometry" in loc
    table = pq.read_table(res.files["localization"])
    assert table.num_rows == loc["mcl"]["updates"]["n"]
    log = res.run.log
    errors = np.hypot(*(log.est_after[:, :2] - log.truth_after[:, :2]).T)
    assert errors.max() < 0.05
    assert res.summary.random_baseline is None and "random_baseline" not in res.summary.to_json()


def test_odometry_replay_steers_by_odometry(chain, tmp_path) -> None:
    res = replay("table", chain.states, chain.qtables, hours=0.03, pose_source="odometry",
                 seed=5, out=tmp_path / "odo", progress=False, baseline_hours=0)
    assert res.summary.primitive_params["heading_source"] == "odometry"
    log = res.run.log
    np.testing.assert_allclose(log.est_after, log.odom_after)


def test_return_to_start_after_each_goal(chain, tmp_path) -> None:
    res = replay("table", chain.states, chain.qtables, hours=0.06, seed=6, out=tmp_path / "r",
                 return_to_start=True, progress=False, baseline_hours=0)
    log = res.run.log
    rewarded = np.flatnonzero(log.reward[:-1] > 0)
    assert len(rewarded) >= 2 and res.run.returns_to_start == int(log.reward.sum())
    start = np.array([0.0, 0.0])
    gaps = np.hypot(*(log.truth_before[rewarded + 1, :2] - start).T)
    assert gaps.max() < 0.04  # drive_to_pose stops within 3 cm
    # The return drives count as robot time.
    assert log.t[rewarded[0] + 1] > log.t[rewarded[0]] + log.duration[rewarded[0]] + log.latency


@pytest.mark.slow
def test_same_seed_same_replay(chain, tmp_path) -> None:
    runs = [replay("table", chain.states, chain.qtables, hours=0.02, seed=seed,
                   out=tmp_path / f"s{i}", progress=False, baseline_hours=0)
            for i, seed in enumerate((8, 8, 9))]
    a, b, c = (pq.read_table(r.files["transitions"]) for r in runs)
    assert a.equals(b)
    assert not a.equals(c)


def test_random_policy_needs_no_qtables(chain, tmp_path) -> None:
    res = replay("table", chain.states, None, hours=0.02, policy="random", mdp=chain.mdp,
                 seed=1, out=tmp_path / "rnd", progress=False)
    assert res.baseline is None and "greedy" not in res.summary.prediction
    assert res.summary.prediction["random"]["rate_per_hour"] > 0


def test_video_gif(chain, tmp_path) -> None:
    import imageio.v3 as iio

    res = replay("table", chain.states, chain.qtables, hours=0.02, seed=2, out=tmp_path / "v",
                 pose_source="mcl", video=True, max_frames=8, progress=False, baseline_hours=0)
    frames = iio.imread(res.files["gif"], index=None)
    assert 2 <= frames.shape[0] <= 8 and frames.shape[-1] == 3
    assert len(res.run.frames) >= frames.shape[0]


def test_existing_outputs_are_refused_before_driving(chain, truth_run) -> None:
    out = truth_run.files["summary"].parent
    before = truth_run.files["summary"].stat().st_mtime_ns
    with pytest.raises(ConfigError, match="already exists"):
        replay("table", chain.states, chain.qtables, hours=0.01, out=out, progress=False)
    assert truth_run.files["summary"].stat().st_mtime_ns == before


@pytest.mark.parametrize("kwargs, match", [
    (dict(hours=0), "hours"),
    (dict(pose_source="gps"), "pose_source"),
    (dict(policy="smart"), "policy"),
    (dict(epsilon=1.5), "epsilon"),
    (dict(escape_radius=-1.0), "escape_radius"),
    (dict(qtables=None), "needs Q-tables"),
    (dict(map="nowhere/map.yaml"), "map file not found"),
])
def test_bad_arguments(chain, tmp_path, kwargs, match) -> None:
    args = dict(arena="table", states=chain.states, qtables=chain.qtables, hours=0.01,
                out=tmp_path / "x", progress=False)
    args.update(kwargs)
    with pytest.raises(ConfigError, match=match):
        replay(**args)
    assert not (tmp_path / "x").exists()


def test_map_of_another_arena_is_refused(chain, tmp_path) -> None:
    from discretize.mapio import write_map
    from simlab.localization.maps import arena_map
    from simlab.physics.arena import load_arena

    yaml_path, _ = write_map(tmp_path / "m" / "map.yaml", arena_map(load_arena("table_obstacles")))
    with pytest.raises(ConfigError) as info:
        replay("table", chain.states, chain.qtables, hours=0.01, map=yaml_path,
               pose_source="mcl", out=tmp_path / "x", progress=False)
    assert str(yaml_path) in str(info.value)


def test_greedy_action_breaks_ties_uniformly_and_respects_exclusions() -> None:
    rng = np.random.default_rng(0)
    q = np.array([0.0, 2.0, 2.0, 1.0, 2.0])
    picks = np.bincount([greedy_action(q, rng) for _ in range(3000)], minlength=5)
    assert picks[[0, 3]].sum() == 0
    # Each of the three tied actions: 1000 expected, binomial sd ~26.
    assert np.all(np.abs(picks[[1, 2, 4]] - 1000) < 4 * math.sqrt(3000 * (1 / 3) * (2 / 3)))
    excluded = np.array([False, True, True, False, True])
    assert greedy_action(q, rng, excluded) == 3


def test_drive_to_pose_reaches_the_target() -> None:
    from simlab.physics.world import World

    with World("table") as world:
        world.reset((0.4, -0.3, 2.0))
        target = np.array([0.0, 0.0, math.pi / 2])
        seconds = drive_to_pose(world, target, world.pose, np.random.default_rng(0))
        p = world.pose()
    assert math.hypot(p[0], p[1]) < 0.03
    assert abs((p[2] - target[2] + math.pi) % (2 * math.pi) - math.pi) < 0.05
    assert 0 < seconds < 60


def test_a_subset_of_goals_and_a_state_id_goal(chain, tmp_path) -> None:
    """--goals: only the named goals are pursued; ``s<id>`` rewards exactly that state."""
    target = int(np.flatnonzero(chain.goal_masks[chain.goal_names.index("C")])[0])
    qtables = {"NE": chain.Q["NE"], f"s{target}": chain.Q["C"]}
    res = replay("table", chain.states, qtables, hours=0.05, pose_source="truth", seed=2,
                 out=tmp_path / "o", progress=False, mdp=chain.mdp,
                 goals=["NE", f"s{target}"], baseline_hours=0.0)
    s = res.summary
    assert list(s.goal_names) == ["NE", f"s{target}"]
    assert set(s.result.goals_reached) == {"NE", f"s{target}"}
    import pyarrow.parquet as pq

    log = pq.read_table(res.files["transitions"]).to_pydict()
    hits = [(g, s2) for g, s2, r in zip(log["goal"], log["s_next"], log["reward"], strict=True)
            if r > 0]
    assert hits and all(s2 == target for g, s2 in hits if g == f"s{target}")
