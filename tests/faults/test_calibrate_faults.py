"""``simlab calibrate``: bad input refused before any simulation, nothing half-written, and
``--overwrite`` replacing only calibrate's own files (kinematic simulator, tiny budgets)."""

from __future__ import annotations

import errno
import json
import os
from pathlib import Path

import numpy as np
import pytest

from discretize.voronoi import Discretizer
from tests.faults.conftest import assert_refused, failing, run_cli, tree_hashes

FAST = ("--simulator kinematic --candidates 2 --hours-per-candidate 0.05 --confirm-top 1 "
        "--confirm-seeds 1 --transfer-seeds 1 --confirm-hours 0.05 --n-boot 5 "
        "--start-states none --workers 1 --no-progress")


def _argv(work: Path, out: str = "cal", extra: str = "") -> list[str]:
    return (f"calibrate --real {work}/counts.csv --states {work}/states.json --out "
            f"{work}/{out} {FAST} {extra}").split()


def test_calibrate_writes_its_files_and_overwrite_keeps_the_users(work: Path, capsys) -> None:
    res = run_cli(_argv(work), capsys)
    assert res.code == 0, res.stderr
    (work / "cal" / "notes.txt").write_text("mine")
    res = run_cli(_argv(work, extra="--overwrite"), capsys)
    assert res.code == 0, res.stderr
    assert (work / "cal" / "notes.txt").read_text() == "mine"
    assert sorted(p.name for p in (work / "cal").iterdir()) == [
        "calibration.png", "notes.txt", "primitives.toml", "report.json", "report.md",
        "transfer.png"]


@pytest.mark.parametrize(("extra", "needles"), [
    ("--start-states 3,99", ("start_states", "99")),
    ("--goal-states 31", ("goal_states", "31")),
    ("--goal-states x,y", ("goal_states",)),
    ("--confirm-seeds 0", ("confirm_seeds",)),
    ("--screen-share -1", ("screen_share",)),
])
def test_bad_options_are_refused_before_anything_runs(work: Path, capsys, extra: str,
                                                      needles: tuple[str, ...]) -> None:
    before = tree_hashes(work)
    assert_refused(run_cli(_argv(work, extra=extra), capsys), *needles)
    assert tree_hashes(work) == before and not (work / "cal").exists()


def test_a_missing_real_file_and_a_states_mismatch_name_the_file(work: Path, capsys) -> None:
    argv = _argv(work)
    argv[2] = str(work / "nothing.csv")
    assert_refused(run_cli(argv, capsys), "nothing.csv")
    g = np.linspace(-0.5, 0.5, 3)
    Discretizer(centres=np.array([(x, y) for y in g for x in g])).save(work / "s9.json")
    argv = _argv(work)
    argv[argv.index("--real") + 1] = str(work / "mdp.npz")
    argv[argv.index("--states") + 1] = str(work / "s9.json")
    assert_refused(run_cli(argv, capsys), "mdp.npz", "25 states", "9")
    assert not (work / "cal").exists()


def test_an_mdp_records_its_action_set_and_a_different_one_is_refused(work: Path,
                                                                      capsys) -> None:
    argv = _argv(work, extra="--n-actions 8 --convention ccw-east")
    argv[argv.index("--real") + 1] = str(work / "mdp.npz")
    assert_refused(run_cli(argv, capsys), "mdp.npz", "records 16 actions", "8 actions")


def test_existing_outputs_are_refused_before_the_work(work: Path, capsys) -> None:
    (work / "cal").mkdir()
    (work / "cal" / "report.md").write_text("the previous report")
    before = tree_hashes(work)
    assert_refused(run_cli(_argv(work), capsys), "report.md", "--overwrite")
    assert tree_hashes(work) == before
    (work / "afile").write_text("x")
    assert_refused(run_cli(_argv(work, out="afile"), capsys), "afile")


@pytest.mark.parametrize("nth", [1, 3])
def test_a_full_disk_keeps_the_previous_outputs_whole(work: Path, capsys, monkeypatch,
                                                      nth: int) -> None:
    assert run_cli(_argv(work), capsys).code == 0
    before = tree_hashes(work)
    real = os.fsync
    monkeypatch.setattr(os, "fsync", failing(errno.ENOSPC, nth, real))
    res = run_cli(_argv(work, extra="--overwrite --seed 4"), capsys)
    monkeypatch.setattr(os, "fsync", real)
    assert_refused(res, "no space left")
    assert tree_hashes(work) == before
    assert not [p for p in (work / "cal").iterdir() if p.name.startswith(".")]



def test_a_real_table_on_a_corner_of_the_lab_is_said_without_numpy_text(work: Path,
                                                                        capsys) -> None:
    # counts.csv: 6 transitions from 3 of the 25 states
    res = run_cli(_argv(work), capsys)
    assert res.code == 0, res.stderr
    warnings = [ln for ln in res.stderr.splitlines() if ": warning: " in ln]
    assert any("only 3 of 25 states (6 transitions)" in ln for ln in warnings), res.stderr
    assert not any("NaN" in ln or "slice" in ln for ln in res.stderr.splitlines())
    assert "nan" not in res.stdout


@pytest.mark.parametrize(("name", "text"), [
    ("primitives.toml", "# my robot, measured by hand\n[primitives]\nfast_speed = 0.25\n"),
    ("report.json", '{"my": "notes"}\n'),
])
def test_overwrite_never_replaces_a_file_the_user_wrote(work: Path, capsys, name: str,
                                                        text: str) -> None:
    (work / "cal").mkdir()
    (work / "cal" / name).write_text(text)
    before = tree_hashes(work)
    assert_refused(run_cli(_argv(work, extra="--overwrite"), capsys), name,
                   "not written by simlab calibrate")
    assert tree_hashes(work) == before


def test_overwrite_still_replaces_calibrates_own_outputs(work: Path, capsys) -> None:
    assert run_cli(_argv(work), capsys).code == 0
    res = run_cli(_argv(work, extra="--overwrite --seed 3"), capsys)
    assert res.code == 0, res.stderr
    assert json.loads((work / "cal" / "report.json").read_text())["config"]["seed"] == 3


def test_an_output_directory_that_is_a_file_is_not_answered_with_overwrite(
        work: Path, capsys) -> None:
    (work / "afile").write_text("x")
    before = tree_hashes(work)
    for extra in ("", "--overwrite"):
        res = run_cli(_argv(work, out="afile", extra=extra), capsys)
        assert_refused(res, "afile", "is a file")
        assert "--overwrite" not in res.stderr
    assert tree_hashes(work) == before


def test_a_space_file_with_a_bad_choice_fails_at_load_naming_the_file(work: Path,
                                                                      capsys) -> None:
    (work / "space.toml").write_text('[parameters.mode]\nchoices = ["fixed", "teleport"]\n'
                                     "[parameters.drive_time]\nlow = 0.2\nhigh = 1.0\n")
    argv = _argv(work, extra=f"--space {work}/space.toml")
    argv[argv.index("kinematic")] = "physics"  # mode is a field of the physics record
    before = tree_hashes(work)
    assert_refused(run_cli(argv, capsys), "space.toml", "parameters.mode", "teleport")
    assert tree_hashes(work) == before and not (work / "cal").exists()


@pytest.mark.parametrize(("extra", "field"), [
    ("--confirm-hours 1e9", "confirm_hours"),
    ("--screen-share 1e9", "screen_share"),
    ("--hours-per-candidate 1e9", "hours_per_candidate"),
])
def test_walk_sizes_are_bounded(work: Path, capsys, extra: str, field: str) -> None:
    argv = _argv(work)
    for flag in ("--confirm-hours", "--hours-per-candidate"):  # the FAST budgets
        if flag in extra:
            k = argv.index(flag)
            del argv[k:k + 2]
    before = tree_hashes(work)
    assert_refused(run_cli(argv + extra.split(), capsys), field)
    assert tree_hashes(work) == before and not (work / "cal").exists()


def test_calibrate_pool_refuses_folders_that_are_not_calibrations(work: Path, capsys) -> None:
    before = tree_hashes(work)
    common = (f"--real {work}/counts.csv --states {work}/states.json --out {work}/pool "
              "--no-progress")
    assert_refused(run_cli(f"calibrate-pool --runs {work} {work}/nothing {common}".split(),
                           capsys), "report.json", str(work))
    assert_refused(run_cli(f"calibrate-pool --runs {work}/nothing {work} {common}".split(),
                           capsys), "not a calibration folder", "nothing")
    assert tree_hashes(work) == before and not (work / "pool").exists()
