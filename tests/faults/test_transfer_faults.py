"""``simlab transfer`` refuses bad input: exit 2, one line naming the problem, nothing
written (every file that existed is byte-identical, no output directory appears)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from simlab.base.actions import SIMLAB16, parse_action_set
from tests.calibration.test_transfer import lattice, lattice_counts, write_counts
from tests.faults.conftest import assert_refused, run_cli, tree_hashes

CCW8 = parse_action_set(8, "ccw-east")


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """states.json, real.csv (8 actions), real.npz, twin.npz (8 actions), twin16.npz (16),
    small.npz (4 states), q/ (a Q-table for goal 8 only)."""
    from simlab.agents.storage import save_q_table
    from simlab.data.estimate import estimate

    d = tmp_path_factory.mktemp("transfer-faults")
    states = lattice().save(d / "states.json")
    write_counts(d / "real.csv", lattice_counts(CCW8))
    estimate(out=d / "real.npz", counts=d / "real.csv", states=states, n_actions=8,
             convention="ccw-east", plot=False)
    estimate(out=d / "twin16.npz", counts=write_counts(d / "t.csv", lattice_counts(SIMLAB16)),
             states=states, plot=False)
    estimate(out=d / "twin.npz", counts=write_counts(d / "t8.csv", lattice_counts(
        CCW8, success=0.7)), states=states, n_actions=8, convention="ccw-east", plot=False)
    small = np.zeros((4, 16, 4), dtype=np.int64)
    small[np.arange(4), :, np.arange(4)] = 1
    estimate(out=d / "small.npz", counts=write_counts(d / "small.csv", small), n_states=4,
             plot=False)
    goal = np.zeros(9, dtype=bool)
    goal[8] = True
    (d / "q").mkdir()
    save_q_table(d / "q" / "q_s8.npz", np.zeros((9, 8)), arrays={"goal_mask": goal},
                 metadata={"goal": "s8", "action_set": CCW8.to_json()})
    return d


def refused(lab: Path, tmp_path: Path, capsys, argv: list[str], *needles: str,
            out: Path | None = None) -> None:
    out = tmp_path / "out" if out is None else out
    before = tree_hashes(lab), tree_hashes(tmp_path)
    res = run_cli(["transfer", *argv, "--out", str(out)], capsys)
    assert_refused(res, *needles)
    assert (tree_hashes(lab), tree_hashes(tmp_path)) == before
    if not before[1]:
        assert not out.exists()


def test_missing_real_file(lab, tmp_path, capsys) -> None:
    refused(lab, tmp_path, capsys, ["--real", str(lab / "nope.npz"), "--sim",
                                    str(lab / "twin.npz"), "--goal-states", "8"],
            "nope.npz", "not found")
    refused(lab, tmp_path, capsys, ["--real", str(lab / "nope.csv"), "--sim",
                                    str(lab / "twin.npz"), "--goal-states", "8"],
            "nope.csv", "not found")


def test_missing_twin(lab, tmp_path, capsys) -> None:
    refused(lab, tmp_path, capsys, ["--real", str(lab / "real.npz"), "--sim",
                                    str(lab / "twin.npz"), str(lab / "gone.npz"),
                                    "--goal-states", "8"], "gone.npz", "not found")


def test_a_directory_without_q_tables(lab, tmp_path, capsys) -> None:
    (tmp_path / "empty").mkdir()
    refused(lab, tmp_path, capsys, ["--real", str(lab / "real.npz"), "--sim",
                                    str(tmp_path / "empty"), "--goal-states", "8"],
            "empty", "q_*.npz")


def test_action_sets_that_do_not_match(lab, tmp_path, capsys) -> None:
    # real counts read as simlab's 16 actions; the twin has the robot's 8 slow ones
    refused(lab, tmp_path, capsys, ["--real", str(lab / "t.csv"), "--states",
                                    str(lab / "states.json"), "--sim", str(lab / "twin.npz"),
                                    "--goal-states", "8"],
            "twin.npz", "8 actions against the real model's 16")
    # the robot's 8 actions against a twin of simlab's 16 primitives: the twin did not walk
    # the robot's actions; refused, with the collect options that make one that does
    refused(lab, tmp_path, capsys, ["--real", str(lab / "real.npz"), "--sim",
                                    str(lab / "twin16.npz"), "--goal-states", "8"],
            "twin16.npz", "16 actions against the real model's 8", "--n-actions 8")
    # a count file of 8-action rows read as 16 is fine; 16-action rows read as 8 are not
    refused(lab, tmp_path, capsys, ["--real", str(lab / "t.csv"), "--n-actions", "8",
                                    "--sim", str(lab / "twin.npz"), "--goal-states", "8"],
            "t.csv")


def test_states_that_do_not_match(lab, tmp_path, capsys) -> None:
    refused(lab, tmp_path, capsys, ["--real", str(lab / "real.npz"), "--sim",
                                    str(lab / "small.npz"), "--goal-states", "1"],
            "small.npz", "4 states")


def test_goal_out_of_range(lab, tmp_path, capsys) -> None:
    refused(lab, tmp_path, capsys, ["--real", str(lab / "real.npz"), "--sim",
                                    str(lab / "twin.npz"), "--goal-states", "8,99"],
            "real.npz", "goal_states", "[99]")
    refused(lab, tmp_path, capsys, ["--real", str(lab / "real.npz"), "--sim",
                                    str(lab / "twin.npz"), "--goal-states", "8",
                                    "--start-states", "-1"], "start_states", "[-1]")
    refused(lab, tmp_path, capsys, ["--real", str(lab / "real.npz"), "--sim",
                                    str(lab / "twin.npz"), "--goal-states", "x"],
            "goal_states", "state ids")


def test_no_goal_and_no_q_table_for_the_goal(lab, tmp_path, capsys) -> None:
    refused(lab, tmp_path, capsys, ["--real", str(lab / "real.npz"), "--sim",
                                    str(lab / "twin.npz")], "--goal-states")
    refused(lab, tmp_path, capsys, ["--real", str(lab / "real.npz"), "--sim",
                                    str(lab / "q"), "--goal-states", "4"],
            "no Q-table for goal s4")


def test_map_without_states(lab, tmp_path, capsys) -> None:
    refused(lab, tmp_path, capsys, ["--real", str(lab / "real.npz"), "--sim",
                                    str(lab / "twin.npz"), "--goal-states", "8",
                                    "--map", str(lab / "map.yaml")], "map", "--states")


def test_output_in_the_way(lab, tmp_path, capsys) -> None:
    args = ["--real", str(lab / "real.npz"), "--sim", str(lab / "twin.npz"),
            "--goal-states", "8"]
    blocker = tmp_path / "file"
    blocker.write_text("mine")
    refused(lab, tmp_path, capsys, args, "file", out=blocker)
    out = tmp_path / "out"
    out.mkdir()
    (out / "transfer.json").write_text('{"mine": true}')
    refused(lab, tmp_path, capsys, args, "transfer.json", "already exists", out=out)
    # --overwrite replaces only what simlab transfer wrote
    refused(lab, tmp_path, capsys, [*args, "--overwrite"], "transfer.json",
            "not written by simlab transfer", out=out)
    # an output directory inside an input (a Q-table directory)
    refused(lab, tmp_path, capsys, ["--real", str(lab / "real.npz"), "--sim", str(lab / "q")],
            "inside an input", out=lab / "q" / "report")


def test_an_8_action_count_file_is_not_read_as_16_actions(lab, tmp_path, capsys) -> None:
    # real.csv holds actions 0..7 only; without --n-actions it was read as simlab's 16
    # (every twin "never" arrived); refused, asking for the action count and numbering
    refused(lab, tmp_path, capsys, ["--real", str(lab / "real.csv"), "--states",
                                    str(lab / "states.json"), "--sim", str(lab / "twin.npz"),
                                    "--goal-states", "8"],
            "real.csv", "0..7", "--n-actions 8", "--convention")


def test_a_start_state_that_is_the_goal(lab, tmp_path, capsys) -> None:
    refused(lab, tmp_path, capsys, ["--real", str(lab / "real.npz"), "--sim",
                                    str(lab / "twin.npz"), "--goal-states", "8",
                                    "--start-states", "0,8"],
            "start_states", "start state 8 is a goal state")


def test_a_goal_the_real_robot_never_reached(lab, tmp_path, capsys) -> None:
    counts = lattice_counts(CCW8)
    into = counts[:, :, 4].copy()
    counts[:, :, 4] = 0
    counts[np.arange(9), :, np.arange(9)] += into  # every move into 4 stayed instead
    counts[4] = lattice_counts(CCW8)[4]
    write_counts(tmp_path / "never4.csv", counts)
    refused(lab, tmp_path, capsys, ["--real", str(tmp_path / "never4.csv"), "--n-actions",
                                    "8", "--convention", "ccw-east", "--states",
                                    str(lab / "states.json"), "--sim", str(lab / "twin.npz"),
                                    "--goal-states", "4"],
            "never reached goal s4", "state(s) [4]")


def test_no_plot_leaves_no_link_to_a_figure(lab, tmp_path, capsys) -> None:
    out = tmp_path / "out"
    res = run_cli(["transfer", "--real", str(lab / "real.npz"), "--sim", str(lab / "twin.npz"),
                   "--goal-states", "8", "--no-plot", "--out", str(out)], capsys)
    assert res.code == 0, res.stderr
    assert not (out / "transfer.png").exists()
    assert "transfer.png" not in (out / "transfer.md").read_text()
