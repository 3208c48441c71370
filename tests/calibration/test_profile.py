"""The profile: each searched field moved alone from the winner, read against the walk-to-walk
spread (kinematic simulator on the 3 x 3 lattice: seconds)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from simlab.base.actions import parse_action_set
from simlab.base.errors import ConfigError
from simlab.calibration.config import CalibrationConfig
from simlab.calibration.profile import (
    TOLD_BAND,
    FieldMove,
    FieldProfile,
    Profile,
    allowed_values,
    moves,
    open_sides,
)
from simlab.calibration.report import _allowed, profile_section, report_json, write_outputs
from simlab.calibration.space import ParameterSpace, ParamSpec
from simlab.calibration.stages import calibrate
from simlab.data.walkers import KinematicParams
from tests.calibration.conftest import hidden_walk, real_table

CCW8 = parse_action_set(8, "ccw-east")


def test_moves_go_a_step_each_way_clipped_and_to_every_other_choice() -> None:
    space = ParameterSpace((ParamSpec("a", 0.0, 1.0), ParamSpec("b", 1.0, 10.0, "log"),
                            ParamSpec("m", choices=("x", "y", "z"))))
    u = np.array([0.1, 0.5, space.specs[2].unit("y")])
    out = moves(space, u, 0.25)
    a = [p[0] for k, p in out if k == 0]
    b = [p[1] for k, p in out if k == 1]
    m = [space.specs[2].value(p[2]) for k, p in out if k == 2]
    assert a == [0.0, pytest.approx(0.35)]          # 0.1 - 0.25 clipped to the range
    assert b == [0.25, 0.75]
    assert sorted(m) == ["x", "z"]
    # the other coordinates stay where they were
    assert all(np.allclose(np.delete(p, k), np.delete(u, k)) for k, p in out)
    # a field at a bound moves only inwards
    assert len(moves(space, np.array([0.0, 1.0, u[2]]), 0.25)) == 1 + 1 + 2


def test_the_profile_reads_each_move_against_the_winner_on_its_own_seed(lattice9,
                                                                      tmp_path) -> None:
    hidden = KinematicParams(drive_time=1.0)
    real = real_table(hidden_walk(lattice9, hidden, CCW8, 3.0, 11, "kinematic"), CCW8)
    space = ParameterSpace((ParamSpec("drive_time", 0.2, 2.0, "log"),
                            ParamSpec("heading_noise", 0.0, 0.5)))
    cfg = CalibrationConfig(hours_per_candidate=3.0, candidates=6, workers=1, seed=2,
                            simulator="kinematic", n_boot=20, progress=False,
                            transfer_seeds=3, profile_step=0.25)
    res = calibrate(real, "table", lattice9, space=space, config=cfg)
    prof = res.profile
    assert prof is not None and [f.name for f in prof.fields] == ["drive_time", "heading_noise"]
    base = res.twins[0]                       # the winner's confirming walk
    assert (prof.seed, prof.distance, prof.score) == (base.seed, base.distance, base.score)
    assert prof.sigma == pytest.approx(np.std([t.score for t in res.twins], ddof=1))
    winner = res.candidates[res.best]
    for k, f in enumerate(prof.fields):
        assert f.value == winner.values[f.name]
        for m in f.moves:  # each a quarter of the range away in the unit cube (or a bound)
            moved = space.specs[k].unit(m.value)
            assert abs(moved - winner.unit[k]) == pytest.approx(0.25) or moved in (0.0, 1.0)
        assert f.told == any(abs(m.score_change) > TOLD_BAND * prof.sigma for m in f.moves)
        # the winner is among the values the profile allows; a field not told keeps its range
        assert f.admits(f.value) is True
        if f.told is False:
            assert f.allowed == (space.specs[k].low, space.specs[k].high)
            assert f.open == (True, True)
    # a quarter of the drive time's (log) range moves every cell-crossing move: told
    assert prof.verdicts()["drive_time"] is True
    # the report says it, and records it
    text = profile_section(res)
    assert "What the real table can tell" in text and "| drive_time |" in text
    doc = json.loads(json.dumps(report_json(res)))
    assert doc["profile"]["fields"][0]["field"] == "drive_time"
    assert doc["profile"]["fields"][0]["allowed"] == list(prof.fields[0].allowed)
    assert doc["profile"]["fields"][0]["open"] == list(prof.fields[0].open)
    assert "values the data allow" in text
    assert math.isclose(doc["profile"]["sigma"], prof.sigma)
    # the space of the told fields is written when some field is not told
    files = write_outputs(res, tmp_path / "cal", plot=False)
    untold = [n for n, v in prof.verdicts().items() if v is not True]
    assert ("told_space.toml" in files) == bool(untold)
    assert (tmp_path / "cal" / "told_space.toml").exists() == bool(untold)


def test_a_move_that_worsens_the_score_beyond_the_band_excludes_the_values_past_it() -> None:
    spec = ParamSpec("x", 0.0, 1.0)

    def m(value: float, change: float) -> FieldMove:
        return FieldMove(value, 0.0, change)

    # both moves worse beyond the limit: the robot's value lies between them
    assert allowed_values(spec, 0.5, [m(0.25, 0.02), m(0.75, 0.03)], 0.01) == (0.25, 0.75)
    # one side within the limit: that side is open to the searched range's end
    assert allowed_values(spec, 0.5, [m(0.25, 0.005), m(0.75, 0.03)], 0.01) == (0.0, 0.75)
    # a move that lowers the score (the winner is not the bottom there) excludes nothing
    assert allowed_values(spec, 0.5, [m(0.25, -0.05), m(0.75, 0.03)], 0.01) == (0.0, 0.75)
    # at a bound the one move bounds its side, the other side is the bound itself
    assert allowed_values(spec, 1.0, [m(0.75, 0.02)], 0.01) == (0.75, 1.0)
    # no spread, no statement
    assert allowed_values(spec, 0.5, [m(0.25, 0.02)], math.nan) is None
    # a named field loses the choices whose move was worse
    mode = ParamSpec("mode", choices=("a", "b", "c"))
    assert allowed_values(mode, "b", [FieldMove("a", 0.0, 0.02), FieldMove("c", 0.0, 0.0)],
                          0.01) == ("b", "c")
    f = FieldProfile("x", 0.5, (), True, (0.25, 0.75))
    assert (f.admits(0.3), f.admits(0.75), f.admits(0.8)) == (True, True, False)
    # a side no move bounds is open: the data set no bound past the searched range's end
    assert open_sides(spec, 0.5, [m(0.25, 0.005), m(0.75, 0.03)], 0.01) == (True, False)
    assert open_sides(spec, 0.5, [m(0.25, 0.02), m(0.75, 0.03)], 0.01) == (False, False)
    assert open_sides(spec, 1.0, [m(0.75, 0.0)], 0.01) == (True, True)
    assert open_sides(spec, 0.5, [m(0.25, 0.02)], math.nan) == (False, False)
    g = FieldProfile("x", 0.5, (), True, (0.0, 0.75), (True, False))
    assert (g.admits(-0.5), g.admits(0.8)) == (True, False)
    assert (g.past_range(-0.5), g.past_range(0.3), f.past_range(-0.5)) == (True, False, False)
    # the report writes an open side as open, a bounded interval as its two ends
    assert _allowed(g.allowed, g.open) == "at most 0.75 (open below the searched 0)"
    assert _allowed(f.allowed, f.open) == "0.25 - 0.75"
    assert FieldProfile("mode", "b", (), True, ("b", "c")).admits("a") is False
    assert FieldProfile("x", 0.5, (), None).admits(0.5) is None


def test_a_profile_needs_the_confirmation_and_a_share_of_the_range() -> None:
    with pytest.raises(ConfigError, match="profile_step"):
        CalibrationConfig(profile_step=0.25, confirm=False)
    with pytest.raises(ConfigError, match="profile_step"):
        CalibrationConfig(profile_step=1.5)
    assert CalibrationConfig().profile_step == 0.0  # off by default: 2 d more walks


def _profile(verdicts: dict[str, bool | None]) -> Profile:
    return Profile(step=0.25, seed=7, transitions=100, distance=0.2, score=0.25, sigma=0.004,
                   fields=tuple(FieldProfile(n, 0.5, (), t) for n, t in verdicts.items()))


def test_the_told_fields_make_a_space_file_the_next_calibration_reads(tmp_path) -> None:
    from types import SimpleNamespace

    from simlab.calibration.report import told_space_toml
    from simlab.calibration.space import load_space

    space = ParameterSpace((ParamSpec("drive_time", 0.2, 2.0, "log"),
                            ParamSpec("heading_noise", 0.0, 0.5),
                            ParamSpec("distance_noise", 0.0, 0.5)))
    res = SimpleNamespace(space=space, profile=_profile(
        {"drive_time": True, "heading_noise": False, "distance_noise": None}))
    text = told_space_toml(res)
    assert text is not None and "heading_noise, distance_noise" in text
    path = tmp_path / "told_space.toml"
    path.write_text(text)
    told = load_space(path)
    assert told.specs == (space.specs[0],)      # the told field, its range and scale
    told.check_fields(KinematicParams())
    # nothing to write: no profile, every field told, or none
    assert told_space_toml(SimpleNamespace(space=space, profile=None)) is None
    for v in (True, False):
        assert told_space_toml(SimpleNamespace(space=space, profile=_profile(
            dict.fromkeys(space.names, v)))) is None
    # a named field keeps its choices
    mixed = ParameterSpace((ParamSpec("mode", choices=("fixed", "until_state_change")),
                            ParamSpec("wheel_noise", 0.0, 0.1)))
    text = told_space_toml(SimpleNamespace(space=mixed, profile=_profile(
        {"mode": True, "wheel_noise": False})))
    path.write_text(text)
    assert load_space(path).specs == (mixed.specs[0],)


def test_overwrite_replaces_a_told_space_file_only_when_calibrate_wrote_it(tmp_path) -> None:
    from simlab.calibration.report import TOLD_TITLE, check_outputs

    path = tmp_path / "told_space.toml"
    path.write_text("[parameters.x]\nlow = 0.0\nhigh = 1.0\n")  # a user's own space
    with pytest.raises(ConfigError, match="not written by simlab calibrate"):
        check_outputs(tmp_path, overwrite=True)
    with pytest.raises(ConfigError):
        check_outputs(tmp_path)  # and never without --overwrite
    path.write_text(TOLD_TITLE + " (simlab calibrate --profile-step 0.25)\n")
    assert check_outputs(tmp_path, overwrite=True)["told_space.toml"] == path
