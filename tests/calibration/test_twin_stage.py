"""Reset rows recognised and kept out, the signature by region, and the transfer stage read
against the perfect-twin line (hand-built tables on the 3 x 3 lattice)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simlab.base.actions import parse_action_set
from simlab.base.errors import ConfigError
from simlab.calibration.config import CalibrationConfig, RealTable
from simlab.calibration.policies import (
    data_need,
    policy_need,
    real_transfer_counts,
    transfer_stage,
)
from simlab.calibration.regions import REGIONS, pair_regions, region_signature
from simlab.calibration.resets import (
    detect_reset_states,
    reset_warning,
    resolve_reset_states,
    without_rows,
)
from simlab.physics.arena import load_arena
from tests.calibration.test_transfer import lattice, lattice_counts

CCW8 = parse_action_set(8, "ccw-east")


def _with_reset(counts: np.ndarray, state: int, to: tuple[int, ...]) -> np.ndarray:
    """``counts`` whose rows of ``state`` are the episode reset: every action to ``to``."""
    out = counts.copy()
    out[state] = 0
    for k, t in enumerate(to):
        out[state, :, t] = 5 + k
    return out


def test_a_reset_row_is_recognised_by_its_jumps_and_nothing_else_is() -> None:
    centres = lattice().centres  # 0.5 m apart: a reset jumps more than 2.5 cells
    moves = lattice_counts(CCW8)
    assert detect_reset_states(moves, centres) == ()
    # 8 (bottom right) jumps to 0 (top left, 1.41 m = 2.8 cells): a reset
    reset = _with_reset(moves, 8, (0,))
    assert detect_reset_states(reset, centres) == (8,)
    # to 2 (1.0 m = 2 cells): could be a long move, not a reset
    assert detect_reset_states(_with_reset(moves, 8, (2,)), centres) == ()
    # a reset state that also stays is not a reset
    staying = _with_reset(moves, 8, (0,))
    staying[8, 0, 8] = 1
    assert detect_reset_states(staying, centres) == ()
    assert detect_reset_states(reset, None) == ()
    assert resolve_reset_states("none", reset, centres) == ()
    assert resolve_reset_states("auto", reset, centres) == (8,)
    assert resolve_reset_states("4,2", reset, centres) == (2, 4)
    with pytest.raises(ConfigError, match="state 9 is not one of the 9 states"):
        resolve_reset_states("9", reset, centres)
    line = reset_warning((8,), reset, centres, "the distance")
    assert "state 8's 40 transitions jump 1.4-1.4 m away (to 0)" in line
    assert "an episode reset" in line and "--reset-states none" in line
    # a state named by hand whose rows are ordinary moves is left out as asked, not
    # called a reset (the centre state stays or moves to a neighbour, 0.0-0.7 m away)
    moved = reset_warning((4,), reset, centres, "the distance")
    assert "episode reset" not in moved
    assert "state 4's 80 transitions end 0.0-0.7 m away" in moved
    assert "look like moves" in moved and "left out of the distance as asked" in moved
    both = reset_warning((4, 8), reset, centres, "the distance")
    assert "state 8's 40 transitions jump" in both and "state 4's" in both
    left = without_rows(reset, (8,))
    assert left[8].sum() == 0 and (left[:8] == reset[:8]).all()


def test_the_transfer_stage_gives_a_reset_state_the_twins_rows_and_drops_unreached_goals(
        ) -> None:
    moves = lattice_counts(CCW8)
    reset = without_rows(_with_reset(moves, 8, (0,)), (8,))
    real = RealTable(reset, CCW8, reset_states=(8,), reset_counts=40)
    twins = [moves, moves * 2]
    counts = real_transfer_counts(real, twins)
    np.testing.assert_array_equal(counts[8], 3 * moves[8])
    np.testing.assert_array_equal(counts[:8], reset[:8])
    # state 4 never entered by the real robot: left out of the goals, said why
    never4 = moves.copy()
    into = never4[:, :, 4].copy()
    never4[:, :, 4] = 0
    never4[np.arange(9), :, np.arange(9)] += into
    never4[4] = moves[4]
    out = transfer_stage(RealTable(never4, CCW8), twins, ["a", "b"], [4, 8], lattice().centres,
                         np.random.default_rng(0))
    assert out is not None and out.left_out == [4]
    assert [g.name for g in out.report.goals] == ["s8"]
    assert any("goal state(s) [4] left out" in w for w in out.warnings)


def test_a_twin_equal_to_the_real_robot_sits_on_the_perfect_twin_line() -> None:
    rng = np.random.default_rng(5)
    truth = lattice_counts(CCW8, n=1000, success=0.6) / 1000.0
    real = RealTable(rng.multinomial(12, truth), CCW8)
    twins = [rng.multinomial(24, truth) for _ in range(3)]
    out = transfer_stage(real, twins, ["a", "b", "c"], list(range(9)), lattice().centres,
                         np.random.default_rng(1))
    assert out is not None and not out.warnings
    assert [r["walks"] for r in out.curve] == [1, 2, 3]
    mean = float(np.mean(out.report.overall_ratios()))
    # the twins are the truth sampled: their score is the perfect twin's, within the spread
    # of its resamples that arrive (on a few, a pair of 12 real moves drawn all stays traps
    # even a perfect twin's plan)
    arrive = out.line.overall[np.isfinite(out.line.overall)]
    assert arrive.size >= 0.8 * out.line.overall.size
    lo, hi = np.quantile(arrive, [0.025, 0.975])
    assert lo - 0.02 <= mean <= hi + 0.02
    assert out.line.transitions == twins[0].sum()


def test_twins_trapped_by_pairs_the_real_robot_only_stayed_in_are_warned() -> None:
    moves = lattice_counts(CCW8)
    real = moves.copy()
    # from 0 the real robot's moves to the east and south-east only ever stayed
    for a in (0, 7):
        real[0, a] = 0
        real[0, a, 0] = 3
    twins = [lattice_counts(CCW8, success=1.0)]
    out = transfer_stage(RealTable(real, CCW8), twins, ["t"], [8], lattice().centres,
                         np.random.default_rng(0))
    assert out is not None
    assert not math.isfinite(out.report.overall_ratios()[0])
    text = " ".join(out.warnings)
    assert "1 of 1 twin seeds never arrive" in text and "only stayed in" in text
    assert "seen 3-3 times each" in text and "--untried mask" in text
    # planned among the pairs the robot moved in, the twin goes round by the south and
    # arrives: the warning gives that figure, the one `--untried mask` would report
    masked = transfer_stage(RealTable(real, CCW8), twins, ["t"], [8], lattice().centres,
                            np.random.default_rng(0), untried="mask")
    assert out.masked is not None and masked.masked is None
    assert math.isfinite(out.masked[0])
    assert out.masked == pytest.approx(list(masked.report.overall_ratios()))
    assert f"so planned, the twin seeds take {out.masked[0]:.3f} x" in text
    # twins that all arrive need no masked figure
    fine = transfer_stage(RealTable(moves, CCW8), twins, ["t"], [8], lattice().centres,
                          np.random.default_rng(0))
    assert fine.masked is None


def test_data_need_fits_the_finite_rows() -> None:
    curve = [{"transitions": 4000, "mean_ratio": math.inf},
             {"transitions": 8000, "mean_ratio": 1.05 + 500 / 8000},
             {"transitions": 16000, "mean_ratio": 1.05 + 500 / 16000}]
    need = data_need(curve)
    assert need is not None and need["limit"] == pytest.approx(1.05)


def test_regions_and_their_signature_on_the_table() -> None:
    """The table is 1.5 m square (walls at +-0.75 m); 3 x 3 lattice 0.5 m apart, cells of
    0.5 m: from a border state the headings towards the near wall (0.25 m) are ``wall``,
    from the centre every heading is open."""
    disc = lattice()
    heads = CCW8.headings()
    regions = pair_regions(load_arena("table"), disc.centres, heads, 0.5)
    wall, open_ = REGIONS.index("wall"), REGIONS.index("open")
    assert (regions[4] == open_).all()
    assert regions[5, 0] == wall and regions[3, 4] == wall  # east of 5, west of 3
    assert regions[5, 4] != wall  # from 5 westwards: 1.0 m of floor
    counts = lattice_counts(CCW8, success=0.8)
    rows = {r["region"]: r for r in region_signature(counts, regions, disc.centres, heads)}
    # straight into a wall the lattice robot's move is clamped to its own cell (it stays);
    # a diagonal one slides along the wall to the next cell
    straight = [(5, 0), (3, 4), (1, 2), (7, 6)]
    assert all(counts[s, a, s] == 10 for s, a in straight)
    assert rows["wall"]["stay"] > 0.5 > rows["open"]["stay"] == pytest.approx(0.2)
    assert rows["open"]["ahead"] == pytest.approx(0.8)
    total = sum(r["transitions"] for r in rows.values())
    assert total == counts.sum()


def test_reset_states_option_reaches_the_config() -> None:
    assert CalibrationConfig(reset_states="none").reset_states == "none"
    with pytest.raises(ConfigError, match="confirm_hours"):
        CalibrationConfig(confirm_hours=1e9)



def test_a_flat_curve_recommends_its_largest_pool_and_says_the_twin_is_the_limit() -> None:
    curve = [{"transitions": 8000, "mean_ratio": 1.184},
             {"transitions": 16000, "mean_ratio": 1.192},
             {"transitions": 24000, "mean_ratio": 1.184}]
    assert data_need(curve) is None  # no 1/N law to extrapolate
    need = policy_need(curve)
    assert need is not None and need["flat"] and need["transitions"] == 24000
    assert need["limit"] == 1.184 and need["c"] == 0.0
    falling = [{"transitions": n, "mean_ratio": 1.05 + 500 / n} for n in (8000, 16000)]
    assert policy_need(falling)["flat"] is False
    assert policy_need(curve[:1]) is None


def test_a_nearly_flat_curve_recommends_no_fewer_transitions_than_it_measured() -> None:
    """A slope of 13 fitted at 8,000-24,000 transitions would ask 1,300 (13 / 0.01), below
    every size measured: the recommendation is the smallest size, where the fit's excess
    over its limit is already within the tolerance; a steep curve keeps the fit's figure."""
    nearly_flat = [{"transitions": n, "mean_ratio": 1.12 + 13 / n + e}
                   for n, e in ((8000, 0.0004), (16000, -0.0003), (24000, 0.0001))]
    fit = data_need(nearly_flat)
    assert fit is not None and fit["transitions"] < 8000
    need = policy_need(nearly_flat)
    assert need["below_measured"] and not need["flat"]
    assert need["transitions"] == 8000 and need["fit_transitions"] == fit["transitions"]
    assert need["c"] / need["transitions"] <= need["tolerance"]
    steep = [{"transitions": n, "mean_ratio": 1.05 + 500 / n} for n in (8000, 16000, 24000)]
    kept = policy_need(steep)
    assert not kept["below_measured"]
    assert kept["transitions"] == pytest.approx(50_000) == kept["fit_transitions"]


def test_an_ensemble_is_scored_against_as_many_of_the_winner_s_walks() -> None:
    """Members that move as the robot does against winner walks that always stay: planned on
    the stays, the policy never arrives; on the members, it does. One member is no
    ensemble."""
    from simlab.calibration.policies import ensemble_transfer

    real = lattice_counts(CCW8, n=20)
    out = transfer_stage(RealTable(real, CCW8), [real], ["t"], [8], lattice().centres,
                         np.random.default_rng(0))
    stays = np.zeros_like(real)
    stays[np.arange(9), :, np.arange(9)] = 20
    good = [lattice_counts(CCW8, n=20, success=p) for p in (0.7, 0.8, 0.9)]
    res = ensemble_transfer(out, good, [stays, stays, stays], CCW8, lattice().centres)
    assert res is not None and res["members"] == 3
    assert res["transitions"] == sum(int(g.sum()) for g in good)
    assert math.isfinite(res["ensemble_ratio"]) and math.isinf(res["winner_ratio"])
    assert res["better"]
    flipped = ensemble_transfer(out, [stays, stays], good, CCW8, lattice().centres)
    assert flipped is not None and not flipped["better"] and flipped["members"] == 2
    assert ensemble_transfer(out, good[:1], good, CCW8, lattice().centres) is None


def test_policy_data_without_a_transfer_report_is_refused() -> None:
    """--policy-data is sized from the transfer report: without it nothing would be
    collected, silently."""
    with pytest.raises(ConfigError, match="--no-confirm leaves out"):
        CalibrationConfig(policy_data=True, confirm=False)
    with pytest.raises(ConfigError, match="--transfer-seeds 0 leaves out"):
        CalibrationConfig(policy_data=True, transfer_seeds=0)
    with pytest.raises(ConfigError, match=r"calibration\.untried"):
        CalibrationConfig(untried="skip")
    assert CalibrationConfig(policy_data=True).policy_data


def test_the_headline_says_what_the_seeds_that_arrive_take() -> None:
    """One twin seed of three never arrives: the headline still gives the other two's
    figure and how to plan among the pairs the robot tried."""
    from types import SimpleNamespace

    from simlab.calibration.policies import TwinTransfer
    from simlab.calibration.report import transfer_headline

    report = SimpleNamespace(overall_ratios=lambda: np.array([1.10, math.inf, 1.20]))
    twin = TwinTransfer(report=report, real_model=None,
                        line=SimpleNamespace(median=1.05))
    sim = SimpleNamespace(counts=np.full((2, 1, 2), 500, dtype=np.int64))
    result = SimpleNamespace(twin_transfer=twin, twins=[SimpleNamespace(sim=sim)] * 3)
    line = transfer_headline(result)
    assert "2 of 3 seeds take 1.150 x the real optimum's steps, 1 never arrive" in line
    assert "--untried mask" in line and "a perfect twin at the same data 1.050" in line
    twin.untried = "mask"
    assert "--untried mask" not in transfer_headline(result)
    report.overall_ratios = lambda: np.array([math.inf, math.inf])
    assert "never arrive for any of 2 seeds" in transfer_headline(result)
