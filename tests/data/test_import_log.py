"""Pose logs: decisions and actions recovered exactly from a synthetic log of known ones."""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from discretize.voronoi import Discretizer
from simlab import commands
from simlab.base.actions import parse_action_set
from simlab.base.errors import ConfigError
from simlab.cli import main
from simlab.data.dataset import open_dataset
from simlab.data.poselog import (
    ImportLogConfig,
    SegmentOptions,
    SegmentParams,
    decision_actions,
    import_log,
    read_pose_log,
    segment_decisions,
)

CCW = parse_action_set(8, "ccw-east")
CENTRES = np.array([[x, y] for y in (2.0, 1.0, 0.0) for x in (0.0, 1.0, 2.0, 3.0)])


def _simulate(plan, rng, *, noise=(0.003, 0.01), rate=2.0, speed=0.15, drive=2.0,
              idle=3.0, w=1.5):
    """Log of a robot executing ``plan`` = [(ccw-east action, blocked)], sampled at ``rate``.

    Each decision: ``idle`` s at rest, turn in place at ``w`` rad/s the short way to the
    action's heading (no turn when already facing it), then drive ``drive`` s at ``speed``
    unless blocked. Returns (samples (N, 4) t x y yaw with noise, true decisions as
    (t_start, t_end, action, blocked, turned)).
    """
    dt = 0.005
    x, y, yaw, t = 1.5, 1.0, 0.0, 0.0
    trace = [(t, x, y, yaw)]
    truth = []

    def step(vx: float, vy: float, wz: float, n: int) -> None:
        nonlocal x, y, yaw, t
        for _ in range(n):
            x, y, yaw, t = x + vx * dt, y + vy * dt, yaw + wz * dt, t + dt
            trace.append((t, x, y, yaw))

    for action, blocked in plan:
        step(0, 0, 0, round(idle / dt))
        t0 = t
        goal = CCW.heading(action)
        turn = (goal - yaw + math.pi) % (2 * math.pi) - math.pi
        if abs(turn) > 1e-9:
            n = round(abs(turn) / w / dt)
            step(0, 0, turn / (n * dt), n)
            yaw = goal
        if not blocked:
            step(speed * math.cos(goal), speed * math.sin(goal), 0, round(drive / dt))
        truth.append((t0, t, action, blocked, abs(turn) > 1e-9))
    step(0, 0, 0, round(idle / dt))
    trace = np.asarray(trace)
    # sample at `rate` Hz with a phase that does not line up with the motions
    times = np.arange(0.13, trace[-1, 0], 1.0 / rate)
    idx = np.searchsorted(trace[:, 0], times)
    samples = trace[idx].copy()
    samples[:, 1:3] += rng.normal(0, noise[0], (len(idx), 2))
    samples[:, 3] = (samples[:, 3] + rng.normal(0, noise[1], len(idx)) + math.pi) % (
        2 * math.pi) - math.pi
    return samples, truth


PLAN = [(0, False), (0, False), (2, False), (5, True), (5, False), (3, False), (7, True),
        (1, False), (6, False), (6, False), (4, True), (2, False), (4, False), (0, False),
        (3, True), (7, False)]


def test_synthetic_log_is_segmented_exactly() -> None:
    samples, truth = _simulate(PLAN, np.random.default_rng(0))
    t, xy, yaw = samples[:, 0], samples[:, 1:3], samples[:, 3]
    dec = segment_decisions(t, xy, yaw)
    assert len(dec) == len(PLAN)
    assert dec.blocked.tolist() == [b for _, b in PLAN]
    assert decision_actions(dec, CCW).tolist() == [a for a, _ in PLAN]
    # boundaries within one sample interval of the truth
    for k, (t0, t1, *_rest) in enumerate(truth):
        assert abs(t[dec.start[k]] - t0) <= 0.5 + 1e-9
        assert abs(t[dec.end[k]] - t1) <= 0.5 + 1e-9
    # decisions that needed no turn (repeated headings) start with the move
    no_turn = [k for k, tr in enumerate(truth) if not tr[4]]
    assert no_turn and all(dec.move_start[k] == dec.start[k] for k in no_turn)


def test_same_motion_in_simlab_convention_gives_the_remapped_actions() -> None:
    samples, _ = _simulate(PLAN, np.random.default_rng(1))
    dec = segment_decisions(samples[:, 0], samples[:, 1:3], samples[:, 3])
    simlab8 = parse_action_set(8, "simlab")
    expected = [simlab8.from_primitive(CCW.to_primitive(a)) for a, _ in PLAN]
    assert decision_actions(dec, simlab8).tolist() == expected


def test_sixteen_actions_take_the_speed_from_the_motion() -> None:
    plan = [(0, False), (2, False), (4, True), (6, False)]
    slow, _ = _simulate(plan, np.random.default_rng(2), speed=0.10)
    fast, _ = _simulate(plan, np.random.default_rng(2), speed=0.22)
    aset = parse_action_set(16, "ccw-east")
    for samples, offset in ((slow, 0), (fast, 8)):
        dec = segment_decisions(samples[:, 0], samples[:, 1:3], samples[:, 3])
        got = decision_actions(dec, aset).tolist()
        assert got == [a if b else a + offset for a, b in plan]


def test_noise_below_thresholds_makes_no_decisions() -> None:
    rng = np.random.default_rng(3)
    t = np.arange(100) * 0.5
    xy = 1.0 + rng.normal(0, 0.003, (100, 2))
    yaw = rng.normal(0, 0.01, 100)
    assert len(segment_decisions(t, xy, yaw)) == 0


def _write_log(path: Path, samples: np.ndarray, cells: np.ndarray | None = None,
               n_cells: int | np.ndarray | None = None) -> Path:
    lines = ["# t x y yaw cell n_cells", ""]
    per_line = np.broadcast_to(np.asarray(n_cells if n_cells is not None else 0),
                               (len(samples),))
    for k, (t, x, y, yaw) in enumerate(samples):
        extra = "" if cells is None else f" {cells[k]}" + ("" if n_cells is None
                                                           else f" {per_line[k]}")
        lines.append(f"{t:.3f} {x:.4f} {y:.4f} {yaw:.4f}{extra}  # sample {k}")
    path.write_text("\n".join(lines) + "\n")
    return path


def _centres_file(path: Path) -> Path:
    # id x y theta, ids shuffled: the ids, not the line order, number the states
    order = np.random.default_rng(9).permutation(len(CENTRES))
    path.write_text("id x y theta\n" + "".join(
        f"{i} {CENTRES[i, 0]} {CENTRES[i, 1]} 0.0\n" for i in order))
    return path


def test_import_log_writes_a_dataset(tmp_path: Path) -> None:
    samples, truth = _simulate(PLAN, np.random.default_rng(4))
    log = _write_log(tmp_path / "run.log", samples)
    res = import_log(log, states=_centres_file(tmp_path / "centres.txt"), out=tmp_path / "ds")
    assert res.decisions == len(PLAN) and res.blocked == sum(b for _, b in PLAN)
    ds = open_dataset(tmp_path / "ds")
    assert ds.action_set == CCW and ds.n_actions == 8 and ds.n_states == len(CENTRES)
    assert ds.manifest["pose_source"] == "log" and ds.manifest["provenance"]["log"] == str(log)
    assert ds.column("a").tolist() == [a for a, _ in PLAN]
    assert ds.column("blocked").tolist() == [b for _, b in PLAN]
    disc = Discretizer(centres=CENTRES)
    xy = np.column_stack([ds.column("x"), ds.column("y")])
    np.testing.assert_array_equal(ds.column("s"), disc.state_of(xy))
    np.testing.assert_allclose(ds.column("t"), [tr[0] for tr in truth], atol=0.5 + 1e-9)
    blocked = ds.column("blocked")
    moved = np.hypot(ds.column("x_next") - ds.column("x"), ds.column("y_next") - ds.column("y"))
    assert np.all(moved[~blocked] > 0.25) and np.all(moved[blocked] < 0.03)


def test_import_log_can_take_states_from_the_cell_column(tmp_path: Path) -> None:
    samples, _ = _simulate(PLAN[:5], np.random.default_rng(5))
    cells = np.arange(len(samples)) % len(CENTRES)
    log = _write_log(tmp_path / "run.log", samples, cells, len(CENTRES))
    states = _centres_file(tmp_path / "centres.txt")
    import_log(log, states=states, out=tmp_path / "ds", use_cell_column=True)
    ds = open_dataset(tmp_path / "ds")
    dec = segment_decisions(samples[:, 0], samples[:, 1:3], samples[:, 3])
    assert ds.column("s").tolist() == cells[dec.start].tolist()
    assert ds.column("s_next").tolist() == cells[dec.end].tolist()
    wrong = _write_log(tmp_path / "wrong.log", samples, cells, 40)
    with pytest.raises(ConfigError, match="40 cells, the states file 12 states"):
        import_log(wrong, states=states, out=tmp_path / "ds2", use_cell_column=True)
    plain = _write_log(tmp_path / "plain.log", samples)
    with pytest.raises(ConfigError, match="no cell column"):
        import_log(plain, states=states, out=tmp_path / "ds3", use_cell_column=True)
    assert not (tmp_path / "ds2").exists() and not (tmp_path / "ds3").exists()


def test_the_cell_column_is_checked_against_the_states_file(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    samples, _ = _simulate(PLAN, np.random.default_rng(8))
    robot = CENTRES.copy()
    robot[5] += (0.2, 0.0)  # the robot's state 5 reaches 0.1 m further east than the file's
    cells = Discretizer(centres=robot).state_of(samples[:, 1:3])
    near = Discretizer(centres=CENTRES).state_of(samples[:, 1:3])
    assert 0 < np.sum(cells != near)  # the walk crosses the moved boundary
    log = _write_log(tmp_path / "run.log", samples, cells, len(CENTRES))
    states = _centres_file(tmp_path / "centres.txt")
    # states from the nearest centre: the dataset keeps them, the check still reports
    res = import_log(log, states=states, out=tmp_path / "ds")
    assert res.cell_check is not None
    assert res.cell_check.agreement == pytest.approx(np.mean(cells == near), abs=1e-12)
    assert res.cell_check.samples == len(samples)
    ds = open_dataset(tmp_path / "ds")
    assert ds.manifest["provenance"]["cell_column_check"]["agreement"] == \
        pytest.approx(res.cell_check.agreement)
    dec = segment_decisions(samples[:, 0], samples[:, 1:3], samples[:, 3])
    assert ds.column("s").tolist() == near[dec.start].tolist()
    # the command line prints it
    assert main(["import-log", str(log), "--states", str(states), "--out",
                 str(tmp_path / "ds2"), "--n-actions", "8", "--convention", "ccw-east"]) == 0
    assert (f"agrees with the nearest centre of the states file in "
            f"{100 * res.cell_check.agreement:.1f} % of {len(samples)} samples"
            in capsys.readouterr().out)
    # no cell column, or one numbering other states: nothing to compare
    plain = import_log(_write_log(tmp_path / "plain.log", samples), states=states,
                       out=tmp_path / "ds3")
    assert plain.cell_check is None
    other = import_log(_write_log(tmp_path / "other.log", samples, cells, 40), states=states,
                       out=tmp_path / "ds4")
    assert other.cell_check is None
    assert open_dataset(tmp_path / "ds4").manifest["provenance"]["cell_column_check"] is None


def test_a_growing_n_cells_leaves_out_the_decisions_before_their_state(tmp_path: Path
                                                                        ) -> None:
    samples, _ = _simulate(PLAN, np.random.default_rng(6))
    cells = Discretizer(centres=CENTRES).state_of(samples[:, 1:3])
    # states are built as the robot goes: 0 at first, then the count grows by one every 4
    # samples to the full 12 (cells numbered in the final set)
    n_at = np.minimum(len(CENTRES), np.arange(len(samples)) // 4)
    log = _write_log(tmp_path / "grow.log", samples, cells, n_at)
    res = import_log(log, states=_centres_file(tmp_path / "c.txt"), out=tmp_path / "ds",
                     use_cell_column=True)
    dec = segment_decisions(samples[:, 0], samples[:, 1:3], samples[:, 3])
    early = cells >= n_at
    keep = ~(early[dec.start] | early[dec.end])
    assert 0 < keep.sum() < len(dec)  # the case is a real one: some of each
    assert res.decisions == int(keep.sum()) and res.before_state == int((~keep).sum())
    ds = open_dataset(tmp_path / "ds")
    assert ds.column("s").tolist() == cells[dec.start[keep]].tolist()
    assert ds.column("s_next").tolist() == cells[dec.end[keep]].tolist()
    assert ds.manifest["provenance"]["decisions_before_their_state"] == int((~keep).sum())
    # with the nearest centre, every decision keeps its states
    res = import_log(log, states=_centres_file(tmp_path / "c.txt"), out=tmp_path / "ds2")
    assert res.decisions == len(dec) and res.before_state == 0


def test_poses_far_from_every_centre_are_refused_without_a_map(tmp_path: Path) -> None:
    samples, _ = _simulate(PLAN[:5], np.random.default_rng(7))
    samples[:, 1:3] += 1000.0  # another frame: 1 km away
    log = _write_log(tmp_path / "far.log", samples)
    with pytest.raises(ConfigError, match=r"far\.log: poses: .* pose samples are more than"):
        import_log(log, states=_centres_file(tmp_path / "c.txt"), out=tmp_path / "ds")
    assert not (tmp_path / "ds").exists()


@pytest.mark.parametrize(("text", "message"), [
    ("0 0 0 0\n1 0 0\n", "line 2: expected 4 columns"),
    ("0 0 0 0\n1 0 x 0\n", "line 2: y: expected a finite number, got 'x'"),
    ("0 0 0 0 1.5\n1 0 0 0 1\n", "line 1: cell: expected a whole number"),
    ("0 0 0\n", "line 1: expected 4 to 6 columns"),
    ("# only a comment\n0 0 0 0\n", "1 sample"),
    ("0 0 0 0\n0 1 0 0\n", "time does not increase at sample 2"),
    ("0 0 0 0 3 5\n1 0 0 0 3 4\n", r"n_cells decreases at sample 2 \(5 -> 4\)"),
    ("0 0 0 0 0 0\n1 0 0 0 0 0\n", "no state was ever built"),
    ("0 0 0 0 -1\n1 0 0 0 3\n", "negative cell -1 at sample 1"),
    ("0 0 0 0\n1 2e12 0 0\n", "line 2: x: 2e\\+12 is beyond"),
    ("1.5e12 0 0 0\n1.6e12 0 0 0\n", "line 1: t: 1.5e\\+12 is beyond.*times in s"),
    ("0 0 0 0 0 -4\n1 0 0 0 0 1\n", "negative n_cells -4 at sample 1"),
    ("0 0 0 0 4 4\n1 0 0 0 3 4\n", r"cell values 3\.\.4 outside 0\.\.3"),
])
def test_bad_logs_name_file_and_line(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "bad.log"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message) as exc:
        read_pose_log(path)
    assert str(path) in str(exc.value)


def test_a_log_in_unix_time_loads_as_it_comes(tmp_path: Path) -> None:
    """The ISIR lab's own logs stamp their samples in UNIX time (t ~ 1.5e9 s): the same
    motion shifted to 1.5e9 s gives the same decisions, actions and durations."""
    samples, _ = _simulate(PLAN, np.random.default_rng(4))
    local = read_pose_log(_write_log(tmp_path / "local.log", samples))
    shifted = samples.copy()
    shifted[:, 0] += 1_500_000_000.0
    unix = read_pose_log(_write_log(tmp_path / "unix.log", shifted))
    assert unix.t[0] == pytest.approx(1.5e9)
    a = segment_decisions(local.t, local.xy, local.yaw)
    b = segment_decisions(unix.t, unix.xy, unix.yaw)
    for name in ("start", "end", "move_start", "blocked"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    np.testing.assert_allclose(b.heading, a.heading, atol=1e-6)


def test_segmentation_refuses_bad_arrays() -> None:
    with pytest.raises(ConfigError, match="increase strictly"):
        segment_decisions([0.0, 1.0, 1.0], np.zeros((3, 2)), np.zeros(3))
    with pytest.raises(ConfigError, match=r"xy \(N, 2\)"):
        segment_decisions([0.0, 1.0], np.zeros((3, 2)), np.zeros(2))


def test_segment_params_are_validated() -> None:
    with pytest.raises(ConfigError, match="move_speed"):
        SegmentParams(move_speed=-1.0)
    with pytest.raises(ConfigError, match="must be > 0"):
        SegmentParams(turn_rate=0.0)


@pytest.mark.parametrize("seed", range(5))
def test_random_plans_are_recovered_exactly(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    plan, heading = [], 0
    for _ in range(30):
        a, blocked = int(rng.integers(8)), bool(rng.random() < 0.25)
        if blocked and a == heading:  # a blocked attempt without a turn leaves no trace
            a = (a + 1) % 8
        plan.append((a, blocked))
        heading = a
    samples, _ = _simulate(plan, rng)
    dec = segment_decisions(samples[:, 0], samples[:, 1:3], samples[:, 3])
    assert decision_actions(dec, CCW).tolist() == [a for a, _ in plan]
    assert dec.blocked.tolist() == [b for _, b in plan]


# ----------------------------------------------------------------- command line
def _states(tmp_path: Path) -> Path:
    path = tmp_path / "centres.txt"
    path.write_text("".join(f"{x} {y}\n" for x, y in CENTRES))
    return path


def test_cli_imports_a_log(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    samples, _ = _simulate(PLAN, np.random.default_rng(7))
    log = _write_log(tmp_path / "run.log", samples)
    out = tmp_path / "ds"
    argv = ["import-log", str(log), "--states", str(_states(tmp_path)), "--out", str(out),
            "--n-actions", "8", "--convention", "ccw-east"]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert f"{len(PLAN)} decisions ({sum(b for _, b in PLAN)} blocked)" in text
    ds = open_dataset(out)
    assert ds.column("a").tolist() == [a for a, _ in PLAN]
    manifest = (out / "_manifest.json").read_bytes()
    assert main(argv) == 2  # no --overwrite: refused, dataset untouched
    assert "not empty" in capsys.readouterr().err
    assert (out / "_manifest.json").read_bytes() == manifest
    assert main([*argv, "--overwrite", "--convention", "simlab"]) == 0
    assert json.loads((out / "_manifest.json").read_text())["action_set"]["convention"] == \
        "simlab"


def test_python_function_is_registered() -> None:
    from simlab.data.poselog import import_log

    assert commands.import_log is import_log


@pytest.mark.parametrize(("log_text", "extra", "message"), [
    ("0 0 0 0\n1 0 0\n", [], "line 2: expected 4 columns"),
    ("0 0 0 0\n1 0.5 0 0\n2 1.0 0 0\n", ["--use-cell-column"], "no cell column"),
    ("0 0 0 0\n1 0 0 0\n", [], "no motion found"),
    ("0 0 0 0\n1 0.5 0 0\n", ["--convention", "north-first"], "unknown direction convention"),
])
def test_cli_bad_input_is_one_line_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                          log_text: str, extra: list[str],
                                          message: str) -> None:
    log = tmp_path / "run.log"
    log.write_text(log_text)
    out = tmp_path / "ds"
    code = main(["import-log", str(log), "--states", str(_states(tmp_path)), "--out",
                 str(out), *extra])
    err = capsys.readouterr().err
    assert code == 2 and message in err and err.count("\n") == 1
    assert not out.exists()


def test_poses_are_checked_against_a_map_and_a_flipped_image_is_spotted(
        tmp_path: Path) -> None:
    from discretize.gridmap import FREE, OCCUPIED, UNKNOWN, OccupancyMap
    from discretize.mapio import write_map

    samples, _ = _simulate(PLAN, np.random.default_rng(4))  # x 1.5..2.1 m, y 0.9..1.5 m
    occ = np.full((60, 40), UNKNOWN, dtype=np.int8)  # 0.1 m pixels, 4 x 6 m
    occ[30:60, :] = OCCUPIED
    occ[31:59, 1:39] = FREE  # the lower half of the image is the lab: y 0.1..2.9 m
    right = tmp_path / "right.yaml"
    write_map(right, OccupancyMap(occupancy=occ, resolution=0.1))
    flipped = tmp_path / "flipped.yaml"
    write_map(flipped, OccupancyMap(occupancy=occ[::-1], resolution=0.1))
    log = _write_log(tmp_path / "run.log", samples)
    states = _centres_file(tmp_path / "centres.txt")
    res = import_log(log, states=states, out=tmp_path / "a", map=right)
    assert res.off_map == 0
    with pytest.raises(ConfigError) as exc:
        import_log(log, states=states, out=tmp_path / "b", map=flipped)
    text = str(exc.value)
    assert f"{len(samples)} of {len(samples)} pose samples are not on free pixels" in text
    assert "the first: sample 1 at" in text and "--flip-y" in text
    # one short line and a count, not every sample
    assert len(text) < 400 and "pose sample 1 " not in text
    assert not (tmp_path / "b").exists()
    res = import_log(log, states=states, out=tmp_path / "c", map=flipped, flip_y=True)
    assert res.off_map == 0 and open_dataset(tmp_path / "c").manifest["provenance"]["flip_y"]


# ----------------------------------------------------------------- options (ImportLogConfig)
def _toml_text(**values: object) -> str:
    return "".join(f"{k} = {json.dumps(v)}\n" for k, v in values.items())


def test_cli_config_file_gives_options_and_the_command_line_wins(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    samples, _ = _simulate(PLAN, np.random.default_rng(7))
    log = _write_log(tmp_path / "run.log", samples)
    out = tmp_path / "ds"
    toml = tmp_path / "import.toml"
    toml.write_text(_toml_text(states=str(_states(tmp_path)), out=str(out), convention="simlab",
                               **{"move-speed": 0.05, "join_gap": 1.5}))
    assert main(["import-log", str(log), "--config", str(toml), "--convention",
                 "ccw-east"]) == 0
    assert f"{len(PLAN)} decisions" in capsys.readouterr().out
    manifest = json.loads((out / "_manifest.json").read_text())
    assert manifest["action_set"]["convention"] == "ccw-east"  # the command line's
    assert manifest["provenance"]["segmentation"] == {  # the file's, and the defaults
        "move_speed": 0.05, "turn_rate": SegmentParams.turn_rate, "join_gap": 1.5,
        "speed_split": SegmentParams.speed_split}
    assert open_dataset(out).column("a").tolist() == [a for a, _ in PLAN]


def help_blocks(text: str) -> dict[str, str]:
    """``--help`` text -> option flag: its line(s) of help, whitespace collapsed."""
    blocks = re.split(r"\n  (?=-)", text)
    return {b.split()[0].rstrip(","): " ".join(b.split()) for b in blocks[1:]}


def test_cli_help_shows_the_defaults(capsys: pytest.CaptureFixture[str],
                                     monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COLUMNS", "200")  # one option per line: no wrapped defaults
    with pytest.raises(SystemExit) as exit_:
        main(["import-log", "--help"])
    text = capsys.readouterr().out
    d = SegmentParams()
    assert exit_.value.code == 0
    for flag, default in (("--move-speed", d.move_speed), ("--turn-rate", d.turn_rate),
                          ("--join-gap", d.join_gap), ("--speed-split", d.speed_split),
                          ("--n-actions", 8), ("--convention", "ccw-east")):
        assert f"(default {default})" in help_blocks(text)[flag]
    for flag in ("--states", "--out", "--use-cell-column", "--map", "--flip-y", "--overwrite",
                 "--config"):
        assert flag in text


def test_cli_unknown_config_key_names_the_file_and_the_key(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    samples, _ = _simulate(PLAN[:3], np.random.default_rng(7))
    log = _write_log(tmp_path / "run.log", samples)
    toml = tmp_path / "import.toml"
    toml.write_text(_toml_text(states=str(_states(tmp_path)), **{"move-sped": 0.05}))
    code = main(["import-log", str(log), "--config", str(toml), "--out", str(tmp_path / "ds")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert str(toml) in err and "move-sped: unknown option" in err and "move_speed" in err
    assert not (tmp_path / "ds").exists()


def test_python_function_takes_the_config_or_its_fields(tmp_path: Path) -> None:
    samples, _ = _simulate(PLAN, np.random.default_rng(8), speed=0.22)  # fast by default
    log = _write_log(tmp_path / "run.log", samples)
    states = _states(tmp_path)
    cfg = ImportLogConfig(log=log, states=states, out=tmp_path / "a", n_actions=16,
                          convention="simlab", turn_rate=0.4, speed_split=0.3)
    by_config = import_log(cfg)
    by_fields = import_log(str(log), states=states, out=tmp_path / "b", n_actions=16,
                           convention="simlab", turn_rate=0.4, speed_split=0.3)
    assert by_config.action_set == by_fields.action_set == parse_action_set(16, "simlab")
    np.testing.assert_array_equal(by_config.actions, by_fields.actions)
    simlab16 = parse_action_set(16, "simlab")  # 0.22 m/s is below the 0.3 split: all slow
    assert by_config.actions.tolist() == [simlab16.from_primitive(CCW.to_primitive(a))
                                          for a, _ in PLAN]
    a, b = open_dataset(tmp_path / "a").table, open_dataset(tmp_path / "b").table
    assert a.equals(b)
    with pytest.raises(ConfigError, match="turn_rate"):
        import_log(log, states=states, out=tmp_path / "c", turn_rate=-1.0)
    with pytest.raises(ConfigError, match=r"unknown option.*'segment'"):
        import_log(log, states=states, out=tmp_path / "c", segment=SegmentParams())
    assert not (tmp_path / "c").exists()


def test_segment_options_are_segment_params_spelled_once() -> None:
    fields = {f.name for f in dataclasses.fields(SegmentParams)}
    assert {f.name for f in dataclasses.fields(SegmentOptions)} == fields
    assert SegmentOptions().segment_params() == SegmentParams()
    group = SegmentOptions(move_speed=0.08, join_gap=0.0)
    assert group.segment_params() == SegmentParams(move_speed=0.08, join_gap=0.0)
    with pytest.raises(ConfigError, match="must be > 0"):
        SegmentOptions(move_speed=0.0)
