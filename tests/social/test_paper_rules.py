"""Paper rules 4-6 in the physics social task (issue 18 item, issue 14 rules)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simlab.base.actions import HEADINGS
from simlab.base.errors import ConfigError
from simlab.physics.motion import action_index
from simlab.social.actions import SocialAction
from simlab.social.human import HumanBody, idle_step
from simlab.social.perception import bearing, quantise_direction
from simlab.social.task import SocialConfig, SocialTable
from simlab.visitlab.humans import Human

UP = quantise_direction(math.pi / 2)
GTH = int(SocialAction.GO_TO_HUMAN)


def test_rules_switch_the_three_options_and_each_can_be_set():
    thesis, paper = SocialConfig(), SocialConfig(rules="paper")
    keys = ("gaze_before_move", "gth_before_attention", "idle_turn_all")
    assert [getattr(thesis, k) for k in keys] == [False] * 3
    assert [getattr(paper, k) for k in keys] == [True] * 3
    one = SocialConfig(rules="paper", idle_turn_all=False)
    assert (one.gaze_before_move, one.gth_before_attention, one.idle_turn_all) == (
        True, True, False)
    with pytest.raises(ConfigError, match="rules"):
        SocialConfig(rules="reference")
    with pytest.raises(ConfigError, match="gaze_before_move"):
        SocialConfig(gaze_before_move=1)


@pytest.mark.parametrize("rules", ["thesis", "paper"])
def test_gaze_after_the_robot_moves(rules):
    """A following human (level 7) and a robot that drives up (+y): under rule 4 the human
    keeps facing where the robot stood before its move (here exactly -x, pi); the thesis
    re-aims it at the robot after both moved."""
    human = Human(lose_attention=0.0)
    with SocialTable(SocialConfig(human=human, rules=rules)) as env:
        env.reset(0, robot_pose=np.array([0.0, 0.0, math.pi / 2]),
                  human_pose=np.array([0.40, 0.0, 0.0]))
        env.engaged = 7
        _, _, info = env.step(action_index(1, UP))
        assert info.level == 7
        robot, hum = info.robot_pose, info.human_pose
        assert robot[1] > 0.05 and hum[0] < 0.40 - 0.1  # both moved
        if rules == "paper":
            assert hum[2] == pytest.approx(math.pi, abs=1e-12)
        else:
            assert hum[2] == pytest.approx(bearing(hum, robot), abs=1e-12)
            assert abs(hum[2] - math.pi) > 0.1


@pytest.mark.parametrize("rules", ["thesis", "paper"])
def test_gaze_of_an_engaged_human_that_does_not_walk(rules):
    """Level 5 (no walking): rule 4 aims the gaze at the robot's position before its move."""
    with SocialTable(SocialConfig(human=Human(), rules=rules)) as env:
        env.reset(0, robot_pose=np.array([0.0, 0.0, math.pi / 2]),
                  human_pose=np.array([0.40, 0.0, 0.5]))
        env.engaged = 5
        _, _, info = env.step(action_index(1, UP))
        robot_before = (0.0, 0.0)
        want = (bearing(info.human_pose, robot_before) if rules == "paper"
                else bearing(info.human_pose, info.robot_pose))
        assert info.human_pose[2] == pytest.approx(want, abs=1e-12)


@pytest.mark.parametrize(("rules", "engaged_before", "drives"), [
    ("thesis", 5, True),    # attention lost at the check: not engaged after it -> drives
    ("paper", 5, False),    # engaged before the check -> refused
    ("paper", 0, True),     # not engaged before -> drives
])
def test_go_to_human_with_a_human_engaged_before_the_check(rules, engaged_before, drives):
    # L_H = 1: an engaged human always loses attention at the check; it neither moves
    # nor turns
    human = Human(lose_attention=1.0)
    with SocialTable(SocialConfig(human=human, rules=rules)) as env:
        start = np.array([-0.30, 0.0, 0.0])
        env.reset(0, robot_pose=start, human_pose=np.array([0.0, 0.0, math.pi / 2]))
        env.engaged = engaged_before
        _, _, info = env.step(GTH)
        assert info.level < 5
        gaze_target = np.array([0.0, 2 * env.config.body.cell_size])
        if drives:
            assert np.hypot(*(info.robot_pose[:2] - gaze_target)) <= env.config.gth_tolerance
        else:
            assert np.hypot(*(info.robot_pose[:2] - start[:2])) < 0.005
            assert info.duration == pytest.approx(env.config.signal_time
                                                  + env.config.primitives.decision_latency)


@pytest.mark.parametrize("turn_all", [False, True])
def test_idle_turn_distribution(turn_all):
    """O_H = 1, r_H = 0: every step is one turn. Rule 6 draws k in 0..7 (current included),
    exactly the seeded integers; the thesis never keeps the current orientation."""
    human = Human(orientation_change=1.0, random_move=0.0)
    body, n = HumanBody(), 4000
    rng, ref = np.random.default_rng(11), np.random.default_rng(11)
    pose = np.array([0.0, 0.0, float(HEADINGS[0])])
    same, counts = 0, np.zeros(8, dtype=int)
    for _ in range(n):
        new, moved = idle_step(None, pose, human, body, np.array([1.0, 1.0]), rng,
                               turn_all=turn_all)
        assert moved == -1
        ref.random(), ref.random()  # the move draw, the turn draw
        if turn_all:
            assert new[2] == float(HEADINGS[int(ref.integers(0, 8))])
        else:
            ref.integers(0, 7)
        d_old, d_new = quantise_direction(pose[2]), quantise_direction(new[2])
        same += d_old == d_new
        counts[d_new] += 1
        pose = new
    if turn_all:
        # uniform over 8: each orientation and "kept" ~ n / 8 (4 sigma bounds)
        sigma = math.sqrt(n * (1 / 8) * (7 / 8))
        assert abs(same - n / 8) < 4 * sigma
        assert np.all(np.abs(counts - n / 8) < 4 * sigma)
    else:
        assert same == 0
        assert np.all(counts > 0)
