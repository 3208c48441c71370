"""The robot's own pose estimate in the physics social task (issue 18, item 1)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.social.actions import SocialAction
from simlab.social.perception import quantise_direction, social_obs_index
from simlab.social.task import SocialConfig, SocialTable, SourceEstimate


class OffsetEstimate:
    """A stub pose estimate: the true pose displaced by a fixed offset (x, y, yaw)."""

    on_scan = None
    scan_beams = None

    def __init__(self, offset):
        self.offset = np.asarray(offset, dtype=float)
        self.world = None

    def reset(self, world, rng):
        del rng
        self.world = world

    def now(self):
        return self.world.pose() + self.offset


# robot truly at the origin facing +x, the human 0.30 m ahead facing it: level 4, class 1
ROBOT = np.array([0.0, 0.0, 0.0])
HUMAN = np.array([0.30, 0.0, math.pi])
# the robot believes it is 0.30 m lower and turned 0.1 rad clockwise
OFFSET = (0.0, -0.30, -0.1)


@pytest.fixture(scope="module")
def shifted():
    with SocialTable(SocialConfig(human="easy"), pose_estimate=OffsetEstimate(OFFSET)) as env:
        yield env


def test_robot_percepts_shift_as_the_hand_computation_says(shifted):
    shifted.reset(0, robot_pose=ROBOT, human_pose=HUMAN)
    est = shifted.robot_pose_estimate()
    np.testing.assert_allclose(est, shifted.world.pose() + OFFSET)
    mine = shifted.percepts()
    # estimate (0, -0.3, -0.1) -> human (0.3, 0): distance 0.3 sqrt 2 = 0.424 m (class 2),
    # bearing 45 deg (NE), 45 + 5.73 deg off the believed yaw: outside the facing field
    true_xy = shifted.world.pose()[:2]
    d = math.hypot(HUMAN[0] - true_xy[0], HUMAN[1] - (true_xy[1] - 0.30))
    assert mine.distance == pytest.approx(d, abs=1e-12)
    assert d == pytest.approx(0.30 * math.sqrt(2.0), abs=1e-3)
    assert mine.distance_class == 2
    assert mine.angle == quantise_direction(math.pi / 4)
    assert not mine.r_looks
    # the human's side is the truth: it sees and looks at the robot
    assert mine.h_sees and mine.h_looks and mine.visible
    assert mine.level == 2  # H looks at R, R does not look at H
    req = shifted.required_direction
    assert shifted.observation() == social_obs_index(2, 2, req, quantise_direction(math.pi / 4))
    # the true percepts do not move
    truth = shifted.true_percepts()
    assert (truth.level, truth.distance_class, truth.angle) == (4, 1, quantise_direction(0.0))
    assert truth.h_sees == mine.h_sees and truth.h_looks == mine.h_looks


def test_the_human_answers_to_the_true_situation(shifted):
    # the robot believes it is at level 2 (HELLO useless), but the human sees level 4
    shifted.reset(0, robot_pose=ROBOT, human_pose=HUMAN)
    assert shifted.percepts().level == 2
    _, _, info = shifted.step(int(SocialAction.HELLO))
    assert shifted.engaged == 5 and info.level == 5


def test_look_h_turns_by_the_believed_angle(shifted):
    shifted.reset(0, robot_pose=ROBOT, human_pose=HUMAN)
    shifted.step(int(SocialAction.LOOK_H))
    # believed bearing 45 deg, believed yaw -0.1 rad: the robot turns pi/4 + 0.1 rad
    tol = shifted.config.primitives.heading_tolerance
    assert shifted.world.yaw() == pytest.approx(math.pi / 4 + 0.1, abs=tol + 0.02)


def test_truth_source_is_the_default_and_unchanged():
    cfg = SocialConfig()
    assert cfg.pose_source == "truth"
    rng = np.random.default_rng(3)
    actions = rng.integers(0, 22, size=6)
    runs = []
    for est in (None, "truth"):
        with SocialTable(cfg) as env:
            if est is not None:
                env = SocialTable(cfg, env.world, pose_estimate=SourceEstimate(est, env.world))
            obs = [env.reset(5)]
            for a in actions:
                o, r, info = env.step(int(a))
                obs.append((o, r, tuple(info.robot_pose), tuple(info.human_pose)))
            runs.append(obs)
    assert runs[0] == runs[1]


def test_odometry_source_reads_the_wheel_odometry():
    with SocialTable(SocialConfig(pose_source="odometry")) as env:
        env.reset(2, robot_pose=ROBOT, human_pose=np.array([0.4, 0.3, 0.0]))
        for a in (1, 9, 3):
            env.step(a)
        odom = env.world.odometry()
        np.testing.assert_array_equal(env.robot_pose_estimate(), odom)
        h = env.human_pose
        assert env.percepts().distance == pytest.approx(math.hypot(h[0] - odom[0],
                                                                   h[1] - odom[1]), abs=1e-12)


def test_unknown_pose_source_is_refused():
    with pytest.raises(ConfigError, match="pose_source"):
        SocialConfig(pose_source="gps")


def test_mcl_source_tracks_the_robot_and_feeds_the_percepts():
    with SocialTable(SocialConfig(pose_source="mcl")) as env:
        env.reset(1, robot_pose=ROBOT, human_pose=np.array([0.4, 0.3, 0.0]))
        for a in (1, 9, int(SocialAction.LOOK_H), 3, 12):
            env.step(a)
        est, truth = env.robot_pose_estimate(), env.world.pose()
        assert not np.array_equal(est, truth)  # an estimate, not the truth
        assert math.hypot(*(est[:2] - truth[:2])) < 0.03  # measured ~0.5 cm over 150 steps
        h = env.human_pose
        assert env.percepts().distance == pytest.approx(math.hypot(h[0] - est[0],
                                                                   h[1] - est[1]), abs=1e-12)
