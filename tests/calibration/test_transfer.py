"""The transfer report: expected steps to the goal on the real model (hand-solved chains,
properties on random MDPs), the action mapping, twins as models and as Q-tables, and
``simlab transfer`` end to end."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from discretize.voronoi import Discretizer
from simlab.base.actions import SIMLAB16, ActionSet, parse_action_set
from simlab.base.errors import ConfigError
from simlab.calibration.transfer import (
    QTable,
    QTableTwin,
    TransferModel,
    optimal_steps,
    policy_from_q,
    policy_steps,
    real_optimal_actions,
    transfer_report,
    twin_columns,
    twin_policy,
)

CCW8 = parse_action_set(8, "ccw-east")


# -- helpers (also used by tests/faults/test_transfer_faults.py) --------------------------

def lattice() -> Discretizer:
    """9 states on a 3 x 3 lattice 0.5 m apart, numbered row by row from the top left."""
    g = np.linspace(-0.5, 0.5, 3)
    return Discretizer(centres=np.array([(x, y) for y in g[::-1] for x in g]))


def lattice_counts(aset: ActionSet, *, n: int = 10, success: float = 0.8,
                   fast_cells: int = 2) -> np.ndarray:
    """Counts (9, A, 9) of a robot on :func:`lattice`: each action moves one cell (a fast
    one ``fast_cells``) in its direction ``round(success * n)`` times of ``n`` (clamped at
    the border), else stays."""
    S = 9
    C = np.zeros((S, aset.n_actions, S), dtype=np.int64)
    moved = round(success * n)
    for s in range(S):
        r, c = divmod(s, 3)
        for a in range(aset.n_actions):
            h = aset.heading(a)
            k = fast_cells if aset.speed_index(a) else 1
            dx, dy = round(float(np.cos(h))), round(float(np.sin(h)))
            s2 = min(max(r - dy * k, 0), 2) * 3 + min(max(c + dx * k, 0), 2)
            C[s, a, s2] += moved
            C[s, a, s] += n - moved
    return C


def write_counts(path: Path, counts: np.ndarray) -> Path:
    s, a, s2 = np.nonzero(counts)
    path.write_text("s,a,s_next,count\n" + "".join(
        f"{i},{j},{k},{counts[i, j, k]}\n" for i, j, k in zip(s, a, s2, strict=True)))
    return path


def line(success: float = 1.0) -> np.ndarray:
    """4 states in a line; action 0 left, action 1 right (succeeds w.p. ``success``, else
    stays); walls keep the robot in place."""
    P = np.zeros((4, 2, 4))
    for s in range(4):
        P[s, 0, max(s - 1, 0)] = 1.0
        P[s, 1, min(s + 1, 3)] += success
        P[s, 1, s] += 1.0 - success
    return P


def random_mdp(rng: np.random.Generator, S: int, A: int) -> np.ndarray:
    P = rng.random((S, A, S)) * (rng.random((S, A, S)) < 0.4)
    empty = P.sum(axis=2) == 0
    s, a = np.nonzero(empty)
    P[s, a, s] = 1.0
    return P / P.sum(axis=2, keepdims=True)


# -- hand-solved chains --------------------------------------------------------------------

def test_deterministic_line_hitting_times() -> None:
    P = line()
    assert optimal_steps(P, [3]).tolist() == [3.0, 2.0, 1.0, 0.0]
    assert twin_policy(P, [3]).tolist()[:3] == [1, 1, 1]
    assert policy_steps(P, [1, 1, 1, 0], [3]).tolist() == [3.0, 2.0, 1.0, 0.0]


def test_stochastic_line_is_distance_over_success_probability() -> None:
    # each cell takes a geometric number of tries: mean 1 / p
    np.testing.assert_allclose(optimal_steps(line(0.4), [3]), [7.5, 5.0, 2.5, 0.0])
    # two goals: left is sure (1 step per cell), right takes 2.5 tries
    np.testing.assert_allclose(optimal_steps(line(0.4), [0, 3]), [0.0, 1.0, 2.0, 0.0])


def test_stochastic_choice_solved_by_hand() -> None:
    # states 0, 1, goal 2. From 0: a0 -> goal or 1 (1/2 each); a1 -> goal w.p. 0.2, else stay.
    # From 1: a0 -> 0; a1 -> goal w.p. 0.2, else stay.
    # V1 = min(1 + V0, 5), V0 = min(1 + V1 / 2, 5)  =>  V0 = 3, V1 = 4 (both by a0).
    P = np.zeros((3, 2, 3))
    P[0, 0, [1, 2]] = 0.5
    P[0, 1, [0, 2]] = [0.8, 0.2]
    P[1, 0, 0] = 1.0
    P[1, 1, [1, 2]] = [0.8, 0.2]
    P[2, :, 2] = 1.0
    np.testing.assert_allclose(optimal_steps(P, [2]), [3.0, 4.0, 0.0])
    assert twin_policy(P, [2]).tolist()[:2] == [0, 0]
    # the other policy at 1: V1 = 5, V0 = 1 + 5 / 2
    np.testing.assert_allclose(policy_steps(P, [0, 1, 0], [2]), [3.5, 5.0, 0.0])
    best = real_optimal_actions(P, [2])
    assert best.tolist() == [[True, False], [True, False], [False, False]]


def test_a_policy_that_loops_never_arrives() -> None:
    P = line()
    steps = policy_steps(P, [1, 1, 0, 0], [3])  # 1 -> 2 -> 1 -> ...
    assert np.isinf(steps[:3]).all() and steps[3] == 0.0
    # pushing into the wall at 0 loops too; state 2 still arrives
    steps = policy_steps(P, [0, 1, 1, 0], [3])
    assert np.isinf(steps[0]) and steps[1:].tolist() == [2.0, 1.0, 0.0]
    # a chance of falling into the loop is enough: 1 goes right w.p. 1/2, else to 0 (stuck)
    Q = line().copy()
    Q[1, 1] = [0.5, 0.0, 0.5, 0.0]
    assert np.isinf(policy_steps(Q, [0, 1, 1, 0], [3])[1])


def test_an_untried_pair_keeps_the_robot_in_place() -> None:
    P = line(0.5)
    mask = np.ones((4, 2), dtype=bool)
    mask[1, 1] = False  # never tried: no data says the robot moves
    steps = policy_steps(P, [1, 1, 1, 0], [3], mask)
    assert np.isinf(steps[:2]).all() and steps[2:].tolist() == [2.0, 0.0]
    # the optimum may not use it either: the goal is out of reach from 0 and 1
    opt = optimal_steps(P, [3], mask)
    assert np.isinf(opt[:2]).all() and opt[2:].tolist() == [2.0, 0.0]


def test_the_goal_out_of_reach_is_infinite_for_every_policy() -> None:
    P = line()
    P[:, :, :] = 0.0
    P[np.arange(4), :, np.arange(4)] = 1.0  # nothing ever moves
    assert np.isinf(optimal_steps(P, [3])[:3]).all()


# -- properties ------------------------------------------------------------------------------

@pytest.mark.parametrize("seed", range(4))
def test_optimum_is_the_best_deterministic_policy(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for _ in range(15):
        S, A = int(rng.integers(2, 5)), int(rng.integers(1, 4))
        P = random_mdp(rng, S, A)
        mask = rng.random((S, A)) < 0.8
        goal = [int(rng.integers(S))]
        V = optimal_steps(P, goal, mask)
        every = np.array([policy_steps(P, pi, goal, mask)
                          for pi in itertools.product(range(A), repeat=S)])
        assert np.all(V <= every + 1e-9)  # no policy beats the optimum
        np.testing.assert_allclose(V, every.min(axis=0), rtol=1e-9)  # and one attains it
        pi = twin_policy(P, goal, mask)
        np.testing.assert_allclose(policy_steps(P, pi, goal, mask), V, rtol=1e-9)


def test_ties_go_to_the_lowest_action_and_results_repeat() -> None:
    P = np.concatenate([line()[:, 1:], line()[:, 1:], line()[:, :1]], axis=1)  # a0 == a1
    assert twin_policy(P, [3]).tolist()[:3] == [0, 0, 0]
    rng = np.random.default_rng(7)
    P = random_mdp(rng, 12, 4)
    a, b = twin_policy(P, [0]), twin_policy(P.copy(), [0])
    assert np.array_equal(a, b)
    np.testing.assert_array_equal(optimal_steps(P, [0]), optimal_steps(P.copy(), [0]))


def test_bad_arguments_are_refused() -> None:
    with pytest.raises(ConfigError, match="not in"):
        optimal_steps(line(), [4])
    with pytest.raises(ConfigError, match="sums to"):
        optimal_steps(line() * 2, [3])
    with pytest.raises(ConfigError, match="policy"):
        policy_steps(line(), [0, 2, 0, 0], [3])
    with pytest.raises(ConfigError, match="mask"):
        optimal_steps(line(), [3], np.ones((4, 3), dtype=bool))


# -- action sets -------------------------------------------------------------------------------

def test_16_primitives_map_onto_the_robots_8_actions() -> None:
    cols = twin_columns(SIMLAB16, CCW8, n_twin=16, n_real=8)
    assert cols.tolist() == CCW8.primitives().tolist() == [3, 5, 0, 4, 2, 6, 1, 7]
    fast = parse_action_set(8, "ccw-east", "fast")
    assert twin_columns(SIMLAB16, fast, n_twin=16, n_real=8).tolist() == [
        c + 8 for c in cols.tolist()]
    # same primitives, another numbering: a permutation
    assert twin_columns(CCW8, parse_action_set(8, "simlab"), n_twin=8, n_real=8).tolist() == [
        2, 6, 4, 0, 3, 1, 5, 7]
    with pytest.raises(ConfigError, match="none of which does real action 8"):
        twin_columns(CCW8, SIMLAB16, n_twin=8, n_real=16, where="twin.npz")
    with pytest.raises(ConfigError, match="unknown"):
        twin_columns(None, CCW8, n_twin=16, n_real=8)


def test_a_twin_in_another_numbering_of_the_same_actions_is_scored_through_it() -> None:
    real = TransferModel.from_counts(lattice_counts(CCW8), action_set=CCW8)
    simlab8 = parse_action_set(8, "simlab")
    twin = TransferModel.from_counts(lattice_counts(simlab8), action_set=simlab8, name="t")
    res = transfer_report(real, [twin], {"corner": [8]})
    g = res.goals[0]
    t = g.twins[0]
    assert t.mean_steps == pytest.approx(g.optimum_mean)
    assert not t.disagree.any() and not t.untried.any()
    # from the far corner: two diagonal moves of 1 / 0.8 tries each
    assert g.optimum[0] == pytest.approx(2 / 0.8)
    assert t.policy[0] == 7  # ccw-east 7 = SE


def test_a_16_action_twin_of_an_8_action_robot_is_refused() -> None:
    """A twin that walked simlab's 16 primitives did not walk the robot's 8 actions (its data
    spread over moves the robot does not have, at simlab's speeds): refused, naming the
    collect options, instead of scored on 8 of its columns."""
    real = TransferModel.from_counts(lattice_counts(CCW8), action_set=CCW8)
    twin = TransferModel.from_counts(lattice_counts(SIMLAB16), action_set=SIMLAB16, name="t")
    with pytest.raises(ConfigError, match=r"16 actions against the real model's 8.*"
                       r"--n-actions 8"):
        transfer_report(real, [twin], {"corner": [8]})


def test_a_twin_equal_to_the_real_model_scores_the_optimum_exactly() -> None:
    rng = np.random.default_rng(3)
    counts = rng.integers(0, 4, size=(9, 8, 9)) * (rng.random((9, 8, 9)) < 0.3)
    real = TransferModel.from_counts(counts, action_set=CCW8)
    twin = TransferModel.from_counts(counts, action_set=CCW8, name="same")
    res = transfer_report(real, [twin, twin], {"g": [4]}, weights="visits")
    g = res.goals[0]
    for t in g.twins:
        fin = np.isfinite(g.optimum)
        np.testing.assert_allclose(t.steps[fin], g.optimum[fin], rtol=1e-9)
        assert not t.disagree.any()
        assert t.ratio == pytest.approx(1.0)
    s = g.summary()
    assert s["spread"] == 0.0 and s["excess"] == pytest.approx(0.0, abs=1e-12)


def test_disagreement_excess_and_weights_by_hand() -> None:
    # real: right succeeds w.p. 1/2; the twin thinks "left" at 0 reaches the goal
    real = TransferModel(T=line(0.5), allowed=np.ones((4, 2), dtype=bool), name="real",
                         visits=np.array([1, 1, 2, 0]))
    bad = line(0.5)
    bad[0, 0] = [0.0, 0.0, 0.0, 1.0]
    twin = TransferModel(T=bad, allowed=np.ones((4, 2), dtype=bool), name="twin")
    res = transfer_report(real, [twin, real], {"end": [3]}, weights="visits")
    g = res.goals[0]
    assert g.starts.tolist() == [0, 1, 2]  # state 3 is the goal
    np.testing.assert_allclose(g.weights, [0.25, 0.25, 0.5])
    np.testing.assert_allclose(g.optimum, [6.0, 4.0, 2.0, 0.0])
    assert g.optimum_mean == pytest.approx(0.25 * 6 + 0.25 * 4 + 0.5 * 2)
    bad_t, good = g.twins
    # the twin goes left at 0 (1 step in the twin) and at 1 (2 steps against 4): on the real
    # robot 1 -> 0, then 0 stays forever; from 2 it goes right (2 steps, the optimum)
    assert bad_t.policy.tolist()[:3] == [0, 0, 1]
    assert bad_t.disagree.tolist() == [True, True, False, False]
    assert np.isinf(bad_t.steps[:2]).all() and bad_t.steps[2] == 2.0
    assert bad_t.never_share == pytest.approx(0.5)
    assert np.isinf(bad_t.mean_steps) and np.isinf(bad_t.ratio)
    assert good.mean_steps == pytest.approx(g.optimum_mean)
    s = g.summary()
    assert np.isinf(s["worst"]) and np.isinf(s["mean"]) and s["best"] == pytest.approx(3.5)
    assert "never" in res.summary_line()


def test_starts_without_a_real_way_to_the_goal_are_dropped() -> None:
    mask = np.ones((4, 2), dtype=bool)
    mask[0, 1] = False
    real = TransferModel(T=line(), allowed=mask, name="real")
    res = transfer_report(real, [real], {"end": [3]}, starts=[0, 1])
    g = res.goals[0]
    assert g.unreachable_starts == (0,) and g.starts.tolist() == [1]
    assert g.optimum_mean == 2.0


def test_q_table_policy_prefers_the_stored_greedy_over_the_real_columns() -> None:
    Q = np.zeros((2, 16))
    Q[0, 3] = 1.0   # slow RIGHT = ccw-east 0
    Q[0, 11] = 5.0  # fast RIGHT: not a real action, skipped
    Q[1, 0] = 2.0   # slow UP = ccw-east 2, but not valid
    Q[1, 1] = 1.0   # slow DOWN = ccw-east 6
    valid = np.ones((2, 16), dtype=bool)
    valid[1, 0] = False
    cols = twin_columns(SIMLAB16, CCW8, n_twin=16, n_real=8)
    table = QTable(Q=Q, goal=np.array([False, True]), valid=valid)
    assert policy_from_q(table, cols).tolist() == [0, 6]
    stored = QTable(Q=Q, goal=table.goal, valid=valid, greedy=np.array([5, 11]))
    # 5 = slow UP_RIGHT = ccw-east 1 is used; 11 (fast) is not a real action: argmax
    assert policy_from_q(stored, cols).tolist() == [1, 6]
    twin = QTableTwin(tables=(stored,), action_set=SIMLAB16)
    assert twin.table_for(np.array([False, True])) is stored
    assert twin.table_for(np.array([True, False])) is None


# -- the command --------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    from simlab.agents.storage import save_q_table
    from simlab.data.estimate import estimate

    d = tmp_path_factory.mktemp("transfer")
    states = lattice().save(d / "states.json")
    real_csv = write_counts(d / "real.csv", lattice_counts(CCW8))
    estimate(out=d / "real" / "mdp.npz", counts=real_csv, states=states, n_actions=8,
             convention="ccw-east", plot=False)
    for seed, success in ((0, 0.9), (1, 0.6)):
        estimate(out=d / f"twin{seed}" / "mdp.npz",
                 counts=write_counts(d / f"twin{seed}.csv",
                                     lattice_counts(CCW8, success=success)),
                 states=states, n_actions=8, convention="ccw-east", plot=False)
    # a Q-table directory as `simlab train` writes it: Q, goal_mask, valid, action set;
    # Q = minus the expected steps of the twin's optimum
    twin = TransferModel.from_counts(lattice_counts(CCW8), action_set=CCW8)
    V = optimal_steps(twin.T, [8])
    Q = -(1.0 + twin.T @ V)
    goal = np.zeros(9, dtype=bool)
    goal[8] = True
    (d / "q").mkdir()
    save_q_table(d / "q" / "q_s8.npz", Q, metadata={"goal": "s8",
                                                   "action_set": CCW8.to_json()},
                 arrays={"goal_mask": goal})
    return {"dir": d, "states": states, "real_csv": real_csv,
            "real": d / "real" / "mdp.npz", "twin0": d / "twin0" / "mdp.npz",
            "twin1": d / "twin1" / "mdp.npz", "q": d / "q"}


def test_cli_end_to_end(files, tmp_path, capsys) -> None:
    from discretize.mapio import write_map
    from simlab.cli import main
    from simlab.localization.maps import arena_map
    from simlab.physics.arena import load_arena

    map_yaml = tmp_path / "map" / "map.yaml"
    write_map(map_yaml, arena_map(load_arena("table"), 0.02))
    out = tmp_path / "out"
    argv = ["transfer", "--real", str(files["real"]), "--sim", str(files["twin0"]),
            str(files["twin1"]), str(files["q"]), "--goal-states", "8", "--states",
            str(files["states"]), "--map", str(map_yaml), "--n-boot", "20", "--out", str(out)]
    assert main(argv) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("over 1 goals, steps / real optimum (summed): ")
    assert "against a perfect twin's" in lines[0]  # the model twins have counts
    line_out = lines[1]
    assert line_out.startswith("twin policy: mean ") and "real optimum 2.03" in line_out
    assert sorted(p.name for p in out.iterdir()) == ["transfer.json", "transfer.md",
                                                     "transfer.png"]
    report = json.loads((out / "transfer.json").read_text())
    assert report["kind"] == "simlab-transfer"
    g = report["goals"][0]
    assert g["goal_states"] == [8] and g["start_states"] == list(range(8))
    # every twin moves the same directions as the real robot: each reaches the optimum
    assert g["optimum_mean"] == pytest.approx((5 * 2.5 + 3 * 1.25) / 8)
    assert [t["mean_steps"] for t in g["twins"]] == pytest.approx([g["optimum_mean"]] * 3)
    assert (out / "transfer.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # 10 transitions per pair of which 8 move: the perfect twin's floor is at least 1
    assert 1.0 <= g["perfect_twin_floor"]["ratio_median"] <= g["perfect_twin_floor"][
        "ratio_high_97.5"]
    assert "| twin | mean steps |" in (out / "transfer.md").read_text()
    # again with --overwrite: replaces its own outputs; same numbers (deterministic)
    assert main([*argv, "--overwrite", "--no-plot"]) == 0
    again = json.loads((out / "transfer.json").read_text())
    assert again["goals"] == report["goals"]


def test_a_map_stored_bottom_row_first_lies_under_the_states_with_flip_y(files, tmp_path,
                                                                       capsys) -> None:
    """The map figure's image is drawn in the states' frame: a map_server image stored
    bottom row first, read with ``--flip-y``, draws the figure the upright image draws; read
    without it, the obstacle lands in the other half of the figure."""
    from matplotlib.image import imread

    from discretize.mapio import OccupancyMap, write_map
    from simlab.cli import main

    occ = np.zeros((30, 30), dtype=np.int8)  # 1.5 m square at 5 cm, row 0 the top
    occ[2:12, 2:12] = 100                     # an obstacle at the top left only
    upright = OccupancyMap(occupancy=occ, resolution=0.05, origin=(-0.75, -0.75, 0.0))
    stored_flipped = OccupancyMap(occupancy=occ[::-1].copy(), resolution=0.05,
                                  origin=(-0.75, -0.75, 0.0))
    write_map(tmp_path / "up" / "map.yaml", upright)
    write_map(tmp_path / "down" / "map.yaml", stored_flipped)
    base = ["transfer", "--real", str(files["real"]), "--sim", str(files["twin0"]),
            "--goal-states", "8", "--states", str(files["states"]), "--n-boot", "0"]
    figures = {}
    for name, extra in (("up", ["--map", str(tmp_path / "up" / "map.yaml")]),
                        ("down", ["--map", str(tmp_path / "down" / "map.yaml")]),
                        ("flipped", ["--map", str(tmp_path / "down" / "map.yaml"), "--flip-y"])):
        assert main([*base, *extra, "--out", str(tmp_path / name)]) == 0
        figures[name] = imread(tmp_path / name / "transfer.png")
    np.testing.assert_array_equal(figures["flipped"], figures["up"])
    assert not np.array_equal(figures["down"], figures["up"])
    # a flip with no map to flip is refused before any work
    capsys.readouterr()
    assert main([*base, "--flip-y", "--out", str(tmp_path / "none")]) == 2
    err = capsys.readouterr().err
    assert "flip_y" in err and "--map" in err
    assert not (tmp_path / "none").exists()


def test_cli_count_file_and_the_q_tables_goal(files, tmp_path, capsys) -> None:
    from simlab.cli import main

    out = tmp_path / "out"
    assert main(["transfer", "--real", str(files["real_csv"]), "--n-actions", "8",
                 "--convention", "ccw-east", "--sim", str(files["q"]), "--out", str(out),
                 "--no-plot", "--start-states", "0,4"]) == 0
    g = json.loads((out / "transfer.json").read_text())["goals"][0]
    assert g["name"] == "s8" and g["start_states"] == [0, 4]  # the Q-table's own goal
    assert g["optimum_mean"] == pytest.approx((2.5 + 1.25) / 2)
    assert g["twins"][0]["mean_steps"] == pytest.approx(g["optimum_mean"])
    assert not (out / "transfer.png").exists()


def test_untried_rule_mask_plans_the_twin_on_the_real_robots_tried_pairs() -> None:
    # a line 0 - 1 - 2 - 3 (goal): left, right, and a slow right that succeeds w.p. 1/2;
    # the real robot never tried "right" at 1, so its optimum there is the slow one (2 steps)
    P = np.zeros((4, 3, 4))
    for s in range(4):
        P[s, 0, max(s - 1, 0)] = 1.0
        P[s, 1, min(s + 1, 3)] = 1.0
        P[s, 2, s] += 0.5
        P[s, 2, min(s + 1, 3)] += 0.5
    allowed = np.ones((4, 3), dtype=bool)
    allowed[1, 1] = False
    real = TransferModel(T=P, allowed=allowed, name="real")
    twin = TransferModel(T=P, allowed=np.ones((4, 3), dtype=bool), name="twin")
    stay = transfer_report(real, [twin], {"end": [3]}).goals[0]
    mask = transfer_report(real, [twin], {"end": [3]}, untried="mask").goals[0]
    np.testing.assert_allclose(stay.optimum, [4.0, 3.0, 1.0, 0.0])
    t = stay.twins[0]
    assert t.policy.tolist()[:3] == [1, 1, 1] and t.untried.tolist() == [False, True,
                                                                          False, False]
    assert np.isinf(t.steps[:2]).all() and np.isinf(t.regret[1])
    m = mask.twins[0]
    assert m.policy.tolist()[:3] == [1, 2, 1] and not m.untried.any()
    np.testing.assert_allclose(m.steps, stay.optimum)
    np.testing.assert_allclose(m.regret, 0.0)
    with pytest.raises(ConfigError, match="untried"):
        transfer_report(real, [twin], {"end": [3]}, untried="ignore")


def test_perfect_twin_floor() -> None:
    from simlab.calibration.transfer import transfer_floor

    rng = np.random.default_rng(11)
    counts = lattice_counts(CCW8, n=20, success=0.6)
    noisy = counts.copy()
    noisy[:, :, :] = rng.multinomial(20, counts / 20.0)  # 20 transitions per pair
    real = TransferModel.from_counts(noisy, action_set=CCW8)
    starts, w = np.arange(8), np.full(8, 1 / 8)
    a = transfer_floor(real, [8], starts, w, n_boot=40, rng=np.random.default_rng(1))
    b = transfer_floor(real, [8], starts, w, n_boot=40, rng=np.random.default_rng(1))
    np.testing.assert_array_equal(a.ratios, b.ratios)  # deterministic by seed
    # each resample's optimum is no worse than the real plan on it: ratios >= 1
    assert np.all(a.ratios[np.isfinite(a.ratios)] >= 1.0 - 1e-12)
    assert a.low <= a.median <= a.high
    # deterministic moves: every resample is the model itself, the floor is exactly 1
    sure = TransferModel.from_counts(lattice_counts(CCW8, success=1.0), action_set=CCW8)
    f = transfer_floor(sure, [8], starts, w, n_boot=5, rng=np.random.default_rng(0))
    assert f.ratios.tolist() == [1.0] * 5
    # with a million transitions per pair the bias vanishes
    big = TransferModel.from_counts(lattice_counts(CCW8, n=10**6, success=0.6),
                                    action_set=CCW8)
    f = transfer_floor(big, [8], starts, w, n_boot=10, rng=np.random.default_rng(0))
    assert f.high < 1.001
    res = transfer_report(real, [real], {"corner": [8]}, n_boot=10,
                          rng=np.random.default_rng(1))
    assert res.goals[0].floor is not None and "perfect twin" in res.summary_line()
    with pytest.raises(ConfigError, match="Generator"):
        transfer_report(real, [real], {"corner": [8]}, n_boot=10)


def test_overall_ratio_sums_steps_over_goals_before_dividing() -> None:
    """A 3-state chain 0 -> 1 -> 2 (action 0 moves right, action 1 stays; state 2 moves
    back left with action 0): goals {2} and {1}. Real optimum from the other states: goal 2
    steps (2 + 1) / 2 = 1.5, goal 1 steps (1 + 1) / 2 = 1. A twin identical to the real
    robot scores 1.0; a twin whose state-0 action is a stay never arrives (inf)."""
    T = np.zeros((3, 2, 3))
    T[0, 0, 1] = T[1, 0, 2] = T[2, 0, 1] = 1.0
    for s in range(3):
        T[s, 1, s] = 1.0
    real = TransferModel(T=T, allowed=np.ones((3, 2), bool), name="real")
    wrong = T.copy()
    wrong[0, 0] = [1.0, 0.0, 0.0]  # the twin believes moving right from 0 stays
    wrong[0, 1] = [0.0, 1.0, 0.0]  # ... and that "stay" moves right
    twin_wrong = TransferModel(T=wrong, allowed=np.ones((3, 2), bool), name="wrong")
    res = transfer_report(real, [real, twin_wrong], {"g2": [2], "g1": [1]})
    assert [g.optimum_mean for g in res.goals] == pytest.approx([1.5, 1.0])
    ratios = res.overall_ratios()
    assert ratios[0] == pytest.approx(1.0) and np.isinf(ratios[1])


def test_the_perfect_twin_line_is_one_on_sure_moves_and_falls_with_more_data() -> None:
    from simlab.calibration.transfer.score import perfect_twin_line

    sure = TransferModel.from_counts(lattice_counts(CCW8, success=1.0), action_set=CCW8)
    res = transfer_report(sure, [sure], {"corner": [8], "middle": [4]})
    line = perfect_twin_line(sure, res, np.full((9, 8), 3), n_boot=5,
                             rng=np.random.default_rng(0))
    # sure moves: every twin sample is the model itself, so is every real resample
    assert line.overall.tolist() == [1.0] * 5 and line.median == 1.0
    assert line.goal_medians.tolist() == [1.0, 1.0]
    rng = np.random.default_rng(3)
    noisy = TransferModel.from_counts(rng.multinomial(30, lattice_counts(CCW8, n=30,
                                                                         success=0.5) / 30),
                                      action_set=CCW8)
    res = transfer_report(noisy, [noisy], {"corner": [8]})
    few = perfect_twin_line(noisy, res, np.full((9, 8), 2), n_boot=40,
                            rng=np.random.default_rng(1))
    many = perfect_twin_line(noisy, res, np.full((9, 8), 2000), n_boot=40,
                             rng=np.random.default_rng(1))
    assert few.transitions == 9 * 8 * 2 and many.transitions == 9 * 8 * 2000
    assert 1.0 <= many.median <= few.median
    again = perfect_twin_line(noisy, res, np.full((9, 8), 2), n_boot=40,
                              rng=np.random.default_rng(1))
    np.testing.assert_array_equal(again.overall, few.overall)  # by seed


def test_the_perfect_twin_line_reads_what_twins_equal_to_the_robot_score() -> None:
    """A known robot on a ring whose moves have rare outcomes; real models of 10 visits per
    pair and twins equal to the robot walked 15 (20 per real model). Their mean score is
    the perfect twin's; a line drawn from the real model's plug-in shares reads below it,
    one drawn from its coverage-adjusted shares (the default) nearer."""
    from simlab.calibration.transfer.score import perfect_twin_line

    S, A = 16, 8
    P = np.zeros((S, A, S))
    w = (0.04, 0.1, 0.5, 0.26, 0.1)
    for s, a in itertools.product(range(S), range(A)):
        step = (1 if a < 4 else -1) * (1 + a % 2)
        for k, off in enumerate(range(-2, 3)):
            P[s, a, (s + step + off) % S] += w[k] if a % 2 == 0 else w[::-1][k]
    rng = np.random.default_rng(0)

    def walk(n: int) -> TransferModel:
        return TransferModel.from_counts(rng.multinomial(n, P), action_set=CCW8)

    truth, plug, adjusted = [], [], []
    for _ in range(10):
        real = walk(10)
        res = transfer_report(real, [walk(15) for _ in range(20)], {"g": [0]})
        truth.append(float(np.mean(res.overall_ratios())))
        v = np.full((S, A), 15)
        plug.append(perfect_twin_line(real, res, v, n_boot=40, rng=np.random.default_rng(1),
                                      adjusted=False).median)
        adjusted.append(perfect_twin_line(real, res, v, n_boot=40,
                                          rng=np.random.default_rng(1)).median)
    t, p, q = np.mean(truth), np.mean(plug), np.mean(adjusted)
    assert p < t and abs(q - t) < abs(p - t) / 2


def test_a_summary_of_twins_that_never_arrive_says_so_without_a_percentage() -> None:
    real = TransferModel(T=line(0.5), allowed=np.ones((4, 2), dtype=bool), name="real")
    bad = line(0.5)
    bad[0, 0] = [0.0, 0.0, 0.0, 1.0]
    twin = TransferModel(T=bad, allowed=np.ones((4, 2), dtype=bool), name="twin")
    text = transfer_report(real, [twin], {"end": [3]}).summary_line()
    assert "(never)" not in text and "never arrive from some start (no mean)" in text
    assert "none arrives; real optimum 4.00 steps" in text


def test_mask_leaves_out_pairs_the_real_robot_only_stayed_in() -> None:
    """A line 0 - 1 - 2 (goal): at 1 the real robot tried "right" only in place (its
    estimate: stays for good), the twin believes it moves; "slow right" moves half the
    time in both. Under ``stay`` the twin's policy is trapped at 1; under ``mask`` it
    chooses among the pairs the real robot left its state in."""
    P = np.zeros((3, 2, 3))
    for s in range(3):
        P[s, 0, min(s + 1, 2)] = 1.0
        P[s, 1, s] += 0.5
        P[s, 1, min(s + 1, 2)] += 0.5
    real_T = P.copy()
    real_T[1, 0] = [0.0, 1.0, 0.0]
    real = TransferModel(T=real_T, allowed=np.ones((3, 2), dtype=bool), name="real")
    twin = TransferModel(T=P, allowed=np.ones((3, 2), dtype=bool), name="twin")
    stay = transfer_report(real, [twin], {"end": [2]}).goals[0].twins[0]
    assert np.isinf(stay.steps[:2]).all()
    mask = transfer_report(real, [twin], {"end": [2]}, untried="mask").goals[0].twins[0]
    assert mask.policy[1] == 1 and mask.steps[1] == pytest.approx(2.0)
    assert mask.steps[0] == pytest.approx(3.0)


def test_an_mdp_whose_t_and_counts_disagree_is_refused(files, tmp_path, capsys) -> None:
    """T is scored on and the counts feed the floor's bootstrap: an mdp.npz whose T is not
    its counts normalised (T edited, counts from another run) is refused, naming the file,
    both fields and the fix, whether it is the real model or a twin."""
    from simlab.cli import main

    with np.load(files["real"], allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    tried = np.argwhere(arrays["counts"].sum(axis=2) > 0)[3]
    row = arrays["T"][tuple(tried)]
    arrays["T"][tuple(tried)] = 0.5 * row + 0.5 * np.roll(row, 1)  # still a distribution
    bad = tmp_path / "edited" / "mdp.npz"
    bad.parent.mkdir()
    np.savez(bad, **arrays)
    for real, sim in ((bad, files["twin0"]), (files["real"], bad)):
        code = main(["transfer", "--real", str(real), "--sim", str(sim), "--goal-states", "8",
                     "--out", str(tmp_path / "out"), "--no-plot", "--n-boot", "5"])
        err = capsys.readouterr().err
        assert code != 0 and not (tmp_path / "out").exists()
        assert str(bad) in err and "T, counts" in err and "T and counts disagree" in err
        assert f"({tried[0]}, {tried[1]})" in err and "re-estimate" in err
        assert len(err.strip().splitlines()) == 1
    # the file as simlab estimate wrote it is accepted
    assert main(["transfer", "--real", str(files["real"]), "--sim", str(files["twin0"]),
                 "--goal-states", "8", "--out", str(tmp_path / "ok"), "--no-plot",
                 "--n-boot", "5"]) == 0


def test_the_transfer_figure_draws_the_arena_in_the_frame_of_the_centres() -> None:
    # The arena under the map panels is drawn in its own frame, the frame the state centres
    # are in: its image spans the arena's bounds, its occupied pixels are the arena's, and
    # the figure with it differs from the figure without it.
    from matplotlib.figure import Figure

    from simlab.calibration.transfer import render_transfer_png
    from simlab.physics.arena import load_arena
    from simlab.physics.render import draw_arena_on

    arena = load_arena("table_obstacles")
    ax = Figure().subplots()
    bounds = draw_arena_on(ax, arena)
    assert bounds == arena.bounds
    img = ax.images[0]
    x0, x1, y0, y1 = img.get_extent()
    assert x0 == pytest.approx(bounds[0]) and y0 == pytest.approx(bounds[1])
    occ = np.asarray(img.get_array())
    h, w = occ.shape
    res = (x1 - x0) / w
    rows, cols = np.meshgrid(np.arange(h), np.arange(w), indexing="ij")
    centres = np.stack([x0 + (cols + 0.5) * res, y1 - (rows + 0.5) * res], axis=-1)
    np.testing.assert_array_equal(occ.astype(bool), arena.occupied(centres))
    assert 0 < occ.astype(bool).mean() < 0.5           # its obstacles, on a free table
    lattice9 = lattice()
    counts = lattice_counts(CCW8)
    real = TransferModel.from_counts(counts, action_set=CCW8, centres=lattice9.centres)
    twin = TransferModel.from_counts(counts, action_set=CCW8, name="same",
                                     centres=lattice9.centres)
    res_t = transfer_report(real, [twin], {"g": [4]})
    assert render_transfer_png(res_t, arena=arena) != render_transfer_png(res_t)

