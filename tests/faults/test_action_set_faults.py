"""What a file's actions mean is never guessed: an 8-action count file without ``--n-actions``,
an action numbering given for a dataset that records its own, and a start state that is the
goal are refused before any work, naming the fix (exit 2, nothing written)."""

from __future__ import annotations

from pathlib import Path

from tests.faults.conftest import assert_refused, run_cli, tree_hashes


def _refused(work: Path, capsys, argv: str, *needles: str) -> None:
    before = tree_hashes(work)
    assert_refused(run_cli(argv.format(w=work).split(), capsys), *needles)
    assert tree_hashes(work) == before


def test_an_8_action_count_file_without_n_actions(work: Path, capsys) -> None:
    (work / "c8.csv").write_text("s,a,s_next,count\n0,0,1,3\n1,3,0,2\n2,7,2,1\n")
    before = tree_hashes(work)
    # read as simlab's 16 it gave "nan bits" for the fast actions
    _refused(work, capsys, "estimate --counts {w}/c8.csv --states {w}/states.json "
             "--out {w}/m.npz --no-plot", "c8.csv", "0..7", "--n-actions 8")
    assert not (work / "m.npz").exists() and tree_hashes(work) == before
    # with the count given it is read
    res = run_cli(f"estimate --counts {work}/c8.csv --states {work}/states.json --n-actions "
                  f"8 --convention ccw-east --out {work}/m.npz --no-plot".split(), capsys)
    assert res.code == 0, res.stderr
    assert "nan" not in res.stdout


def test_a_numbering_given_for_a_dataset_that_records_its_own(work: Path, capsys) -> None:
    res = run_cli(f"import-log {work}/log.txt --states {work}/states.json --out "
                  f"{work}/il".split(), capsys)  # ccw-east, 8 actions
    assert res.code == 0, res.stderr
    # the default spelled out is still a choice: the dataset's own record is ccw-east
    _refused(work, capsys, "estimate {w}/il --convention simlab --out {w}/m.npz --no-plot",
             "convention", "records its own action set")
    assert not (work / "m.npz").exists()


def test_an_episodic_task_that_starts_at_its_goal(work: Path, capsys) -> None:
    _refused(work, capsys, "train --mdp {w}/mdp.npz --goal-states 3 --start-states 3,5 "
             "--task episodic --episodes 2 --runs 1 --out {w}/t --no-plots --no-progress",
             "start_states", "start state 3 is a goal state")
    assert not (work / "t").exists()
