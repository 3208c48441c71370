"""Social module dynamics (SPEC B3): every interaction-level transition.

Deterministic transitions are checked exactly with human parameters 0 or 1;
stochastic ones against the 99.9 % binomial interval over 10,000 tries.
"""

from __future__ import annotations

import numpy as np
import pytest

from simlab.visitlab import dynamics as dyn
from simlab.visitlab.actions import DIR_DELTA, Action
from simlab.visitlab.envs import decode_social
from simlab.visitlab.grid import Layout, gridworld, paper_layout
from simlab.visitlab.humans import Human
from simlab.visitlab.perception import THESIS_PERCEPTION, Perception

U, D, L, R, UL, UR, DL, DR = range(8)
N = 10_000


class Sim:
    """The social kernels bound to a layout, a human and a perception."""

    def __init__(self, human: Human, layout: Layout | None = None, redraw_p: float = 0.0,
                 perception: Perception = THESIS_PERCEPTION) -> None:
        self.lay = layout or gridworld(21, 21, (1, 1))
        self.hp = human.to_array()
        self.pcfg = perception.to_array()
        self.los = self.lay.los_table()
        self.redraw_p = redraw_p

    def state(self, robot, robot_ori, human, human_ori, engaged=0, req=R):
        st = dyn.new_state()
        st[dyn.S_ROBOT] = self.lay.cell(*robot)
        st[dyn.S_ROBOT_ORI] = robot_ori
        st[dyn.S_HUMAN] = self.lay.cell(*human)
        st[dyn.S_HUMAN_ORI] = human_ori
        st[dyn.S_ENGAGED] = engaged
        st[dyn.S_REQ_DIR] = req
        return st

    def step(self, st, action, rng):
        return dyn.social_step(self.lay.walls_h, self.lay.walls_v, self.los, self.pcfg, self.hp,
                               self.redraw_p, st, int(action), rng)

    def obs(self, st):
        return decode_social(dyn.social_obs(self.lay.walls_h, self.lay.walls_v, self.los,
                                            self.pcfg, st))

    def level(self, st):
        return self.obs(st)[0]

    def pos(self, st, who):
        return self.lay.rowcol(int(st[who]))


def human_with(**kw) -> Human:
    return Human(**kw)


# Scenes on a 21 x 21 open grid, human at (10, 10), robot 3 cells to its right (Manhattan 3,
# distance class 2: appropriate). Robot -> human is LEFT.
HUMAN_AT = (10, 10)
ROBOT_AT = (10, 13)
LEVEL_SCENES = {  # level: (robot_ori, human_ori)
    4: (L, R),
    3: (L, U),
    2: (U, R),
    1: (U, U),
    0: (L, L),
}


def scene(sim, level, engaged=0, robot=ROBOT_AT, req=R):
    robot_ori, human_ori = LEVEL_SCENES[level]
    st = sim.state(robot, robot_ori, HUMAN_AT, human_ori, engaged=engaged, req=req)
    assert sim.level(st) == (engaged if engaged >= 5 else level)
    return st


# --------------------------------------------------------------------------- HELLO


@pytest.mark.parametrize("fail", [0.0, 1.0])
def test_hello_at_level_4_always_succeeds(fail, rng):
    sim = Sim(human_with(fail_hello=fail))
    st = scene(sim, 4)
    sim.step(st, Action.HELLO, rng)
    assert st[dyn.S_ENGAGED] == 5 and sim.level(st) == 5


def test_hello_at_level_3_fails_exactly_with_f_1(rng):
    sim = Sim(human_with(fail_hello=0.0))
    st = scene(sim, 3)
    sim.step(st, Action.HELLO, rng)
    assert sim.level(st) == 5
    sim = Sim(human_with(fail_hello=1.0))
    st = scene(sim, 3)
    sim.step(st, Action.HELLO, rng)
    assert st[dyn.S_ENGAGED] == 0 and sim.level(st) == 3


@pytest.mark.parametrize("level", [0, 1, 2])
def test_hello_below_level_3_does_nothing(level, rng):
    sim = Sim(human_with())
    st = scene(sim, level)
    sim.step(st, Action.HELLO, rng)
    assert st[dyn.S_ENGAGED] == 0 and sim.level(st) == level


@pytest.mark.parametrize(("robot", "dist_class"), [((10, 11), 0), ((10, 15), 4), ((10, 18), 4)])
def test_hello_at_bad_distance_does_nothing(robot, dist_class, rng):
    sim = Sim(human_with())
    st = sim.state(robot, L, HUMAN_AT, R)
    level, dist, _, _ = sim.obs(st)
    assert level == 4 and dist == dist_class
    sim.step(st, Action.HELLO, rng)
    assert st[dyn.S_ENGAGED] == 0


@pytest.mark.parametrize("dist_cells", [2, 3, 4])
def test_hello_at_each_appropriate_distance(dist_cells, rng):
    sim = Sim(human_with())
    st = sim.state((10, 10 + dist_cells), L, HUMAN_AT, R)
    assert 1 <= sim.obs(st)[1] <= 3
    sim.step(st, Action.HELLO, rng)
    assert sim.level(st) == 5


def test_hello_failure_rate_equals_f_h(assert_rate):
    f = 0.3
    sim = Sim(human_with(fail_hello=f))
    rng = np.random.default_rng(1)
    base = scene(sim, 3)
    fails = 0
    for _ in range(N):
        st = base.copy()
        sim.step(st, Action.HELLO, rng)
        fails += st[dyn.S_ENGAGED] == 0
    assert_rate(fails, N, f)


# --------------------------------------------------------------------------- COME / POINTING


def test_come_at_5_goes_to_7_without_pointing_need(rng):
    sim = Sim(human_with(pointing_need=0.0))
    st = scene(sim, 4, engaged=5)
    sim.step(st, Action.COME, rng)
    assert sim.level(st) == 7


def test_come_at_5_waits_at_6_with_pointing_need_1_then_pointing_gives_7(rng):
    sim = Sim(human_with(pointing_need=1.0))
    st = scene(sim, 4, engaged=5)
    sim.step(st, Action.COME, rng)
    assert sim.level(st) == 6
    sim.step(st, Action.COME, rng)  # COME again does nothing at 6
    assert sim.level(st) == 6
    sim.step(st, Action.POINTING, rng)
    assert sim.level(st) == 7


@pytest.mark.parametrize(("engaged", "action", "expected"), [
    (0, Action.COME, 4),  # COME before HELLO: nothing
    (5, Action.POINTING, 5),  # POINTING before COME: nothing
    (0, Action.POINTING, 4),
    (7, Action.COME, 7),
    (7, Action.HELLO, 7),
    (6, Action.HELLO, 6),
    (5, Action.HELLO, 5),
    (7, Action.POINTING, 7),
])
def test_social_actions_out_of_sequence_do_nothing(engaged, action, expected, rng):
    sim = Sim(human_with())
    st = scene(sim, 4, engaged=engaged)
    sim.step(st, action, rng)
    assert sim.level(st) == expected


def test_pointing_need_rate_equals_p_h(assert_rate):
    p = 0.45
    sim = Sim(human_with(pointing_need=p))
    rng = np.random.default_rng(2)
    base = scene(sim, 4, engaged=5)
    waits = 0
    for _ in range(N):
        st = base.copy()
        sim.step(st, Action.COME, rng)
        assert st[dyn.S_ENGAGED] in (6, 7)
        waits += st[dyn.S_ENGAGED] == 6
    assert_rate(waits, N, p)


# --------------------------------------------------------------------------- attention


@pytest.mark.parametrize("engaged", [5, 6, 7])
@pytest.mark.parametrize("percept_level", [0, 3, 4])
def test_losing_attention_falls_back_to_percept_level(engaged, percept_level, rng):
    sim = Sim(human_with(lose_attention=1.0))
    st = scene(sim, percept_level, engaged=engaged)
    sim.step(st, Action.STAY, rng)
    assert st[dyn.S_ENGAGED] == 0
    # the human's gaze no longer tracks the robot; with all other parameters 0
    # nothing moved, so the level is the percept level of the scene
    assert sim.level(st) == percept_level


@pytest.mark.parametrize("engaged", [5, 6, 7])
def test_never_loses_attention_with_l_0_at_good_distance(engaged, rng):
    sim = Sim(human_with(lose_attention=0.0))
    st = scene(sim, 0, engaged=engaged)
    action = Action.COME if engaged == 7 else Action.STAY  # COME keeps a level-7 human still
    for _ in range(20):
        sim.step(st, action, rng)
        assert st[dyn.S_ENGAGED] == engaged


@pytest.mark.parametrize("robot", [(10, 11), (9, 10), (10, 15), (13, 13)])
def test_bad_distance_always_loses_attention(robot, rng):
    sim = Sim(human_with(lose_attention=0.0))
    st = sim.state(robot, L, HUMAN_AT, R, engaged=7)
    dist = sim.obs(st)[1]
    assert dist in (0, 4)
    sim.step(st, Action.STAY, rng)
    assert st[dyn.S_ENGAGED] == 0


def test_hello_right_after_losing_attention_reengages(rng):
    # attention is checked before the action: HELLO in the same step starts again at 5
    sim = Sim(human_with(lose_attention=1.0))
    st = scene(sim, 4, engaged=7)
    sim.step(st, Action.HELLO, rng)
    assert sim.level(st) == 5


def test_losing_attention_rate_equals_l_h(assert_rate):
    p = 0.2
    sim = Sim(human_with(lose_attention=p))
    rng = np.random.default_rng(3)
    base = scene(sim, 4, engaged=6)
    lost = 0
    for _ in range(N):
        st = base.copy()
        sim.step(st, Action.STAY, rng)
        lost += st[dyn.S_ENGAGED] == 0
    assert_rate(lost, N, p)


# --------------------------------------------------------------------------- gaze and following


def test_engaged_gaze_tracks_the_robot(rng):
    sim = Sim(human_with())
    st = scene(sim, 0, engaged=5)  # human looks LEFT, away from the robot on its right
    sim.step(st, Action.UP2, rng)  # robot to (8, 13)
    assert sim.pos(st, dyn.S_ROBOT) == (8, 13)
    assert st[dyn.S_HUMAN_ORI] == UR  # offset (-2, +3) is 33.7 deg
    assert sim.pos(st, dyn.S_HUMAN) == HUMAN_AT  # level 5 does not follow


@pytest.mark.parametrize("speed", [1, 2, 3])
def test_level_7_human_follows_the_robot_at_its_speed(speed, rng):
    probs = [0.0, 0.0, 0.0]
    probs[speed - 1] = 1.0
    sim = Sim(human_with(speed_probs=tuple(probs)))
    st = scene(sim, 4, engaged=7, robot=(10, 14), req=R)
    reward = sim.step(st, Action.RIGHT3, rng)  # robot to (10, 17); human follows RIGHT
    assert sim.pos(st, dyn.S_ROBOT) == (10, 17)
    assert sim.pos(st, dyn.S_HUMAN) == (10, 10 + speed)
    assert st[dyn.S_HUMAN_MOVE] == R
    assert reward == 1.0


def test_following_human_walks_toward_where_it_saw_the_robot(rng):
    # the robot (right of the human) jumps up; the human still walks RIGHT this step
    # (the direction opposite to the observed angle), then looks at the robot again
    sim = Sim(human_with())
    st = scene(sim, 4, engaged=7, req=R)
    assert sim.obs(st)[3] == L  # observed angle robot -> human
    reward = sim.step(st, Action.UP3, rng)
    assert sim.pos(st, dyn.S_ROBOT) == (7, 13)
    assert sim.pos(st, dyn.S_HUMAN) == (10, 11) and st[dyn.S_HUMAN_MOVE] == R
    assert reward == 1.0
    assert st[dyn.S_HUMAN_ORI] == UR  # offset (-3, +2): 56.3 deg


def test_following_human_stops_before_the_robot(rng):
    sim = Sim(human_with(speed_probs=(0.0, 0.0, 1.0)))
    st = scene(sim, 4, engaged=7, robot=(10, 12))
    reward = sim.step(st, Action.STAY, rng)
    assert sim.pos(st, dyn.S_HUMAN) == (10, 11)
    assert reward == 1.0  # moved RIGHT, the required direction


@pytest.mark.parametrize("action", [Action.HELLO, Action.COME, Action.POINTING])
def test_hello_come_pointing_stop_the_following_human(action, rng):
    sim = Sim(human_with())
    st = scene(sim, 4, engaged=7)
    reward = sim.step(st, action, rng)
    assert sim.pos(st, dyn.S_HUMAN) == HUMAN_AT and st[dyn.S_HUMAN_MOVE] == -1
    assert reward == 0.0 and st[dyn.S_ENGAGED] == 7


@pytest.mark.parametrize("required", range(8))
def test_reward_only_for_moving_in_the_required_direction(required, rng):
    sim = Sim(human_with())
    st = scene(sim, 4, engaged=7, req=required)
    reward = sim.step(st, Action.STAY, rng)  # human moves RIGHT toward the robot
    assert st[dyn.S_HUMAN_MOVE] == R
    assert reward == (1.0 if required == R else 0.0)


@pytest.mark.parametrize("engaged", [5, 6])
def test_no_reward_below_level_7(engaged, rng):
    sim = Sim(human_with(random_move=1.0))
    st = scene(sim, 4, engaged=engaged)
    for _ in range(10):
        assert sim.step(st, Action.STAY, rng) == 0.0
        assert sim.pos(st, dyn.S_HUMAN) == HUMAN_AT  # engaged humans do not wander


def test_following_speed_distribution_matches_s_h(assert_rate):
    probs = (0.2, 0.5, 0.3)
    sim = Sim(human_with(speed_probs=probs))
    rng = np.random.default_rng(4)
    base = scene(sim, 4, engaged=7, robot=(10, 14))
    counts = np.zeros(4, dtype=int)
    for _ in range(N):
        st = base.copy()
        sim.step(st, Action.RIGHT3, rng)
        counts[sim.pos(st, dyn.S_HUMAN)[1] - 10] += 1
    assert counts[0] == 0
    for k in range(3):
        assert_rate(counts[k + 1], N, probs[k])


# --------------------------------------------------------------------------- idle human


def test_idle_human_with_zero_parameters_never_moves_or_turns(rng):
    sim = Sim(human_with())
    st = scene(sim, 1)
    for _ in range(50):
        sim.step(st, Action.STAY, rng)
        assert sim.pos(st, dyn.S_HUMAN) == HUMAN_AT and st[dyn.S_HUMAN_ORI] == U


def test_random_move_rate_direction_and_speed(assert_rate):
    r_h, probs = 0.35, (0.5, 0.2, 0.3)
    sim = Sim(human_with(random_move=r_h, speed_probs=probs))
    rng = np.random.default_rng(5)
    base = sim.state((0, 0), R, HUMAN_AT, U)  # robot far in a corner
    moved = 0
    dirs = np.zeros(8, dtype=int)
    speeds = np.zeros(4, dtype=int)
    for _ in range(N):
        st = base.copy()
        sim.step(st, Action.STAY, rng)
        if st[dyn.S_HUMAN_MOVE] >= 0:
            moved += 1
            d = st[dyn.S_HUMAN_MOVE]
            dirs[d] += 1
            assert st[dyn.S_HUMAN_ORI] == d  # it faces where it walks
            r, c = sim.pos(st, dyn.S_HUMAN)
            k = max(abs(r - 10), abs(c - 10))
            assert (r - 10, c - 10) == tuple(DIR_DELTA[d] * k)
            speeds[k] += 1
        else:
            assert sim.pos(st, dyn.S_HUMAN) == HUMAN_AT
    assert_rate(moved, N, r_h)
    for d in range(8):
        assert_rate(dirs[d], moved, 1 / 8)
    for k in range(3):
        assert_rate(speeds[k + 1], moved, probs[k])


def test_random_turn_rate_equals_o_h_and_never_keeps_orientation(assert_rate):
    o_h = 0.25
    sim = Sim(human_with(orientation_change=o_h))
    rng = np.random.default_rng(6)
    base = scene(sim, 1)
    turned = 0
    new = np.zeros(8, dtype=int)
    for _ in range(N):
        st = base.copy()
        sim.step(st, Action.STAY, rng)
        if st[dyn.S_HUMAN_ORI] != U:
            turned += 1
            new[st[dyn.S_HUMAN_ORI]] += 1
    assert_rate(turned, N, o_h)
    assert new[U] == 0
    for d in range(1, 8):
        assert_rate(new[d], turned, 1 / 7)


def test_required_direction_redraw_rate(assert_rate):
    sim = Sim(human_with(), redraw_p=0.2)
    rng = np.random.default_rng(7)
    st = scene(sim, 1, req=R)
    changes = 0
    for _ in range(N):
        before = st[dyn.S_REQ_DIR]
        sim.step(st, Action.STAY, rng)
        changes += st[dyn.S_REQ_DIR] != before
    # a redraw is uniform over the 8 directions, so it changes the direction 7 times in 8
    assert_rate(changes, N, 0.2 * 7 / 8)


# --------------------------------------------------------------------------- robot actions


def test_look_h_turns_the_robot_to_the_human(rng):
    sim = Sim(human_with())
    st = sim.state((13, 14), U, HUMAN_AT, D)  # human is up-left of the robot (-3, -4)
    sim.step(st, Action.LOOK_H, rng)
    assert st[dyn.S_ROBOT_ORI] == UL
    assert sim.obs(st)[3] == UL  # the angle in the state


def test_robot_move_sets_orientation_even_when_blocked(rng):
    sim = Sim(human_with())
    st = sim.state((0, 5), D, HUMAN_AT, D)
    sim.step(st, Action.UP, rng)
    assert sim.pos(st, dyn.S_ROBOT) == (0, 5) and st[dyn.S_ROBOT_ORI] == U


def test_robot_cannot_enter_the_human_cell(rng):
    sim = Sim(human_with())
    st = sim.state((10, 13), L, HUMAN_AT, R)
    sim.step(st, Action.LEFT3, rng)
    assert sim.pos(st, dyn.S_ROBOT) == (10, 11)


def test_go_to_human_places_robot_two_cells_ahead_of_the_gaze(rng):
    sim = Sim(human_with())
    for d in range(8):
        st = sim.state((0, 0), U, HUMAN_AT, d)
        sim.step(st, Action.GO_TO_HUMAN, rng)
        dr, dc = DIR_DELTA[d] * 2
        assert sim.pos(st, dyn.S_ROBOT) == (10 + dr, 10 + dc)
        # the human now sees the robot (it is right in front of it)
        assert sim.level(st) in (2, 4)


def test_go_to_human_respects_walls_and_does_nothing_when_engaged(rng):
    sim = Sim(human_with(), layout=paper_layout())
    st = sim.state((20, 20), U, (6, 7), R)  # human faces the wall of its room
    sim.step(st, Action.GO_TO_HUMAN, rng)
    assert sim.pos(st, dyn.S_ROBOT) == (20, 20)
    st = sim.state((20, 20), U, (6, 6), R)
    sim.step(st, Action.GO_TO_HUMAN, rng)
    assert sim.pos(st, dyn.S_ROBOT) == (6, 7)  # one cell: the wall stops the second
    sim = Sim(human_with())
    st = scene(sim, 0, engaged=5)
    sim.step(st, Action.GO_TO_HUMAN, rng)
    assert sim.pos(st, dyn.S_ROBOT) == ROBOT_AT


def test_humans_and_robot_never_share_a_cell():
    sim = Sim(Human((0.2, 0.3, 0.5), 0.3, 0.3, 0.1, 0.3, 0.5), layout=gridworld(6, 6, (1, 1)),
              redraw_p=0.2)
    rng = np.random.default_rng(8)
    st = dyn.new_state()
    for _ in range(200):
        dyn.social_reset(st, rng, sim.lay.n_cells, -1, -1)
        for _ in range(20):
            sim.step(st, int(rng.integers(0, 30)), rng)
            assert st[dyn.S_ROBOT] != st[dyn.S_HUMAN]
            assert 0 <= st[dyn.S_ROBOT] < 36 and 0 <= st[dyn.S_HUMAN] < 36
