"""The odometry motion model: exact without noise, variances as specified with noise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.localization.motion import (
    OdometryMotionParams,
    compose,
    odometry_delta,
    relative,
    sample_odometry_motion,
    wrap,
)

NO_NOISE = OdometryMotionParams(0.0, 0.0, 0.0, 0.0)


def test_compose_and_relative_are_inverse() -> None:
    rng = np.random.default_rng(1)
    a = np.column_stack([rng.normal(size=(50, 2)), rng.uniform(-4, 4, 50)])
    b = np.column_stack([rng.normal(size=(50, 2)), rng.uniform(-4, 4, 50)])
    back = compose(a, relative(a, b))
    np.testing.assert_allclose(back[:, :2], b[:, :2], atol=1e-12)
    np.testing.assert_allclose(wrap(back[:, 2] - b[:, 2]), 0.0, atol=1e-12)


def test_noise_free_motion_applies_the_odometry_increment_in_each_particle_frame() -> None:
    rng = np.random.default_rng(2)
    prev, now = np.array([0.3, -0.2, 0.4]), np.array([0.45, -0.05, 1.3])
    particles = np.column_stack([rng.normal(size=(20, 2)), rng.uniform(-3, 3, 20)])
    moved = sample_odometry_motion(particles, prev, now, NO_NOISE, rng)
    expected = compose(particles, relative(prev, now))
    np.testing.assert_allclose(moved[:, :2], expected[:, :2], atol=1e-12)
    np.testing.assert_allclose(wrap(moved[:, 2] - expected[:, 2]), 0.0, atol=1e-12)
    # The particle sitting at the previous odometry pose lands on the new one.
    np.testing.assert_allclose(sample_odometry_motion(prev[None], prev, now, NO_NOISE, rng)[0],
                               now, atol=1e-12)


def test_in_place_turn_has_no_first_rotation() -> None:
    rot1, trans, rot2 = odometry_delta(np.zeros(3), np.array([0.004, 0.003, 1.0]))
    assert rot1 == 0.0 and trans == pytest.approx(0.005) and rot2 == pytest.approx(1.0)


def test_noise_variances_follow_the_model() -> None:
    a1, a2, a3, a4 = 0.02, 0.03, 0.04, 0.05
    params = OdometryMotionParams(a1, a2, a3, a4)
    rng = np.random.default_rng(7)
    n = 40_000
    # Straight ahead then turn: rot1 = 0, trans = 0.2, rot2 = 0.3.
    moved = sample_odometry_motion(np.zeros((n, 3)), np.zeros(3), np.array([0.2, 0.0, 0.3]),
                                   params, rng)
    sd_rot1 = math.sqrt(a2 * 0.2**2)
    sd_trans = math.sqrt(a3 * 0.2**2 + a4 * 0.3**2)
    sd_rot2 = math.sqrt(a1 * 0.3**2 + a2 * 0.2**2)
    heading_sd = math.hypot(sd_rot1, sd_rot2)
    dist = np.hypot(moved[:, 0], moved[:, 1])
    # Sample std has a relative standard error of 1/sqrt(2n) = 0.35 %; allow 3 %.
    assert moved[:, 2].std() == pytest.approx(heading_sd, rel=0.03)
    assert dist.std() == pytest.approx(sd_trans, rel=0.03)
    assert abs(moved[:, 2].mean() - 0.3) < 4 * heading_sd / math.sqrt(n)
    assert abs(dist.mean() - 0.2) < 4 * sd_trans / math.sqrt(n)
    # The direction of travel scatters by rot1's noise only (arctan: a sampled translation
    # can come out negative, a move along the same line).
    assert np.arctan(moved[:, 1] / moved[:, 0]).std() == pytest.approx(sd_rot1, rel=0.03)


def test_backward_motion_rotation_noise_ignores_the_half_turn() -> None:
    # A 0.2 m backward move: rot1 = rot2 = pi, but the noise must not scale with pi.
    params = OdometryMotionParams(alpha1=1.0, alpha2=0.01, alpha3=0.0, alpha4=0.0)
    rng = np.random.default_rng(8)
    moved = sample_odometry_motion(np.zeros((20_000, 3)), np.zeros(3),
                                   np.array([-0.2, 0.0, 0.0]), params, rng)
    expected = math.sqrt(2 * 0.01 * 0.2**2)
    assert wrap(moved[:, 2]).std() == pytest.approx(expected, rel=0.05)
    assert moved[:, 0].mean() == pytest.approx(-0.2, abs=1e-3)


def test_negative_alpha_raises() -> None:
    with pytest.raises(ConfigError, match="alpha3"):
        OdometryMotionParams(alpha3=-0.1)
