"""Issue 17 part 2: the stationary distribution by one ``solve`` equals the least-squares
answer within float rounding and is a stationary distribution."""

from __future__ import annotations

import numpy as np
import pytest

from simlab.replay.prediction import _stationary


def _lstsq(P: np.ndarray) -> np.ndarray:
    n = P.shape[0]
    M = np.vstack([P.T - np.eye(n), np.ones((1, n))])
    b = np.zeros(n + 1)
    b[-1] = 1.0
    pi = np.clip(np.linalg.lstsq(M, b, rcond=None)[0], 0.0, None)
    return pi / pi.sum()


@pytest.mark.parametrize("n", [1, 2, 7, 60])
def test_stationary_matches_lstsq_and_balances(n: int) -> None:
    rng = np.random.default_rng(n)
    A = rng.random((n, n)) * (rng.random((n, n)) < 0.3) + 0.1 * np.roll(np.eye(n), 1, axis=1)
    P = A / A.sum(axis=1, keepdims=True)  # irreducible: the cycle i -> i+1 is always there
    pi = _stationary(P)
    assert pi.shape == (n,)
    assert pi.sum() == pytest.approx(1.0, abs=1e-14)
    assert np.all(pi >= 0.0)
    np.testing.assert_allclose(pi @ P, pi, atol=1e-13)
    np.testing.assert_allclose(pi, _lstsq(P), atol=1e-13)


def test_stationary_two_state_analytic() -> None:
    a, b = 0.3, 0.1
    P = np.array([[1 - a, a], [b, 1 - b]])
    np.testing.assert_allclose(_stationary(P), [b / (a + b), a / (a + b)], atol=1e-15)
