"""The search's objective: the robot's signature at its own visits, and its penalty."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simlab.calibration.objective import (
    TOLERANCES,
    Reference,
    SignatureGap,
    matched_entropy,
    score,
    signature_gap,
)


def _random_counts(rng: np.random.Generator, S: int = 6, A: int = 4, n: int = 30
                   ) -> np.ndarray:
    T = rng.dirichlet(np.full(S, 0.5), size=(S, A))
    return np.stack([[rng.multinomial(n, T[s, a]) for a in range(A)] for s in range(S)])


def test_a_twin_equal_to_the_robot_has_no_gap_and_no_penalty() -> None:
    real = _random_counts(np.random.default_rng(0))
    gap = signature_gap(real, Reference.build(real), np.random.default_rng(1))
    assert gap.self_share == pytest.approx(gap.self_share_real)
    assert gap.entropy == pytest.approx(gap.entropy_real)   # same rows, no subsampling
    assert math.isnan(gap.regions)                           # no regions given
    assert gap.penalty(1.0) == pytest.approx(0.0, abs=1e-18)


def test_self_share_is_read_at_the_robot_s_visits_not_the_twin_s() -> None:
    """Two pairs: the robot stays in pair A (10 visits of 10), moves in pair B (30 of 30).
    The twin has the same T but visits pair A 100 times and B 10 times: its own walk stays
    in 91 % of its moves, at the robot's visits in 25 %, as the robot does."""
    real = np.zeros((2, 2, 2), dtype=np.int64)
    real[0, 0, 0] = 10     # pair A: stays
    real[0, 1, 1] = 30     # pair B: moves
    sim = np.zeros_like(real)
    sim[0, 0, 0] = 100
    sim[0, 1, 1] = 10
    gap = signature_gap(sim, Reference.build(real), np.random.default_rng(0))
    assert gap.self_share_real == pytest.approx(0.25)
    assert gap.self_share == pytest.approx(0.25)
    assert np.einsum("sas->", sim) / sim.sum() == pytest.approx(100 / 110)


def test_matched_entropy_compares_rows_at_the_same_number_of_draws() -> None:
    """A robot row of 3 draws on 3 states (plug-in 1.585 bits) against a twin spreading over
    8 states with 800 draws (plug-in 3 bits): at 3 draws each, the twin's entropy can be no
    more than log2(3), so the plug-in bias of the small row is not charged to the twin."""
    real = np.zeros((1, 1, 8), dtype=np.int64)
    real[0, 0, :3] = 1
    sim = np.full((1, 1, 8), 100, dtype=np.int64)
    common = np.ones((1, 1), dtype=bool)
    twin, robot = matched_entropy(sim, real, common, np.random.default_rng(0), draws=64)
    assert robot == pytest.approx(math.log2(3))
    assert twin <= math.log2(3) + 1e-12
    # three draws from 8 equal states are all distinct with probability 7/8 * 6/8 = 0.656
    # (a bit more without replacement); two alike give 0.918 bits: expectation ~1.45
    assert twin == pytest.approx(1.45, abs=0.08)


def test_a_twin_that_always_stays_is_charged_for_its_stays_and_its_certainty() -> None:
    real = _random_counts(np.random.default_rng(3))
    S = real.shape[0]
    stays = np.zeros_like(real)
    stays[np.arange(S), :, np.arange(S)] = 50
    gap = signature_gap(stays, Reference.build(real), np.random.default_rng(0))
    assert gap.self_share == pytest.approx(1.0)
    assert gap.entropy == pytest.approx(0.0)
    expected = ((1.0 - gap.self_share_real) / TOLERANCES["self_share"]) ** 2 + \
        (gap.entropy_real / TOLERANCES["entropy"]) ** 2
    assert gap.penalty(0.01) == pytest.approx(0.01 * expected)
    assert gap.within() == {"self_share": False, "entropy": False}


def test_region_outcomes_compare_stay_ahead_side_behind_per_region() -> None:
    """Three states on a line, one action heading east (+x). From state 0 the robot goes
    ahead to 1 every time; a twin that stays half the time differs by TV 0.5 on that
    region; a twin that goes ahead to 2 instead (another state, same class) differs by 0."""
    from simlab.calibration.regions import outcome_classes

    centres = np.array([[0.0, 0.0], [0.4, 0.0], [0.8, 0.0]])
    headings = np.array([0.0])
    classes = outcome_classes(centres, headings)
    assert classes[0, 0, 1] == 1 and classes[0, 0, 0] == 0
    real = np.zeros((3, 1, 3), dtype=np.int64)
    real[0, 0, 1] = 20
    ref = Reference.build(real, np.zeros((3, 1), dtype=np.int64), centres, headings)
    half = np.zeros_like(real)
    half[0, 0, 0], half[0, 0, 1] = 10, 10
    far = np.zeros_like(real)
    far[0, 0, 2] = 20
    rng = np.random.default_rng(0)
    assert signature_gap(half, ref, rng).regions == pytest.approx(0.5)
    assert signature_gap(far, ref, rng).regions == pytest.approx(0.0)


def test_the_signature_objectives_add_the_penalty_to_their_distance() -> None:
    rng = np.random.default_rng(5)
    real = _random_counts(rng)
    sim = _random_counts(rng, n=60)
    ref = Reference.build(real)
    full, gap = score("signature", sim, ref, 0.3, seed=0, unvisited="max", weight=0.02)
    assert full == pytest.approx(0.3 + gap.penalty(0.02)) and gap.penalty(0.02) > 0
    plain, same = score("excess", sim, ref, 0.3, seed=0, unvisited="max")
    over, again = score("signature-excess", sim, ref, 0.3, seed=0, unvisited="max",
                        weight=0.02)
    assert same == gap == again
    assert over == pytest.approx(plain + gap.penalty(0.02))


def test_a_twin_with_no_pair_in_common_has_no_signature() -> None:
    real = np.zeros((2, 1, 2), dtype=np.int64)
    real[0, 0, 1] = 5
    sim = np.zeros_like(real)
    sim[1, 0, 0] = 5
    gap = signature_gap(sim, Reference.build(real), np.random.default_rng(0))
    assert isinstance(gap, SignatureGap) and math.isnan(gap.self_share)
    assert gap.penalty() == 0.0
