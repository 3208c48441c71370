"""Shared helpers for the Visit-the-lab tests."""

from __future__ import annotations

import math

import numpy as np
import pytest

Z_999 = 3.2905  # two-sided 99.9 % normal quantile


def binomial_interval(p: float, n: int, z: float = Z_999) -> tuple[float, float]:
    """Range of observed rates ``k / n`` compatible with a true rate ``p`` (normal
    approximation of the binomial, two-sided, ``z`` standard errors)."""
    half = z * math.sqrt(max(p * (1 - p), 1e-12) / n)
    return p - half, p + half


def assert_rate(k: int, n: int, p: float) -> None:
    """Observed rate ``k / n`` lies in the 99.9 % interval around the true rate ``p``."""
    lo, hi = binomial_interval(p, n)
    rate = k / n
    assert lo <= rate <= hi, f"rate {rate:.4f} outside [{lo:.4f}, {hi:.4f}] for p={p}"


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


@pytest.fixture(name="assert_rate")
def assert_rate_fixture():
    """The :func:`assert_rate` check (99.9 % binomial interval)."""
    return assert_rate
