"""The twin's order of the arms is judged only where the real model's runs can tell."""

from __future__ import annotations

import numpy as np

from simlab.online.twin import _totals, order_disagreements


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
