"""The profile: each searched field moved alone from the winner, read against the walk-to-walk
spread (kinematic simulator on the 3 x 3 lattice: seconds)."""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest

from simlab.base.actions import parse_action_set
from simlab.base.errors import ConfigError
from simlab.calibration.config import CalibrationConfig
from simlab.calibration.profile import (
    FieldMove,
    FieldProfile,
    Profile,
    allowed_values,
    moves,
    open_sides,
    told_band,
)
from simlab.calibration.report import _allowed, profile_section, report_json, write_outputs
from simlab.calibration.space import ParameterSpace, ParamSpec
from simlab.calibration.stages import calibrate
from simlab.data.walkers import KinematicParams
from tests.calibration.conftest import hidden_walk, real_table

CCW8 = parse_action_set(8, "ccw-east")


def test_the_band_is_students_for_the_spreads_degrees_of_freedom() -> None:
    """The 97.5 % quantiles of Student's t from their closed forms (1 degree of freedom: the
    Cauchy quantile tan(pi (p - 1/2)); 2: (2p - 1) / sqrt(2 p (1 - p)), 4.303), times
    sqrt(2); the normal band with the spread known; none without a degree of freedom."""
    p = 0.975
    assert told_band(2) == pytest.approx(math.sqrt(2.0) * (2 * p - 1) / math.sqrt(2 * p * (1 - p)))
    assert told_band(1) == pytest.approx(math.sqrt(2.0) * math.tan(math.pi * (p - 0.5)))
    assert told_band(None) == pytest.approx(1.959964 * math.sqrt(2.0))
    assert told_band(math.inf) == told_band(None)
    assert math.isnan(told_band(0))
    bands = [told_band(d) for d in (1, 2, 3, 5, 10, 30, 1000)]
    assert all(a > b for a, b in itertools.pairwise(bands)) and bands[-1] > told_band(None)


@pytest.mark.parametrize("walks", [3, 5])
def test_a_move_that_changes_nothing_is_told_one_time_in_twenty(walks: int) -> None:
    """What the band is for: a move whose true change is zero, read against a spread estimated
    from ``walks`` walks of the winner, passes the band 5 % of the time when the move and the
    walk it is read against are independent of that estimate, and less (about 3.6 % with three
    walks) when, as in the profile, that walk is one of them. The normal band with the same
    estimate passes far more often (0.16-0.19 with three walks): it told fields, and excluded
    values, that the walks could not tell."""
    rng = np.random.default_rng(11)
    n = 200_000
    winner = rng.normal(0.0, 1.0, (n, walks))          # the winner's walks, sigma 1
    sigma = winner.std(axis=1, ddof=1)
    band = told_band(walks - 1) * sigma
    apart = rng.normal(0.0, 1.0, n) - rng.normal(0.0, 1.0, n)
    assert np.mean(np.abs(apart) > band) == pytest.approx(0.05, abs=0.004)
    profile = rng.normal(0.0, 1.0, n) - winner[:, 0]   # a null move minus the base walk
    assert 0.02 < np.mean(np.abs(profile) > band) <= 0.05
    assert np.mean(np.abs(profile) > told_band(None) * sigma) > 0.09
    assert np.mean(np.abs(apart) > told_band(None) * sigma) > 0.1


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
    # the band is Student's for the spread's degrees of freedom: three walks, two
    assert prof.dof == len(res.twins) - 1 == 2
    assert prof.limit == pytest.approx(told_band(2) * prof.sigma)
    winner = res.candidates[res.best]
    for k, f in enumerate(prof.fields):
        assert f.value == winner.values[f.name]
        for m in f.alone:  # each a quarter of the range away in the unit cube (or a bound)
            moved = space.specs[k].unit(m.value)
            assert abs(moved - winner.unit[k]) == pytest.approx(0.25) or moved in (0.0, 1.0)
        assert f.told == any(abs(m.score_change) > prof.limit for m in f.alone)
        # the other confirmed candidates' walks on the same seed join as confirmed points
        others = [c for c in res.confirmed if c.seed == prof.seed and c.index != res.best]
        assert others and sorted((m.value, m.score_change) for m in f.moves if m.confirmed) \
            == sorted((c.values[f.name], c.score - base.score) for c in others)
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
    assert "basin of this winner" in text and "simlab calibrate-pool --runs" in text
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


def test_pair_moves_go_both_diagonals_both_ways_and_leave_out_a_field_that_stays() -> None:
    from simlab.calibration.profile import pair_moves

    space = ParameterSpace((ParamSpec("a", 0.0, 1.0), ParamSpec("b", 0.0, 1.0),
                            ParamSpec("c", 0.0, 1.0), ParamSpec("m", choices=("x", "y"))))
    u = np.array([0.5, 0.5, 0.0, space.specs[3].unit("x")])
    out = pair_moves(space, u, 0.25, [0, 1, 2, 3])
    ab = sorted((float(p[0]), float(p[1])) for i, j, p in out if (i, j) == (0, 1))
    assert ab == [(0.25, 0.25), (0.25, 0.75), (0.75, 0.25), (0.75, 0.75)]
    # c sits at its bound: only its inward move pairs; the named field never pairs
    assert sorted((i, j) for i, j, _p in out) == [(0, 1)] * 4 + [(0, 2)] * 2 + [(1, 2)] * 2
    assert all(p[2] == pytest.approx(0.25) for i, j, p in out if j == 2)
    # the fields not in the pair stay at the winner's values
    assert all(np.allclose(np.delete(p, [i, j]), np.delete(u, [i, j])) for i, j, p in out)
    assert pair_moves(space, u, 0.25, [0]) == []


def test_a_value_is_excluded_only_when_every_point_that_put_the_field_there_was_worse() -> None:
    spec = ParamSpec("x", 0.0, 1.0)
    slice_ = [FieldMove(0.25, 0.0, 0.02), FieldMove(0.75, 0.0, 0.03)]
    assert allowed_values(spec, 0.5, slice_, 0.01) == (0.25, 0.75)
    # a second field's move makes up for the move up: that side is no longer bounded
    made_up = [*slice_, FieldMove(0.75, 0.0, 0.004, "y", 0.2),
               FieldMove(0.75, 0.0, 0.05, "y", 0.8)]
    assert allowed_values(spec, 0.5, made_up, 0.01) == (0.25, 1.0)
    assert open_sides(spec, 0.5, made_up, 0.01) == (False, True)
    # pairs that are worse too change nothing
    worse = [*slice_, FieldMove(0.25, 0.0, 0.5, "y", 0.2), FieldMove(0.75, 0.0, 0.02, "y", 0.8)]
    assert allowed_values(spec, 0.5, worse, 0.01) == (0.25, 0.75)


def test_a_confirmed_candidate_as_good_as_the_winner_past_a_move_frees_that_side() -> None:
    """A move worse beyond the band excludes the values past it on the assumption that the
    score keeps worsening out there; another confirmed candidate on the same seed within the
    band past it shows it does not, and the side is left open. One between the winner and
    the move, or one beyond the band, changes nothing."""
    spec = ParamSpec("x", 0.0, 1.0)
    slice_ = [FieldMove(0.25, 0.0, 0.02), FieldMove(0.75, 0.0, 0.03)]

    def seen(x: float, change: float) -> FieldMove:
        return FieldMove(x, 0.0, change, confirmed=True)

    assert allowed_values(spec, 0.5, slice_, 0.01) == (0.25, 0.75)
    out_there = [*slice_, seen(0.1, 0.004)]
    assert allowed_values(spec, 0.5, out_there, 0.01) == (0.0, 0.75)
    assert open_sides(spec, 0.5, out_there, 0.01) == (True, False)
    for other in (seen(0.4, 0.0), seen(0.1, 0.02), seen(0.9, 0.05)):
        assert allowed_values(spec, 0.5, [*slice_, other], 0.01) == (0.25, 0.75)
        assert open_sides(spec, 0.5, [*slice_, other], 0.01) == (False, False)
    # a confirmed point is not a move: it neither tells the field nor joins the slice
    f = FieldProfile("x", 0.5, tuple(out_there), True)
    assert f.alone == tuple(slice_) and f.excluded_alone(0.01) == {0.25, 0.75}
    # a named field: an excluded choice a confirmed candidate as good takes is allowed
    named = ParamSpec("m", choices=("a", "b", "c"))
    moves_ = [FieldMove("b", 0.0, 0.05), FieldMove("c", 0.0, 0.05)]
    assert allowed_values(named, "a", moves_, 0.01) == ("a",)
    assert allowed_values(named, "a", [*moves_, FieldMove("c", 0.0, 0.0, confirmed=True)],
                          0.01) == ("a", "c")
    # report.json keeps the flag
    prof = Profile(step=0.25, seed=1, transitions=10, distance=0.1, score=0.1,
                   sigma=0.01 / told_band(2),
                   fields=(FieldProfile("x", 0.5, tuple(out_there), True, (0.0, 0.75),
                                        (True, False)),), dof=2)
    assert Profile.from_json(json.loads(json.dumps(prof.to_json()))) == prof
    # one walk of the winner: no spread, no band; report.json stays strict JSON
    alone = Profile(step=0.25, seed=1, transitions=10, distance=0.1, score=0.1,
                    sigma=math.nan, fields=(), dof=0)
    doc = json.loads(json.dumps(alone.to_json(), allow_nan=False))
    assert doc["band"] is None and doc["sigma"] is None and math.isnan(alone.limit)
    from types import SimpleNamespace
    text = profile_section(SimpleNamespace(profile=prof, space=ParameterSpace((spec,))))
    assert "Freed by a confirmed candidate" in text
    assert "x below 0.25 (a confirmed candidate at 0.1: +0.0040)" in text


def test_pairs_free_two_fields_that_trade_off_exactly(lattice9) -> None:
    """The kinematic walker drives ``slow_speed * drive_time`` metres a move: with both on
    log ranges of the same ratio, a step up of one and down of the other is the same walk, so
    the table cannot tell them apart, only their product. The slice, moving one at a time,
    excludes both sides of both; the pairs find the diagonal that keeps the product."""
    hidden = KinematicParams(drive_time=1.0, slow_speed=0.1)
    real = real_table(hidden_walk(lattice9, hidden, CCW8, 3.0, 11, "kinematic"), CCW8)
    space = ParameterSpace((ParamSpec("drive_time", 0.25, 4.0, "log"),
                            ParamSpec("slow_speed", 0.025, 0.4, "log")))
    runs = {}
    for pairs in (False, True):
        cfg = CalibrationConfig(hours_per_candidate=3.0, candidates=6, workers=1, seed=2,
                                simulator="kinematic", n_boot=20, progress=False,
                                transfer_seeds=3, profile_step=0.25, profile_pairs=pairs)
        runs[pairs] = calibrate(real, "table", lattice9, space=space, config=cfg).profile
    alone, both = runs[False], runs[True]
    assert both.pairs and not alone.pairs
    limit = both.limit
    for f, g in zip(alone.fields, both.fields, strict=True):
        # the slice's walks are the same walks with or without the pairs
        assert [m for m in g.moves if m.partner is None] == list(f.moves)
        assert f.told is True and f.open == (False, False)   # bounded on both sides alone
        pairs = [m for m in g.moves if m.partner is not None]
        assert {m.partner for m in pairs} == {h.name for h in both.fields} - {f.name}
        # one point per move of the field times move of its partner (both ways, both)
        assert len(pairs) == len(alone.fields[0].alone) * len(alone.fields[1].alone)
    dt, sp = both.fields
    # the point with the drive time down and the speed up keeps the product: the same walk
    down = next(m for m in dt.moves if m.partner is not None and m.value < dt.value
                and m.partner_value > sp.value)
    assert down.value * down.partner_value == pytest.approx(dt.value * sp.value)
    assert abs(down.score_change) <= limit
    # so neither field is bounded on that side any more: the data tell only the product
    assert dt.open[0] and sp.open[1]
    assert dt.admits(space.specs[0].low) and sp.admits(space.specs[1].high)
    assert not alone.fields[0].admits(space.specs[0].low)
    # the report names the point that freed it
    from types import SimpleNamespace
    text = profile_section(SimpleNamespace(profile=both, space=space))
    # the table ties the two: each alone is told, together they trade off
    assert both.ties() == [("drive_time", "slow_speed")] and alone.ties() == []
    assert "Tied by the data: drive_time with slow_speed" in text
    assert "freed by a pair" in text and f"with slow_speed {_value_text(down.partner_value)}" in text
    doc = json.loads(json.dumps(both.to_json()))
    assert doc["pairs"] is True and doc["ties"] == [["drive_time", "slow_speed"]]
    assert Profile.from_json(doc) == both        # report.json gives the profile back
    assert {"field": "slow_speed", "value": down.partner_value} in [
        m["with"] for m in doc["fields"][0]["moves"]]


def _value_text(x: float) -> str:
    from simlab.calibration.report import _value

    return _value(x)


def test_pairs_need_the_profile() -> None:
    with pytest.raises(ConfigError, match="profile_pairs"):
        CalibrationConfig(profile_pairs=True)
    assert CalibrationConfig(profile_step=0.25, profile_pairs=True).profile_pairs


def test_more_points_at_a_value_never_exclude_the_robots_value_more_often() -> None:
    """The exclusion is a test of "this value is as good as the winner's": with the best point
    at a value truly no worse than the winner (the others worse by any amount), the value is
    excluded only when that point's own noise passes the band, at most 2.5 % (one side of
    1.96 sd of a difference of two walks), however many points sit there. More points only
    make a truly worse value likelier to be freed by a dip of one of them: the allowed
    values widen (the test loses power), they never lose the robot's value more often."""
    rng = np.random.default_rng(7)
    n = 20_000
    limit = told_band(None) * 1.0  # sigma 1, known: a difference of two walks has sd sqrt(2)
    spec = ParamSpec("x", 0.0, 1.0)

    def excluded(truth: list[float]) -> float:
        """How often 0.75 is excluded, its points' true changes ``truth``."""
        changes = np.asarray(truth) + rng.normal(0.0, math.sqrt(2.0), (n, len(truth)))
        out = 0
        for row in changes:
            mine = [FieldMove(0.75, 0.0, float(c), None if i == 0 else "y", 0.1 * i)
                    for i, c in enumerate(row)]
            out += allowed_values(spec, 0.5, mine, limit) == (0.0, 0.75)
        return out / n

    slack = 4.0 * math.sqrt(0.025 * 0.975 / n)
    one = excluded([0.0])
    assert one == pytest.approx(0.025, abs=slack)
    # the robot's value at the first point, its partners' points worse by three bands
    assert excluded([0.0] + [3.0 * limit] * 8) <= one + slack
    # partners as good: excluded only when every one of them passes the band
    assert excluded([0.0] * 3) < 0.001
    # a value worse by two bands: freed more often as more points sit there
    assert 1.0 - excluded([2.0 * limit]) == pytest.approx(0.025, abs=slack)
    assert 1.0 - excluded([2.0 * limit] * 9) > 0.1
