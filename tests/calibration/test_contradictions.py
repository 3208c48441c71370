"""Where the twin contradicts the robot: the per-pair test and its false-discovery reading."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from simlab.calibration.contradictions import (
    Contradictions,
    common_pairs,
    contradicted_pairs,
    direction,
    pair_pvalue,
)


def test_a_two_outcome_pair_gets_the_exact_permutation_pvalue() -> None:
    # 4 real moves and 5 twin moves over two next states: C(9, 4) = 126 relabellings, fewer
    # than the resamples, so the test is exact. Under relabelling the real side's count of
    # outcome 0 is hypergeometric; the p-value is the mass of the tables at least as far
    # apart (in TV) as the observed one.
    real, twin = np.array([4, 0]), np.array([1, 4])
    n1, n2, k_total = 4, 5, 5
    obs = abs(4 / n1 - 1 / n2)
    ks = np.arange(0, n1 + 1)
    far = [k for k in ks if abs(k / n1 - (k_total - k) / n2) >= obs - 1e-12]
    exact = stats.hypergeom(n1 + n2, k_total, n1).pmf(far).sum()
    assert pair_pvalue(real, twin, np.random.default_rng(0)) == pytest.approx(exact, rel=1e-9)


def test_one_next_state_on_both_sides_is_never_a_contradiction() -> None:
    assert pair_pvalue([0, 7, 0], [0, 30, 0], np.random.default_rng(0)) == 1.0


def _table(rng: np.random.Generator, probs: np.ndarray, n: int) -> np.ndarray:
    """(S, A, S) counts with ``n`` draws per pair from ``probs``."""
    S, A, _ = probs.shape
    return np.stack([[rng.multinomial(n, probs[s, a]) for a in range(A)] for s in range(S)])


def _probs(rng: np.random.Generator, S: int = 4, A: int = 2) -> np.ndarray:
    p = rng.dirichlet(np.full(S, 0.7), size=(S, A))
    return p


def test_a_twin_equal_to_the_robot_in_shares_lists_nothing() -> None:
    rng = np.random.default_rng(3)
    real = _table(rng, _probs(rng), 12)
    c = contradicted_pairs(real, 3 * real, np.random.default_rng(1), resamples=199)
    assert c.tested == real.shape[0] * real.shape[1]
    assert c.pairs == [] and c.raw == 0          # TV 0: no relabelling is further apart
    assert c.visit_share == 0.0 and c.distance_share == 0.0
    assert "none of 8 real (s, a) pairs" in c.summary()


def test_a_pair_the_twin_gets_wrong_is_listed_and_the_false_listings_stay_rare() -> None:
    # The twin walks the robot's own moves (three times the data) except at one pair, where
    # it stays in place 90 % of the time where the robot moves. Benjamini-Hochberg bounds the
    # expected share of false listings by alpha: over 60 lab replicates the wrong pair is
    # found nearly every time, and the mean share of listed pairs that are false stays near
    # or under 5 % (its standard error over 60 replicates is about 0.03).
    S, A, bad = 4, 2, (2, 1)
    found, fdp = 0, []
    for k in range(60):
        rng = np.random.default_rng(100 + k)
        p = _probs(rng, S, A)
        q = p.copy()
        q[bad] = 0.1 / (S - 1)
        q[bad][bad[0]] = 0.9
        p[bad] = np.full(S, 1.0 / S)
        p[bad][bad[0]] = 0.0
        p[bad] /= p[bad].sum()
        real, twin = _table(rng, p, 30), _table(rng, q, 90)
        c = contradicted_pairs(real, twin, rng, resamples=199)
        listed = {(r["state"], r["action"]) for r in c.pairs}
        found += bad in listed
        fdp.append(len(listed - {bad}) / max(len(listed), 1))
    assert found >= 57
    assert np.mean(fdp) <= 0.05 + 2 * 0.03


def test_the_listed_pairs_carry_what_the_test_says_of_them() -> None:
    rng = np.random.default_rng(7)
    S, A = 5, 3
    p = _probs(rng, S, A)
    q = p.copy()
    q[1, 0] = np.eye(S)[1]          # the twin always stays where the robot moves
    p[1, 0] = np.eye(S)[4]
    q[3, 2] = np.eye(S)[0]          # the twin always moves to 0 where the robot stays
    p[3, 2] = np.eye(S)[3]
    real, twin = _table(rng, p, 25), _table(rng, q, 75)
    real[4] = 0                     # a state the robot never left from: nothing to test
    real[0, 1] = 0
    real[0, 1, 2] = 1               # one real move: too few to test
    twin[2, 2] = 0                  # a pair the twin never tried
    regions = np.zeros((S, A), dtype=np.int64)
    regions[1, 0] = 2
    c = contradicted_pairs(real, twin, np.random.default_rng(0), resamples=499,
                           skip_states=[3], regions=regions)
    listed = {(r["state"], r["action"]): r for r in c.pairs}
    assert (1, 0) in listed and (3, 2) not in listed          # state 3 is skipped
    r = listed[(1, 0)]
    assert r["stay_real"] == 0.0 and r["stay_twin"] == 1.0 and direction(r) == "stays more"
    assert r["next_real"] == 4 and r["share_real"] == 1.0 and r["next_twin"] == 1
    assert r["tv"] == 1.0 and r["region"] == "wall" and r["real"] == 25 and r["twin"] == 75
    assert all(row["p"] <= row["q"] < c.alpha for row in c.pairs)
    assert [row["q"] for row in c.pairs] == sorted(row["q"] for row in c.pairs)
    # 15 pairs: state 3's 3 skipped, state 4's 3 never tried by the robot, (0, 1) with one
    # move and (2, 2) the twin never tried are real pairs left untested
    assert c.tested == 15 - 3 - 3 - 2 and c.untested == 2 and c.twin_untried == 1
    w = real.sum(axis=2)
    assert c.visit_share == pytest.approx(
        sum(w[k] for k in listed) / sum(w[s, a] for s in (0, 1, 2) for a in range(A)
                                        if (s, a) not in ((0, 1), (2, 2))))
    back = Contradictions.from_json(c.to_json())
    assert back == c and back.expected == pytest.approx(c.alpha * c.tested)


def test_the_same_seed_gives_the_same_listing() -> None:
    rng = np.random.default_rng(11)
    p = _probs(rng, 4, 2)
    real, twin = _table(rng, p, 10), _table(rng, _probs(rng, 4, 2), 30)
    a = contradicted_pairs(real, twin, np.random.default_rng(5), resamples=199)
    b = contradicted_pairs(real, twin, np.random.default_rng(5), resamples=199)
    assert a == b and a.tested == 8


def test_bad_arguments_are_refused() -> None:
    real = np.ones((2, 1, 2), dtype=np.int64)
    with pytest.raises(ValueError, match="differ in shape"):
        contradicted_pairs(real, np.ones((2, 2, 2)), np.random.default_rng(0))
    with pytest.raises(ValueError, match="alpha"):
        contradicted_pairs(real, real, np.random.default_rng(0), alpha=1.5)


def test_common_pairs_are_those_every_run_lists() -> None:
    def run(*pairs: tuple[int, int]) -> Contradictions:
        return Contradictions(alpha=0.05, tested=10, untested=0, twin_untried=0, raw=0,
                              pairs=[{"state": s, "action": a} for s, a in pairs])

    assert common_pairs([run((1, 0), (2, 3), (4, 1)), run((2, 3), (1, 0)), run((1, 0), (2, 3),
                                                                              (5, 5))]) == [
        (1, 0), (2, 3)]
    assert common_pairs([run((1, 0)), run()]) == [] and common_pairs([]) == []


@pytest.mark.parametrize(("real", "twin", "expected"), [
    (0.1, 0.5, "stays more"), (0.6, 0.2, "stays less"), (0.3, 0.35, "moves elsewhere"),
    (math.nan, 0.2, "moves elsewhere")])
def test_direction_names_how_the_twin_differs(real, twin, expected) -> None:
    assert direction({"stay_real": real, "stay_twin": twin}) == expected
