"""``simlab calibrate`` end to end (kinematic simulator) and its refusals."""

from __future__ import annotations

import itertools
import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from simlab.base.actions import parse_action_set
from simlab.base.errors import ConfigError
from simlab.calibration.command import load_base
from simlab.cli import main
from simlab.data.walkers import KinematicParams
from simlab.physics.motion import PrimitiveParams
from tests.calibration.conftest import hidden_walk, write_counts_csv

CCW8 = parse_action_set(8, "ccw-east")


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory, lattice9) -> tuple[Path, Path, float]:
    d = tmp_path_factory.mktemp("cal")
    states = d / "states.json"
    lattice9.save(states)
    sim = hidden_walk(lattice9, KinematicParams(drive_time=0.9), CCW8, 1.0, 4, "kinematic")
    return write_counts_csv(d / "real.csv", sim.counts), states, sim.hours


def argv(real: Path, states: Path, out: Path, *extra: str) -> list[str]:
    return ["calibrate", "--real", str(real), "--states", str(states), "--out", str(out),
            "--simulator", "kinematic", "--n-actions", "8", "--convention", "ccw-east",
            "--hours-per-candidate", "0.5", "--candidates", "3", "--workers", "1",
            "--n-boot", "20", "--no-progress", *extra]


def test_calibrate_writes_a_primitives_file_collect_can_read(inputs, tmp_path, capsys) -> None:
    real, states, hours = inputs
    out = tmp_path / "cal"
    assert main(argv(real, states, out, "--real-hours", f"{hours}")) == 0
    printed = capsys.readouterr().out
    assert "TV distance" in printed
    assert sorted(p.name for p in out.iterdir()) == [
        "calibration.png", "primitives.toml", "report.json", "report.md", "transfer.png"]
    report = json.loads((out / "report.json").read_text())
    assert len(report["candidates"]) == 3
    # the summary line names the confirmed winner, the one the report marks
    assert f"winner: candidate #{report['best_candidate']} of 3" in printed
    winners = {c["index"] for c in report["confirmed"] if c["index"] == report["best_candidate"]}
    assert winners == {report["best_candidate"]}
    # three twin seeds scored on the real model, every state a goal (9 states)
    overview = report["transfer"]["overview"]
    assert len(overview["twins"]) == 3 and overview["goals"] == 9
    assert all(t["ratio"] is None or t["ratio"] >= 1.0 - 1e-9 for t in overview["twins"])
    assert f"({len(overview['twins'])} twins of" in printed
    # read against a perfect twin at the same data, in the summary and the report
    assert "a perfect twin at the same data" in printed
    assert report["transfer"]["perfect_twin_line"]["n_boot"] > 0
    assert all("perfect_ratio" in r for r in report["transfer"]["data_curve"])
    # the same three walks pooled 1, 2 and 3 at a time; one walk per twin is the overview
    curve = report["transfer"]["data_curve"]
    assert [(r["walks"], r["pools"]) for r in curve] == [(1, 3), (2, 1), (3, 1)]
    sizes = [r["transitions"] for r in curve]
    assert all(a < b for a, b in itertools.pairwise(sizes))
    assert curve[0]["mean_ratio"] == pytest.approx(overview["mean_ratio"])
    assert curve[0]["worst_ratio"] == pytest.approx(overview["worst_ratio"])
    need = report["transfer"]["data_need"]
    assert ("policy data:" in printed) == (need is not None)
    cov = report["coverage"]
    assert cov["real_pairs_tried"] <= cov["real_pairs"] == report["real"]["pairs_visited"]
    assert report["real"]["action_set"]["convention"] == "ccw-east"
    assert report["real"]["transitions"] == int(np.loadtxt(real, delimiter=",",
                                                           skiprows=1)[:, 3].sum())
    assert 0.0 <= report["distance"]["distance"] <= 1.0
    assert report["floor"]["low_2.5"] <= report["floor"]["median"] <= report["floor"]["high_97.5"]
    # the level against a twin equal to the robot (the perfect-twin floor), and the plug-in's
    perfect = report["perfect_twin_floor"]
    assert perfect["low_2.5"] <= perfect["median"] <= perfect["high_97.5"]
    d = report["distance"]["distance"]
    level = report["level"]
    assert (level["perfect_twin"], level["matched"]) == pytest.approx(
        (d / perfect["median"], d / report["matched_floor"]["median"]))
    # the level on the twin walks of seeds the winner was not chosen on
    assert level["fresh"]["walks"] == 2              # three twin seeds, one confirming walk
    assert level["fresh"]["perfect_twin"] == pytest.approx(
        level["fresh"]["distance"] / perfect["median"])
    assert f"a twin equal to the robot {perfect['median']:.3f}: " \
        f"{level['perfect_twin']:.2f}x, {level['fresh']['perfect_twin']:.2f}x on fresh" in printed
    params = load_base(out / "primitives.toml", "kinematic")
    assert params.drive_time == pytest.approx(report["params"]["drive_time"])
    assert report["decision_latency_fitted"] is True
    doc = tomllib.loads((out / "primitives.toml").read_text())
    assert doc["calibration"]["searched"] == ["drive_time", "distance_noise", "heading_noise"]
    md = (out / "report.md").read_text()
    assert "| transitions per hour |" in md and "bootstrap sampling floor" in md
    assert f"this twin is {report['level']['perfect_twin']:.2f}x that distance" in md
    assert doc["calibration"]["perfect_twin_floor_median"] == pytest.approx(perfect["median"])
    assert "## Transfer to the real robot" in md and "## Budgets" in md
    # the signature at the robot's visits, the search's rungs and the twin ensemble
    gap = report["signature_gap"]
    assert 0.0 <= gap["self_share"] <= 1.0 and gap["self_share_real"] == pytest.approx(
        report["real"]["self_transition_share"])       # the walk tried every real pair
    assert "## Signature at the robot's visits" in md
    assert f"signature at the robot's visits, twin / robot: stays {gap['self_share']:.3f}" \
        in printed
    search = report["search"]
    assert search["sampler"] == "tpe" and [r["rung"] for r in search["rungs"]] == [1, 2]
    assert [c["index"] for c in search["rungs"][0]["candidates"]] == [0, 1, 2]
    assert search["picks"][0] in {c["index"] for c in search["rungs"][1]["candidates"]}
    members = report["ensemble"]["members"]
    assert members[0]["index"] == report["best_candidate"]
    spread = report["ensemble"]["spread"]
    assert [r["field"] for r in spread] == doc["calibration"]["searched"]
    for row in spread:   # the winner is a member: its values lie within the ensemble's
        v = report["params"][row["field"]]
        assert row["low"] - 1e-9 <= v <= row["high"] + 1e-9
        assert 0.0 <= row["span_of_range"] <= 1.0 and isinstance(row["told"], bool)


def refused(args: list[str], capsys) -> str:
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("simlab calibrate: error:")
    return err


def test_existing_outputs_are_not_replaced(inputs, tmp_path, capsys) -> None:
    real, states, _ = inputs
    out = tmp_path / "cal"
    out.mkdir()
    (out / "report.md").write_text("mine")
    assert "already exists" in refused(argv(real, states, out), capsys)
    assert (out / "report.md").read_text() == "mine"
    assert sorted(p.name for p in out.iterdir()) == ["report.md"]


@pytest.mark.parametrize("change, message", [
    (("--states", "missing.json"), "missing.json"),
    (("--real", "WIDE"), "out of range"),  # action 12 in a table read as 8 actions
    (("--convention", "clockwise"), "unknown direction convention"),
    (("--candidates", "1"), "calibration.candidates"),
    (("--pose-source", "mcl"), "pose"),
    (("--space", "SPACE"), "no field 'slip'"),
    (("--primitives", "PRIMS"), "unknown field 'warp'"),
])
def test_bad_input_is_one_line_and_writes_nothing(inputs, tmp_path, capsys, change,
                                                   message) -> None:
    real, states, _ = inputs
    (tmp_path / "space.toml").write_text("[parameters.slip]\nlow = 0.0\nhigh = 0.5\n")
    (tmp_path / "prims.toml").write_text("[primitives]\nwarp = 9\n")
    (tmp_path / "wide.csv").write_text("s,a,s_next,count\n0,12,1,3\n")
    args = argv(real, states, tmp_path / "out")
    flag, value = change
    value = {"SPACE": str(tmp_path / "space.toml"), "PRIMS": str(tmp_path / "prims.toml"),
             "WIDE": str(tmp_path / "wide.csv"),
             "missing.json": str(tmp_path / "missing.json")}.get(value, value)
    if flag in args:
        args[args.index(flag) + 1] = value
    else:
        args += [flag, value]
    assert message in refused(args, capsys)
    assert not (tmp_path / "out").exists()


def test_physics_primitives_file_round_trip(tmp_path) -> None:
    path = tmp_path / "p.toml"
    path.write_text("[primitives]\ndrive_time = 0.8\ndetector_margin = 0.02\n[other]\nx = 1\n")
    p = load_base(path, "physics")
    assert p == PrimitiveParams(drive_time=0.8, detector_margin=0.02)
    path.write_text("[primitives]\ndrive_time = -1.0\n")
    with pytest.raises(ConfigError, match="drive_time"):
        load_base(path, "physics")


# ---- the options as CalibrateConfig: --config FILE, --help, the Python function

FAST = dict(simulator="kinematic", n_actions=8, convention="ccw-east", hours_per_candidate=0.25,
            candidates=2, workers=1, n_boot=10, confirm=False, progress=False)


def _same_run(report: dict) -> dict:
    """The report without its wall-clock times."""
    report = {k: v for k, v in report.items() if k != "wall_seconds"}
    report["candidates"] = [{k: v for k, v in c.items() if k != "wall_seconds"}
                            for c in report["candidates"]]
    return report


def test_config_file_and_the_command_line_wins(inputs, tmp_path, capsys) -> None:
    import argparse

    from simlab.calibration.command import CalibrateConfig
    from simlab.calibration.config import CalibrationConfig
    from simlab.cli.calibrate import add_arguments

    real, states, _ = inputs
    toml = tmp_path / "cal.toml"
    toml.write_text(f'real = "{real}"\nstates = "{states}"\nsimulator = "kinematic"\n'
                    'n-actions = 8\nconvention = "ccw-east"\ncandidates = 5\nseed = 3\n'
                    "confirm = false\n")
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    text = parser.format_help()
    # the command's defaults are the library's, and --help says them
    assert CalibrateConfig.candidates == CalibrationConfig.candidates
    assert f"(default {CalibrationConfig.candidates})" in text
    assert "(default signature)" in text and "--no-confirm" in text
    assert "(default tpe)" in text and "--eta" in text
    cfg = CalibrateConfig.from_args(parser.parse_args(
        ["--config", str(toml), "--out", "o", "--candidates", "3"]))
    assert cfg.real_action_set() == CCW8 and cfg.real == str(real)
    assert cfg.search_config() == CalibrationConfig(candidates=3, seed=3, simulator="kinematic",
                                                    confirm=False)
    # every search option of the command reaches the search
    cfg = CalibrateConfig.from_args(parser.parse_args(
        ["--config", str(toml), "--out", "o", "--sampler", "qmc", "--batch", "2", "--eta", "4",
         "--rungs", "3", "--signature-weight", "0.05", "--untried", "mask"]))
    assert cfg.search_config() == CalibrationConfig(
        candidates=5, seed=3, simulator="kinematic", confirm=False, sampler="qmc", batch=2,
        eta=4, rungs=3, signature_weight=0.05, untried="mask")
    toml.write_text("candidatez = 3\n")
    err = refused(argv(real, states, tmp_path / "out", "--config", str(toml)), capsys)
    assert str(toml) in err and "candidatez" in err
    assert not (tmp_path / "out").exists()


def test_calibrate_command_takes_the_config_or_its_fields(inputs, tmp_path) -> None:
    from simlab.calibration.command import CalibrateConfig, calibrate_command, calibrate_files
    from simlab.calibration.config import CalibrationConfig

    real, states, _ = inputs
    calibrate_command(CalibrateConfig(real=real, states=states, out=tmp_path / "a", **FAST))
    calibrate_command(real, states, "table", tmp_path / "b", **FAST)
    search = {k: v for k, v in FAST.items() if k not in ("n_actions", "convention")}
    calibrate_files(real, states, "table", tmp_path / "c", action_set=CCW8,
                    config=CalibrationConfig(**search))
    a, b, c = (_same_run(json.loads((tmp_path / d / "report.json").read_text())) for d in "abc")
    assert a == b == c and len(a["candidates"]) == 2
    assert a["real"]["action_set"]["convention"] == "ccw-east"
    with pytest.raises(ConfigError, match=r"calibration\.n_boot"):  # CalibrationConfig's check
        CalibrateConfig(real=real, states=states, out=tmp_path / "d", n_boot=0)


@pytest.mark.parametrize("aset, need, expected", [
    (parse_action_set(8, "ccw-east", "fast"), {"hours": 143.2, "transitions": 59073},
     "--primitives primitives.toml --n-actions 8 --convention ccw-east --speed fast "
     "--start-states all --hours 144 "),
    (parse_action_set(8, "3,5,1,4,2,6,0,7"), {"hours": None, "transitions": 59073},
     "--n-actions 8 --convention 3,5,1,4,2,6,0,7 --speed slow --start-states all "
     "--transitions 59073 "),
])
def test_the_policy_data_collect_line_walks_in_the_real_actions(aset, need, expected) -> None:
    from simlab.calibration.report import collect_line

    line = collect_line(aset, need)
    assert line.startswith("simlab collect ") and expected in line


@pytest.mark.parametrize("below", [False, True])
def test_the_policy_data_need_reaches_the_summary_and_the_report(inputs, tmp_path, capsys,
                                                                  monkeypatch, below) -> None:
    """With a need of 50,000 transitions (stubbed: the tiny walk's curve need not fall),
    the summary line and report.md say it, with the robot hours at the real rate and the
    collect command of that data; when it is the smallest size measured because the fit
    asked fewer, both say so and report.md gives the fit's own figure."""
    import simlab.calibration.report as report_mod

    need = {"limit": 1.06, "c": 50.0 if below else 500.0, "tolerance": 0.01,
            "transitions": 50_000.0, "flat": False, "below_measured": below,
            "fit_transitions": 5_000.0 if below else 50_000.0}
    monkeypatch.setattr(report_mod, "policy_need", lambda curve: dict(need))
    real, states, hours = inputs
    out = tmp_path / "cal"
    assert main(argv(real, states, out, "--real-hours", f"{hours}")) == 0
    printed = capsys.readouterr().out
    n_real = int(np.loadtxt(real, delimiter=",", skiprows=1)[:, 3].sum())
    h = 50_000 * hours / n_real
    assert f"policy data: 50,000 twin transitions ({h:.0f} h)" in printed
    md = (out / "report.md").read_text()
    assert "**50,000 twin transitions**" in md and f"--hours {math.ceil(h)} " in md
    said = ("the smallest size measured" in printed, "the fit's 5,000 lie below" in md)
    assert said == (below, below)
    report = json.loads((out / "report.json").read_text())
    assert report["transfer"]["data_need"]["hours"] == pytest.approx(h)


def test_policy_data_is_collected_and_scored_against_the_perfect_twin(lattice9, tmp_path,
                                                                      capsys) -> None:
    # moves of about a cell (1.5 s) and 6 h of real data: twins whose policies arrive
    states = tmp_path / "states.json"
    lattice9.save(states)
    sim = hidden_walk(lattice9, KinematicParams(drive_time=1.5), CCW8, 6.0, 4, "kinematic")
    real = write_counts_csv(tmp_path / "real.csv", sim.counts)
    out = tmp_path / "cal"
    assert main(argv(real, states, out, "--real-hours", f"{sim.hours}", "--policy-data",
                     "--goal-states", "0,8")) == 0
    printed = capsys.readouterr().out
    tr = json.loads((out / "report.json").read_text())["transfer"]
    need, policy = tr["data_need"], tr["policy_data"]
    assert need is not None  # three sizes whose twins arrive: a fit, or the largest pool
    # the recommended transitions, walked and scored on every goal
    assert policy["transitions"] == need["transitions"]
    assert set(policy["goal_ratios"]) == {g["name"] for g in tr["goals"]}
    assert policy["line"]["transitions"] == policy["transitions"]
    assert "the policy of" in printed and "collected transitions" in printed
    assert "| policy data | gap |" in (out / "report.md").read_text()


def test_a_pair_the_twin_cannot_reproduce_is_reported_and_drawn(inputs, tmp_path,
                                                                capsys) -> None:
    # The robot's busiest pair doctored: where this robot (0.9 s drives in 0.5 m cells)
    # mostly stays, it now always moves, which no kinematic twin of it does at that pair
    # alone. The report lists that pair, says how the twin differs, and draws it.
    real, states, hours = inputs
    counts = np.zeros((9, 8, 9), dtype=np.int64)
    for s, a, s2, n in np.loadtxt(real, delimiter=",", skiprows=1, dtype=np.int64):
        counts[s, a, s2] = n
    n = counts.sum(axis=2)
    s, a = np.unravel_index(np.argmax(n), n.shape)
    assert n[s, a] >= 10 and counts[s, a, s] >= n[s, a] / 2
    counts[s, a] = 0
    counts[s, a, (s + 1) % 9] = n[s, a]
    doctored = write_counts_csv(tmp_path / "doctored.csv", counts)
    out = tmp_path / "cal"
    assert main(argv(doctored, states, out, "--real-hours", f"{hours}")) == 0
    printed = capsys.readouterr().out
    c = json.loads((out / "report.json").read_text())["contradictions"]
    listed = {(r["state"], r["action"]): r for r in c["pairs"]}
    assert (s, a) in listed
    row = listed[(s, a)]
    assert row["stay_real"] == 0.0 and row["stay_twin"] > 0.5 and row["q"] < c["alpha"]
    assert row["real"] == n[s, a] and row["next_real"] == (s + 1) % 9
    assert c["tested"] + c["untested"] == int((counts.sum(axis=2) > 0).sum())
    assert f"at {len(listed)} of {c['tested']} real (s, a) pairs" in printed
    md = (out / "report.md").read_text()
    assert "## Where the twin contradicts the robot" in md and "![pairs](pairs.png)" in md
    assert f"| {s} | {a} (" in md and "(stays more)" in md
    assert (out / "pairs.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
