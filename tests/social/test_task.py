"""The physics social task: HELLO's conditions, following, determinism (issue 18)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.physics.motion import action_index
from simlab.social.actions import GRID_ACTION, N_SOCIAL_ACTIONS, SocialAction, grid_q_to_physics
from simlab.social.human import HumanBody
from simlab.social.task import SocialConfig, SocialTable
from simlab.visitlab.humans import PRESETS, Human

HELLO, COME = int(SocialAction.HELLO), int(SocialAction.COME)


@pytest.fixture(scope="module")
def table():
    with SocialTable(SocialConfig(human="easy")) as env:
        yield env


def _facing(robot_xy, human_xy, human_theta):
    """Robot pose at robot_xy facing the human; human pose (3,)."""
    yaw = math.atan2(human_xy[1] - robot_xy[1], human_xy[0] - robot_xy[0])
    return np.array([*robot_xy, yaw]), np.array([*human_xy, human_theta])


@pytest.mark.parametrize(("robot", "human", "level_before", "engaged"), [
    ((0.0, 0.0), (0.30, 0.0), 4, True),     # both look, class 1
    ((0.0, 0.0), (0.55, 0.0), 4, True),     # both look, class 3
    ((0.0, 0.0), (0.12, 0.0), 4, False),    # too close (class 0)
    ((-0.35, 0.0), (0.35, 0.0), 4, False),  # too far (class 4)
])
def test_hello_needs_an_appropriate_distance(table, robot, human, level_before, engaged):
    r, h = _facing(robot, human, math.pi)
    table.reset(0, robot_pose=r, human_pose=h)
    assert table.level() == level_before
    _, _, info = table.step(HELLO)
    assert (info.level == 5) is engaged
    assert table.engaged == (5 if engaged else 0)


def test_hello_needs_the_robot_to_look_at_the_human(table):
    # human looks at the robot, the robot looks away: level 2
    table.reset(0, robot_pose=np.array([0.0, 0.0, math.pi / 2]),
                human_pose=np.array([0.3, 0.0, math.pi]))
    assert table.level() == 2
    _, _, info = table.step(HELLO)
    assert info.level == 2 and table.engaged == 0


@pytest.mark.parametrize(("fail", "engaged"), [(0.0, True), (1.0, False)])
def test_hello_at_level_3_fails_with_probability_f_h(fail, engaged):
    # the human sees the robot 60 deg off its orientation (visual, not facing field)
    a = math.radians(60)
    r, h = _facing((0.3 * math.cos(a), 0.3 * math.sin(a)), (0.0, 0.0), 0.0)
    with SocialTable(SocialConfig(human=Human(fail_hello=fail))) as env:
        env.reset(0, robot_pose=r, human_pose=h)
        assert env.level() == 3
        _, _, info = env.step(HELLO)
        assert (info.level == 5) is engaged


def test_hello_at_level_4_always_succeeds():
    r, h = _facing((0.0, 0.0), (0.3, 0.0), math.pi)
    with SocialTable(SocialConfig(human=Human(fail_hello=1.0))) as env:
        env.reset(0, robot_pose=r, human_pose=h)
        assert env.step(HELLO)[2].level == 5


def test_come_only_after_hello(table):
    r, h = _facing((0.0, 0.0), (0.3, 0.0), math.pi)
    table.reset(0, robot_pose=r, human_pose=h)
    assert table.step(COME)[2].level == 4  # not engaged: nothing happens
    assert table.step(HELLO)[2].level == 5
    assert table.step(COME)[2].level == 7  # easy human: P_H = 0


def test_engaged_human_follows_the_driving_robot(table):
    # robot above the human, facing it; engage, then drive a square loop of 20 fast moves
    r, h = _facing((-0.45, -0.30), (-0.45, -0.55), math.pi / 2)
    table.reset(3, robot_pose=r, human_pose=h)
    assert table.step(HELLO)[2].level == 5
    assert table.step(COME)[2].level == 7
    up, right, down, left = 0, 3, 1, 2
    moves = 0
    path = 0.0
    for d in [up] * 5 + [right] * 5 + [down] * 5 + [left] * 5:
        required = table.required_direction
        before = table.human_pose.copy()
        _, reward, info = table.step(action_index(1, d))
        assert not info.blocked
        assert info.level == 7  # never lost: the distance stayed appropriate
        assert 0.15 < info.percepts.distance <= 0.45
        # the easy human walks 0.15 m per step, faster than the robot's 0.11 m: it
        # catches up and stops exactly follow_gap short of the robot
        assert info.percepts.distance == pytest.approx(HumanBody().follow_gap, abs=1e-6)
        assert reward == (1.0 if info.moved == required else 0.0)
        moves += info.moved >= 0
        path += float(np.hypot(*(info.human_pose[:2] - before[:2])))
    assert moves >= 15
    assert path > 1.5  # the robot drove 20 x 0.11 m = 2.2 m


def test_unengaged_easy_human_stands_still(table):
    r, h = _facing((0.0, 0.0), (0.3, 0.0), 0.0)
    table.reset(1, robot_pose=r, human_pose=h)
    for a in (action_index(0, 0), int(SocialAction.STAY), action_index(1, 2)):
        _, reward, info = table.step(a)
        assert info.moved == -1 and reward == 0.0
        assert np.array_equal(info.human_pose, h)


def test_look_h_turns_the_robot_to_the_human(table):
    table.reset(0, robot_pose=np.array([0.0, 0.0, -math.pi / 2]),
                human_pose=np.array([0.2, 0.3, 0.0]))
    _, _, info = table.step(int(SocialAction.LOOK_H))
    assert info.percepts.r_looks
    bearing = math.atan2(0.3 - info.robot_pose[1], 0.2 - info.robot_pose[0])
    assert abs(math.remainder(info.robot_pose[2] - bearing, 2 * math.pi)) < math.radians(2)
    assert np.hypot(*info.robot_pose[:2]) < 0.01  # turned in place


def test_go_to_human_lands_in_the_facing_field(table):
    table.reset(0, robot_pose=np.array([-0.5, -0.5, 0.0]),
                human_pose=np.array([0.1, 0.0, math.pi / 2]))  # human faces +y
    _, _, info = table.step(int(SocialAction.GO_TO_HUMAN))
    assert info.percepts.h_looks and info.percepts.r_looks
    assert info.level == 4 and 1 <= info.percepts.distance_class <= 3


def _rollout(seed: int, human: str, n: int = 15):
    acts = np.random.default_rng(11).integers(0, N_SOCIAL_ACTIONS, size=n)
    with SocialTable(SocialConfig(human=human)) as env:
        out = [(env.reset(seed), 0.0, None, None)]
        for a in acts:
            obs, reward, info = env.step(int(a))
            out.append((obs, reward, info.human_pose.tobytes(), info.robot_pose.tobytes()))
    return out


def test_same_seed_same_sequence():
    a = _rollout(7, "medium")
    assert a == _rollout(7, "medium")
    assert a != _rollout(8, "medium")


def test_grid_actions_map_to_physics_actions():
    assert GRID_ACTION[action_index(0, 0)] == 0       # slow UP -> UP (speed 1)
    assert GRID_ACTION[action_index(1, 0)] == 4       # fast UP -> UP2
    assert GRID_ACTION[action_index(0, 7)] == 15      # slow DR -> DOWN_RIGHT
    assert GRID_ACTION[action_index(1, 4)] == 16      # fast UL -> UP_LEFT2
    assert list(GRID_ACTION[16:]) == [24, 25, 26, 27, 28, 29]
    q = np.arange(2560 * 30, dtype=float).reshape(2560, 30)
    assert grid_q_to_physics(q).shape == (2560, N_SOCIAL_ACTIONS)
    assert grid_q_to_physics(q)[5, int(SocialAction.HELLO)] == q[5, 26]


def test_presets_and_bad_settings():
    assert SocialConfig(human="H2").human == PRESETS["H2"]
    with pytest.raises(ConfigError, match="human"):
        SocialConfig(human="nobody")
    with pytest.raises(ConfigError, match="follow_gap"):
        HumanBody(min_separation=0.3, follow_gap=0.2)
    with pytest.raises(ConfigError, match="redraw_p"):
        SocialConfig(redraw_p=1.5)


def test_human_in_front_blocks_a_primitive():
    # human 0.25 m ahead (+y) of a robot facing +y; the fast UP primitive would reach it
    r, h = np.array([0.0, -0.3, math.pi / 2]), np.array([0.0, -0.05, 0.0])
    for blocks, moved in ((True, False), (False, True)):
        with SocialTable(SocialConfig(human_blocks=blocks)) as env:
            env.reset(0, robot_pose=r, human_pose=h)
            _, _, info = env.step(action_index(1, 0))
            assert info.blocked is not moved
            dist = float(np.hypot(*(info.robot_pose[:2] - r[:2])))
            assert (dist > 0.08) is moved


def test_human_corridor_border():
    from simlab.physics.motion import PrimitiveParams
    from simlab.physics.robot import load_robot_spec
    from simlab.social.actions import human_in_corridor

    spec, p = load_robot_spec("turtlebot3_burger"), PrimitiveParams()
    a = action_index(0, 3)  # slow RIGHT: heading 0
    reach = spec.footprint[1] + p.nominal_distance(a) + p.detector_margin
    radius = 0.06
    at = np.array([reach + radius, 0.0])
    assert human_in_corridor((0.0, 0.0), 0.0, a, at, radius, spec, p)
    assert not human_in_corridor((0.0, 0.0), 0.0, a, np.array([reach + radius + 1e-6, 0.0]), radius, spec, p)
    assert not human_in_corridor((0.0, 0.0), math.pi, a, at, radius, spec, p)  # behind


def test_go_to_human_detours_around_the_human(table):
    # the robot stands behind the human, who faces away: the target is past the human
    h = np.array([0.0, -0.1, math.pi / 2])
    table.reset(0, robot_pose=np.array([0.0, -0.45, math.pi / 2]), human_pose=h)
    _, _, info = table.step(int(SocialAction.GO_TO_HUMAN))
    assert info.level == 4 and info.percepts.h_looks and info.percepts.r_looks
    assert info.robot_pose[1] > h[1] + 0.15  # in front of the human now
    assert np.array_equal(info.human_pose, h)
