"""The combined architecture (SPEC B6, thesis Fig. 3.1): the required-direction rule on
hand-built navigation Q rows, the delegation of action 29, the goal switch, the goal
count, the episode recorder and its GIF."""

from __future__ import annotations

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.visitlab import dynamics as dyn
from simlab.visitlab.actions import Action, move_action
from simlab.visitlab.combined import (
    PAPER_SPEED_WEIGHTS,
    THESIS_SPEED_WEIGHTS,
    CombinedKernelArgs,
    CombinedTask,
    Modules,
    combined_reset,
    combined_step,
    direction_values,
    evaluate,
    next_goal,
    record_episodes,
    required_direction,
    write_episode_gif,
)
from simlab.visitlab.humans import Human

U, D, L, R, UL, UR, DL, DR = range(8)
W_THESIS = np.array(THESIS_SPEED_WEIGHTS)
W_PAPER = np.array(PAPER_SPEED_WEIGHTS)


def row(**moves: float) -> np.ndarray:
    """A navigation Q row (25,) with the given values at ``d<dir>s<speed>`` moves."""
    q = np.zeros(25)
    for name, v in moves.items():
        if name == "stay":
            q[24] = v
            continue
        d, s = int(name[1]), int(name[3])
        q[move_action(d, s)] = v
    return q


# --------------------------------------------------------------------------- required direction


def test_direction_values_weight_each_speed_and_sum_per_direction():
    q = row(d0s1=1.0, d0s2=2.0, d0s3=3.0, d5s3=1.0, stay=100.0)
    vals = direction_values(q, W_THESIS, np.zeros(8))
    expected = np.zeros(8)
    expected[U] = 0.1 * 1.0 + 0.1 * 2.0 + 0.8 * 3.0
    expected[UR] = 0.8 * 1.0
    np.testing.assert_allclose(vals, expected)  # STAY (index 24) has no direction


@pytest.mark.parametrize(("weights", "expected"), [(W_THESIS, R), (W_PAPER, L)])
def test_speed_weights_decide_between_a_slow_and_a_fast_move(weights, expected, rng):
    # LEFT at speed 1 is worth 1.0, RIGHT at speed 3 is worth 0.5:
    # thesis weights 0.1 * 1.0 = 0.1 < 0.8 * 0.5 = 0.4; paper weights 1/3 > 1/6
    q = row(d2s1=1.0, d3s3=0.5)
    assert required_direction(q, weights, -1, 1e-9, rng) == expected


def test_sum_over_speeds_beats_a_single_better_move(rng):
    # DOWN: 0.4 at every speed -> 0.1*0.4 + 0.1*0.4 + 0.8*0.4 = 0.4; DL: 0.45 at speed 3 -> 0.36
    q = row(d1s1=0.4, d1s2=0.4, d1s3=0.4, d6s3=0.45)
    assert required_direction(q, W_THESIS, -1, 1e-9, rng) == D


def test_unique_best_replaces_the_current_direction(rng):
    q = row(d7s3=2.0, d0s3=1.0)
    for current in (-1, U, L):
        assert required_direction(q, W_THESIS, current, 1e-9, rng) == DR


def test_current_direction_is_kept_while_among_the_best(rng):
    q = row(d2s3=1.0, d5s3=1.0, d0s3=0.5)  # LEFT and UR tie
    assert required_direction(q, W_THESIS, UR, 1e-9, rng) == UR
    assert required_direction(q, W_THESIS, L, 1e-9, rng) == L
    # within the tolerance counts as a tie, beyond it does not
    q2 = row(d2s3=1.0, d5s3=1.0 - 1e-6)
    assert required_direction(q2, W_THESIS, UR, 1e-5, rng) == UR
    assert required_direction(q2, W_THESIS, UR, 1e-9, rng) == L


def test_ties_without_the_current_direction_are_broken_uniformly():
    q = row(d2s3=1.0, d5s3=1.0)
    rng = np.random.default_rng(7)
    n = 4000
    picks = np.array([required_direction(q, W_THESIS, U, 1e-9, rng) for _ in range(n)])
    assert set(np.unique(picks)) == {L, UR}
    k = int((picks == L).sum())
    assert abs(k / n - 0.5) < 3.29 * np.sqrt(0.25 / n)  # 99.9 % interval


def test_next_goal_is_uniform_over_the_other_rooms():
    labels = np.arange(9, dtype=np.int64)
    rng = np.random.default_rng(3)
    n = 16_000
    draws = np.array([next_goal(labels, 4, rng) for _ in range(n)])
    counts = np.bincount(draws, minlength=9)
    assert counts[4] == 0
    p = 1 / 8
    half = 3.29 * np.sqrt(p * (1 - p) / n)
    assert np.all(np.abs(counts[np.arange(9) != 4] / n - p) < half)
    assert next_goal(np.array([2], dtype=np.int64), 2, rng) == 2  # a single goal stays
    assert next_goal(labels, -1, rng) in labels  # not a goal: any room


# --------------------------------------------------------------------------- world step


EASY = Human((1.0, 0.0, 0.0), name="easy")


def make_task(**kw):
    return CombinedTask(layout="gridworld", human=kw.pop("human", EASY), **kw)


def nav_q_towards(task: CombinedTask, direction: int) -> np.ndarray:
    """A navigation table whose every row prefers ``direction`` (speed 3)."""
    lay = task.layout
    q = np.zeros((lay.n_labels * lay.n_cells, 25))
    q[:, move_action(direction, 3)] = 1.0
    return q


def gth_q_with(action: int) -> np.ndarray:
    q = np.zeros((dyn.N_GTH_STATES, 25))
    q[:, action] = 1.0
    return q


def args(task, nav_q, gth_q):
    """The kernels' world record (random starts)."""
    lay = task.layout
    return CombinedKernelArgs(
        lay.walls_h, lay.walls_v, lay.los_table(), lay.cell_labels,
        np.array(lay.goal_labels, dtype=np.int64), task.perception.to_array(),
        task.human.to_array(), nav_q, gth_q, np.array(task.speed_weights), task.tie_tol,
        -1, -1, 40)


def world(task, robot, human, engaged=0, goal=8, req=R, robot_ori=L, human_ori=R):
    lay = task.layout
    st = dyn.new_state()
    st[dyn.S_ROBOT] = lay.cell(*robot)
    st[dyn.S_ROBOT_ORI] = robot_ori
    st[dyn.S_HUMAN] = lay.cell(*human)
    st[dyn.S_HUMAN_ORI] = human_ori
    st[dyn.S_ENGAGED] = engaged
    st[dyn.S_GOAL] = goal
    st[dyn.S_REQ_DIR] = req
    return st


def test_action_29_executes_the_go_to_human_modules_greedy_move():
    task = make_task()
    a = args(task, nav_q_towards(task, R), gth_q_with(int(Action.DOWN2)))
    st = world(task, robot=(2, 2), human=(12, 12))
    reward, executed, reached = combined_step(a, st, int(Action.GO_TO_HUMAN),
                                              np.random.default_rng(0))
    assert executed == Action.DOWN2
    assert task.layout.rowcol(int(st[dyn.S_ROBOT])) == (4, 2)  # two cells down, no jump
    assert st[dyn.S_ROBOT_ORI] == D
    assert reward == 0.0 and not reached


def test_delegated_step_equals_the_social_step_of_that_move():
    task = make_task(human=Human((1, 0, 0), 0, 0, 0, 0.5, 0.5))  # a human that wanders
    a = args(task, nav_q_towards(task, R), gth_q_with(int(Action.UP_LEFT3)))
    lay = task.layout
    for seed in range(20):
        st = world(task, robot=(9, 9), human=(14, 15))
        ref = st.copy()
        combined_step(a, st, int(Action.GO_TO_HUMAN), np.random.default_rng(seed))
        rng = np.random.default_rng(seed)
        dyn.social_step(lay.walls_h, lay.walls_v, lay.los_table(), task.perception.to_array(),
                        task.human.to_array(), 0.0, ref, int(Action.UP_LEFT3), rng)
        # everything but the required direction (recomputed from navigation) agrees
        keep = [i for i in range(dyn.N_STATE) if i != dyn.S_REQ_DIR]
        np.testing.assert_array_equal(st[keep], ref[keep])


def test_other_actions_are_executed_unchanged():
    task = make_task()
    a = args(task, nav_q_towards(task, R), gth_q_with(int(Action.DOWN2)))
    for action in (int(Action.LEFT), int(Action.STAY), int(Action.LOOK_H), int(Action.HELLO)):
        st = world(task, robot=(5, 5), human=(5, 8))
        _, executed, _ = combined_step(a, st, action, np.random.default_rng(1))
        assert executed == action


def test_required_direction_comes_from_the_human_cell_for_the_current_goal():
    task = make_task()
    lay = task.layout
    nav_q = np.zeros((lay.n_labels * lay.n_cells, 25))
    human = lay.cell(12, 12)
    nav_q[human + 3 * lay.n_cells, move_action(UL, 3)] = 1.0  # goal 3 at the human's cell
    nav_q[human + 5 * lay.n_cells, move_action(DR, 3)] = 1.0  # goal 5 at the human's cell
    nav_q[lay.cell(2, 2) + 3 * lay.n_cells, move_action(D, 3)] = 1.0  # the robot's cell
    a = args(task, nav_q, gth_q_with(int(Action.STAY)))
    for goal, expected in ((3, UL), (5, DR)):
        st = world(task, robot=(2, 2), human=(12, 12), goal=goal, req=U)
        combined_step(a, st, int(Action.STAY), np.random.default_rng(0))
        assert st[dyn.S_REQ_DIR] == expected


def test_goal_switches_when_the_human_enters_the_goal_room():
    """An engaged easy human follows the robot one cell to the right, into room 5
    (rows 8-15, columns 16-23 of the 24 x 24 gridworld): one goal, a new goal room."""
    task = make_task()
    lay = task.layout
    a = args(task, nav_q_towards(task, R), gth_q_with(int(Action.STAY)))
    switched = set()
    for seed in range(40):
        st = world(task, robot=(10, 17), human=(10, 15), engaged=7, goal=5, req=R,
                   robot_ori=L, human_ori=R)
        assert lay.cell_labels[st[dyn.S_HUMAN]] == 4
        reward, _, reached = combined_step(a, st, int(Action.RIGHT),
                                           np.random.default_rng(seed))
        assert lay.rowcol(int(st[dyn.S_HUMAN])) == (10, 16)  # followed, now in room 5
        assert reached
        assert reward == 1.0  # level 7 and moved RIGHT, the required direction
        assert st[dyn.S_GOAL] != 5 and st[dyn.S_GOAL] in lay.goal_labels
        switched.add(int(st[dyn.S_GOAL]))
    assert len(switched) > 4  # drawn among the other rooms, not a fixed successor


def test_no_goal_counted_while_the_human_stays_out_of_the_goal_room():
    task = make_task()
    a = args(task, nav_q_towards(task, R), gth_q_with(int(Action.STAY)))
    st = world(task, robot=(10, 17), human=(10, 15), engaged=7, goal=8, req=R)
    _, _, reached = combined_step(a, st, int(Action.RIGHT), np.random.default_rng(0))
    assert not reached and st[dyn.S_GOAL] == 8


def test_reset_draws_a_goal_other_than_the_humans_room():
    task = make_task()
    lay = task.layout
    w = args(task, nav_q_towards(task, R), gth_q_with(int(Action.STAY)))._replace(tie_tol=1e-9)
    rng = np.random.default_rng(5)
    st = dyn.new_state()
    for _ in range(300):
        combined_reset(w, st, rng)
        assert st[dyn.S_ROBOT] != st[dyn.S_HUMAN]
        assert st[dyn.S_GOAL] != lay.cell_labels[st[dyn.S_HUMAN]]
        assert st[dyn.S_ENGAGED] == 0 and st[dyn.S_REQ_DIR] == R


# --------------------------------------------------------------------------- trials


@pytest.fixture(scope="module")
def leader():
    """Modules of a scripted leader: the social module says HELLO at level 3/4, COME at
    5, POINTING at 6, walks in the required direction at level 7, and otherwise turns to
    the human (LOOK_H) or delegates to go-to-human; navigation points at the goal room
    (exact values on the open gridworld); go-to-human is a learner's table."""
    from simlab.visitlab.envs import encode_social
    from simlab.visitlab.passive import nav_optimal_q
    from simlab.visitlab.training import train

    task = make_task(max_steps=60)
    social = np.zeros((dyn.N_SOCIAL_STATES, 30))
    for level in range(8):
        for dist in range(5):
            for req in range(8):
                for angle in range(8):
                    s = encode_social(level, dist, req, angle)
                    if level == 7:
                        a = move_action(req, 1)
                    elif level in (3, 4) and 1 <= dist <= 3:
                        a = int(Action.HELLO)
                    elif level == 5:
                        a = int(Action.COME)
                    elif level == 6:
                        a = int(Action.POINTING)
                    elif level == 2 and 1 <= dist <= 3:
                        a = int(Action.LOOK_H)
                    else:
                        a = int(Action.GO_TO_HUMAN)
                    social[s, a] = 1.0
    gth = train("gotohuman", "mb-egreedy", trials=300, seeds=1, seed=2, progress=False).q[0]
    return task, Modules(nav_optimal_q(task.layout), social, gth)


def test_goals_per_trial_count_the_rooms_the_human_entered(leader):
    task, modules = leader
    lay = task.layout
    episodes = record_episodes(task, modules, 8, (np.random.default_rng(1),
                                                  np.random.default_rng(2)))
    run = evaluate(task, modules, 8, (np.random.default_rng(1), np.random.default_rng(2)))
    assert [e.goals for e in episodes] == run.goals.astype(int).tolist()
    for e in episodes:
        before, after = e.states[:-1], e.states[1:]
        entered = lay.cell_labels[after[:, dyn.S_HUMAN]] == before[:, dyn.S_GOAL]
        np.testing.assert_array_equal(e.reached.astype(bool), entered)
        # the goal changes exactly at the steps that count one
        changed = after[:, dyn.S_GOAL] != before[:, dyn.S_GOAL]
        np.testing.assert_array_equal(changed, entered)
        np.testing.assert_array_equal(e.executed[e.actions != 29], e.actions[e.actions != 29])
        assert np.all(e.executed[e.actions == 29] < 25)
    assert run.goals.sum() > 0  # the scripted leader does lead the human somewhere


def test_evaluation_is_deterministic_by_seed_and_beats_random_actions(leader):
    task, modules = leader

    def gens():
        return np.random.default_rng(11), np.random.default_rng(12)

    a = evaluate(task, modules, 30, gens())
    b = evaluate(task, modules, 30, gens())
    np.testing.assert_array_equal(a.goals, b.goals)
    chance = evaluate(task, modules, 30, gens(), epsilon=1.0)
    assert a.goals.mean() > chance.goals.mean()


def test_episode_gif_has_one_frame_per_step(leader, tmp_path):
    import imageio.v3 as iio

    task, modules = leader
    (ep,) = record_episodes(task, modules, 1, (np.random.default_rng(1),
                                               np.random.default_rng(2)))
    path = write_episode_gif(task, ep, tmp_path / "ep.gif")
    frames = iio.imread(path, index=None)
    assert frames.shape[0] == task.max_steps + 1
    with pytest.raises(ConfigError):
        write_episode_gif(task, ep, path)


def test_bad_settings_and_modules_raise_config_errors():
    with pytest.raises(ConfigError) as e:
        CombinedTask(speed_weights=(1, 2))
    assert e.value.key == "speed_weights"
    with pytest.raises(ConfigError):
        CombinedTask(max_steps=0)
    with pytest.raises(ConfigError):
        CombinedTask(robot_start=3, human_start=3)
    task = CombinedTask()
    bad = Modules(np.zeros((10, 25)), np.zeros((2560, 30)), np.zeros((320, 25)))
    with pytest.raises(ConfigError) as e:
        evaluate(task, bad, 1, (np.random.default_rng(0), np.random.default_rng(0)))
    assert e.value.key == "nav_q"
