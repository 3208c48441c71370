"""The twin's order of the arms is judged only where the real model's runs can tell."""

from __future__ import annotations

import numpy as np

from simlab.online.twin import (
    _outcomes,
    _totals,
    order_disagreements,
    outcome_order,
    outcome_split_differs,
)


def _runs(totals: list[float], at: int = 0) -> list[dict[str, np.ndarray]]:
    """Runs whose rewards before ``at`` are a constant 5 and after it sum to ``totals``."""
    return [{"reward": np.r_[np.full(at, 5.0), t / 4 * np.ones(4)]} for t in totals]


def test_a_pair_the_real_runs_separate_must_keep_its_order() -> None:
    real = {"mb": np.array([100.0, 102, 98, 101, 99]), "mf": np.array([60.0, 62, 58, 61, 59])}
    assert order_disagreements(real, {"mb": np.array([90.0]), "mf": np.array([70.0])}) == (1, [])
    assert order_disagreements(real, {"mb": np.array([70.0]), "mf": np.array([90.0])}) == (
        1, [("mb", "mf")])
    # A tie in the twin does not reproduce a separated order either.
    assert order_disagreements(real, {"mb": np.array([80.0]), "mf": np.array([80.0])})[1] == [
        ("mb", "mf")]


def test_a_pair_within_the_real_runs_noise_is_not_judged() -> None:
    # Means 100 and 95 with a spread of about 30: Welch's p is far above 0.05.
    real = {"mb": np.array([130.0, 70, 100, 140, 60]), "mf": np.array([125.0, 65, 95, 135, 55])}
    assert order_disagreements(real, {"mb": np.array([0.0]), "mf": np.array([50.0])}) == (0, [])


def test_three_arms_count_each_separated_pair_once() -> None:
    real = {"a": np.array([10.0, 11, 9]), "b": np.array([20.0, 21, 19]),
            "c": np.array([20.5, 19.5, 20])}
    # a < b and a < c are separated, b ~ c is not: the twin's b/c order does not matter.
    twin = {"a": np.array([1.0]), "b": np.array([9.0]), "c": np.array([5.0])}
    assert order_disagreements(real, twin) == (2, [])
    twin = {"a": np.array([6.0]), "b": np.array([9.0]), "c": np.array([5.0])}
    assert order_disagreements(real, twin) == (2, [("a", "c")])


def test_totals_count_the_rewards_after_the_change() -> None:
    logs = {"mb": _runs([40.0, 44.0], at=3)}
    np.testing.assert_allclose(_totals(logs, 3)["mb"], [40.0, 44.0])
    np.testing.assert_allclose(_totals(logs, None)["mb"], [55.0, 59.0])


def test_the_order_is_judged_within_each_outcome_of_the_change() -> None:
    """Two outcomes (1: a hard change, 2: an easy one). On the real model MB beats MF in
    outcome 1; in the twin too, but the twin drew outcome 2 for most MF runs, so MF's pooled
    mean passes MB's: pooled the pair is judged wrong, within the outcomes it is right."""
    real = {"mb": np.array([100.0, 102, 98, 101, 99, 100, 97, 103]),
            "mf": np.array([40.0, 42, 38, 41, 39, 40, 120, 118])}
    real_k = {"mb": np.ones(8, int), "mf": np.r_[np.ones(6, int), 2, 2]}
    twin = {"mb": np.array([90.0, 92, 88, 91, 89, 90, 87, 93]),
            "mf": np.array([30.0, 130, 128, 131, 129, 130, 127, 133])}
    twin_k = {"mb": np.ones(8, int), "mf": np.r_[1, np.full(7, 2)]}
    assert order_disagreements(real, twin)[1] == [("mb", "mf")]
    assert outcome_order(real, twin, real_k, twin_k) == (1, [])
    # Within outcome 1 a twin that inverts the pair is caught.
    twin_bad = {"mb": twin["mb"] - 70.0, "mf": twin["mf"]}
    assert outcome_order(real, twin_bad, real_k, twin_k) == (1, [(1, "mb", "mf")])
    # An outcome the twin has no MB run in judges nothing there (outcome 2: MB absent on
    # the real model too).
    assert outcome_order(real, twin, real_k, {"mb": np.full(8, 2), "mf": twin_k["mf"]}) == (
        0, [])


def test_a_split_of_the_outcomes_is_told_apart_only_beyond_chance() -> None:
    """Fisher's exact test: 4 of 10 against 6 of 10 is chance (p = 0.66); 0 of 10 against
    10 of 10 is not (p = 1.1e-5)."""
    def k(n2: int) -> np.ndarray:
        return np.r_[np.ones(10 - n2, int), np.full(n2, 2)]

    assert outcome_split_differs({"mf": k(4)}, {"mf": k(6)}) == []
    assert outcome_split_differs({"mf": k(0), "mb": k(0)}, {"mf": k(10), "mb": k(0)}) == ["mf"]


def test_a_runs_outcome_is_its_phase_at_the_change() -> None:
    logs = {"mf": [{"phase": np.r_[np.zeros(3, int), np.full(4, 2)]},
                   {"phase": np.r_[np.zeros(3, int), np.full(4, 1)]}]}
    np.testing.assert_array_equal(_outcomes(logs, 3)["mf"], [2, 1])
    np.testing.assert_array_equal(_outcomes(logs, None)["mf"], [0, 0])
