"""Paper-exact social rules 3-6 of issue 14 against hand-worked situations (the agent rules
1, 2 and 7 are in tests/agents/test_core.py)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from simlab.visitlab import dynamics as dyn
from simlab.visitlab.actions import Action
from simlab.visitlab.envs import SocialEnv
from simlab.visitlab.grid import gridworld
from simlab.visitlab.humans import Human
from simlab.visitlab.perception import (
    PAPER_PERCEPTION,
    THESIS_PERCEPTION,
    Perception,
    direction_between,
    percepts,
)

U, D, L, R, UL, UR, DL, DR = range(8)
LAY = gridworld(30, 30, (1, 1))
QUANTISED = replace(PAPER_PERCEPTION, continuous=False, gaze_before_move=False,
                    gth_before_attention=False, share_cells=False)


def _sees_looks(perception: Perception, human_rc, human_ori, robot_rc):
    _, _, _, sees, looks, _ = percepts(LAY.walls_h, LAY.walls_v, LAY.los_table(),
                                       perception.to_array(), LAY.cell(*robot_rc), U,
                                       LAY.cell(*human_rc), human_ori)
    return bool(sees), bool(looks)


@pytest.mark.parametrize("robot,paper,thesis", [
    ((9, 11), (True, True), (True, True)),     # 45 deg: facing border, inclusive
    ((10, 11), (True, False), (True, False)),  # 90 deg: visual border, inclusive
    ((11, 11), (False, False), (False, False)),  # 135 deg
    ((9, 12), (True, False), (True, True)),    # 63.4 deg: quantised to 45 -> "looks"
    ((11, 16), (False, False), (True, False)),  # 99.5 deg: quantised to 90 -> "sees"
])
def test_rule3_fields_on_the_continuous_bearing(robot, paper, thesis):
    human = (10, 10)  # facing UP
    assert _sees_looks(PAPER_PERCEPTION, human, U, robot) == paper
    assert _sees_looks(QUANTISED, human, U, robot) == thesis


def _step(perception, human: Human, st, action, seed=0):
    return dyn.social_step(LAY.walls_h, LAY.walls_v, LAY.los_table(), perception.to_array(),
                           human.to_array(), 0.0, st, int(action), np.random.default_rng(seed))


def _state(robot, robot_ori, human, human_ori, engaged=0):
    st = dyn.new_state()
    st[dyn.S_ROBOT], st[dyn.S_ROBOT_ORI] = LAY.cell(*robot), robot_ori
    st[dyn.S_HUMAN], st[dyn.S_HUMAN_ORI] = LAY.cell(*human), human_ori
    st[dyn.S_ENGAGED] = engaged
    return st


def test_rule4_gaze_aims_before_the_robot_moves_and_is_not_reaimed():
    w = LAY.width
    follower = Human()  # speed 1, never loses attention
    for perception, paper in ((PAPER_PERCEPTION, True), (THESIS_PERCEPTION, False)):
        st = _state((10, 12), R, (10, 10), R, engaged=7)
        _step(perception, follower, st, Action.UP)  # robot -> (9, 12); human walks right
        assert LAY.rowcol(int(st[dyn.S_HUMAN])) == (10, 11)
        before = direction_between(w, LAY.cell(10, 10), LAY.cell(10, 12))  # RIGHT
        after = direction_between(w, LAY.cell(10, 11), LAY.cell(9, 12))  # UP-RIGHT
        assert before != after
        assert st[dyn.S_HUMAN_ORI] == (before if paper else after)


def test_rule5_go_to_human_with_a_human_engaged_before_the_attention_check():
    # engaged (5) but too far: attention is lost in this step's check
    for perception, moved in ((PAPER_PERCEPTION, False), (THESIS_PERCEPTION, True)):
        st = _state((10, 25), L, (10, 10), U, engaged=5)
        _step(perception, Human(), st, Action.GO_TO_HUMAN)
        assert st[dyn.S_ENGAGED] == 0
        assert (LAY.rowcol(int(st[dyn.S_ROBOT])) == (8, 10)) == moved  # 2 cells along gaze
        assert (LAY.rowcol(int(st[dyn.S_ROBOT])) == (10, 25)) == (not moved)


def test_rule5_go_to_human_may_land_on_the_human():
    # the human faces the top wall: the 2-cell move along its gaze ends on its own cell
    for perception, lands in ((PAPER_PERCEPTION, True), (THESIS_PERCEPTION, False)):
        st = _state((10, 20), L, (0, 10), U)
        _step(perception, Human(), st, Action.GO_TO_HUMAN)
        assert (st[dyn.S_ROBOT] == LAY.cell(0, 10)) == lands


def test_rule6_robot_may_step_onto_the_human():
    for perception, cell in ((PAPER_PERCEPTION, (10, 10)), (THESIS_PERCEPTION, (10, 9))):
        st = _state((10, 9), R, (10, 10), U)
        _step(perception, Human(), st, Action.RIGHT)
        assert LAY.rowcol(int(st[dyn.S_ROBOT])) == cell


def test_rule6_idle_turn_draws_among_all_eight_orientations():
    turner = Human(orientation_change=1.0)
    for share, expected_keep in ((True, True), (False, False)):
        rng = np.random.default_rng(0)
        kept = 0
        for _ in range(800):
            st = _state((5, 5), U, (10, 10), U)
            dyn.human_idle(LAY.walls_h, LAY.walls_v, st, turner.to_array(), rng, share)
            kept += st[dyn.S_HUMAN_ORI] == U
        if expected_keep:
            assert 60 <= kept <= 145  # 1/8 of 800 = 100 (about 4.5 sigma either side)
        else:
            assert kept == 0


def test_rule6_paper_grid_is_140_with_the_human_at_the_centre():
    env = SocialEnv(variant="paper")
    assert (env.layout.height, env.layout.width) == (140, 140)
    env.reset(seed=0)
    assert env.layout.rowcol(int(env.world_state[dyn.S_HUMAN])) == (70, 70)
    assert SocialEnv(variant="thesis").layout.width == 41


def test_thesis_perception_keeps_every_paper_rule_off():
    assert THESIS_PERCEPTION.to_array()[7:].tolist() == [0, 0, 0, 0]
    assert PAPER_PERCEPTION.to_array()[7:].tolist() == [1, 1, 1, 1]
