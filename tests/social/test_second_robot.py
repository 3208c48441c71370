"""A second TurtleBot as the human (issue 18 item 1, ``human_body="turtlebot"``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.physics.arena import load_arena
from simlab.physics.robot import load_robot_spec
from simlab.social.actions import SocialAction
from simlab.social.human import HumanBody
from simlab.social.perception import line_of_sight
from simlab.social.render import render_social
from simlab.social.task import SocialConfig, SocialTable
from simlab.visitlab.humans import Human

# two TurtleBots (swept radius 0.12 m) must keep apart: a wider body than the disc's
BODY = HumanBody(radius=0.12, min_separation=0.26, follow_gap=0.30)
# the URDF: scanner at x = -0.032 m of the base frame, its housing a 0.035 m cylinder
# around the scanner's axis, spanning the scan plane
SCANNER_X, HOUSING_R = -0.032, 0.035


@pytest.fixture(scope="module")
def two_bots():
    cfg = SocialConfig(human=Human(random_move=1.0), body=BODY, human_body="turtlebot")
    with SocialTable(cfg) as env:
        yield env


@pytest.mark.parametrize("theta", [0.0, math.pi])
def test_lidar_sees_the_second_turtlebot_at_the_hand_computed_distance(two_bots, theta):
    two_bots.reset(0, robot_pose=np.array([0.0, 0.0, 0.0]),
                   human_pose=np.array([0.40, 0.0, theta]))
    scan = two_bots.world.scan(None)
    # beam 0 (+x) from the robot's scanner (x = -0.032) to the near side of the other
    # robot's housing, whose axis is at 0.40 + cos(theta) * -0.032
    housing = 0.40 + math.cos(theta) * SCANNER_X
    expected = housing - HOUSING_R - SCANNER_X
    assert scan.ranges[0] == pytest.approx(expected, abs=2e-3)
    assert scan.hit_ids[0] == two_bots.human_body_id


def test_the_disc_human_is_invisible_to_the_lidar():
    with SocialTable(SocialConfig(body=BODY)) as env:
        env.reset(0, robot_pose=np.array([0.0, 0.0, 0.0]),
                  human_pose=np.array([0.40, 0.0, 0.0]))
        assert env.human_body_id is None
        scan = env.world.scan(None)
        # the wall at x = 0.75 instead
        assert scan.ranges[0] == pytest.approx(0.75 - SCANNER_X, abs=2e-3)


def test_line_of_sight_is_not_blocked_by_the_humans_own_body(two_bots):
    two_bots.reset(0, robot_pose=np.array([0.0, 0.0, 0.0]),
                   human_pose=np.array([0.40, 0.0, math.pi]))
    w = two_bots.world
    assert two_bots.true_percepts().visible
    assert line_of_sight(w, two_bots.human_pose[:2], ignore=two_bots.human_body_id)
    # the body is real for other rays: a point behind the human cannot see the robot
    assert not line_of_sight(w, (0.60, 0.0), ignore=None)
    perc = two_bots.percepts()
    assert perc.level == 4 and perc.distance_class == 2  # 0.30 < 0.40 <= 0.45 m


def test_the_body_follows_the_human(two_bots):
    two_bots.reset(3, robot_pose=np.array([-0.4, -0.4, 0.0]),
                   human_pose=np.array([0.2, 0.2, 0.0]))
    c, body = two_bots.world.client, two_bots.human_body_id
    inertial = np.asarray(c.getDynamicsInfo(body, -1)[3])
    moved = 0
    for _ in range(4):
        _, _, info = two_bots.step(int(SocialAction.STAY))
        moved += info.moved >= 0
        com, orn = c.getBasePositionAndOrientation(body)
        yaw = c.getEulerFromQuaternion(orn)[2]
        rot = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
        xy = np.asarray(com[:2]) - rot @ inertial[:2]
        np.testing.assert_allclose(xy, info.human_pose[:2], atol=1e-9)
        assert math.remainder(yaw - info.human_pose[2], 2 * math.pi) == pytest.approx(0.0,
                                                                                   abs=1e-9)
    assert moved > 0  # r_H = 1: the human walked, its body with it


def test_render_draws_the_human_as_a_robot():
    arena, spec = load_arena("table"), load_robot_spec("turtlebot3_burger")
    pose = (0.3, 0.3, 0.0)
    disc = render_social(arena, spec, (-0.4, -0.4, 0.0), pose, BODY)
    bot = render_social(arena, spec, (-0.4, -0.4, 0.0), pose, BODY, human_body="turtlebot")
    assert disc.shape == bot.shape and not np.array_equal(disc, bot)


def test_unknown_human_body_is_refused():
    with pytest.raises(ConfigError, match="human_body"):
        SocialConfig(human_body="android")
