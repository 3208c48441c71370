"""The particle filter: resampling, estimates, update on synthetic scans, recovery trigger."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.localization.filter import (
    MCLParams,
    ParticleFilter,
    effective_sample_size,
    low_variance_resample,
    weighted_pose_mean,
)
from simlab.localization.motion import wrap


def test_low_variance_resampling_counts_are_floor_or_ceil() -> None:
    rng = np.random.default_rng(4)
    for _ in range(20):
        w = rng.dirichlet(np.full(50, 0.3))
        idx = low_variance_resample(w, 1000, rng)
        counts = np.bincount(idx, minlength=50)
        assert counts.sum() == 1000
        assert np.all(counts >= np.floor(1000 * w) - 1e-9)
        assert np.all(counts <= np.ceil(1000 * w) + 1e-9)
    uniform = low_variance_resample(np.full(64, 1 / 64), 64, rng)
    np.testing.assert_array_equal(np.sort(uniform), np.arange(64))


def test_effective_sample_size() -> None:
    assert effective_sample_size(np.full(10, 0.1)) == pytest.approx(10)
    assert effective_sample_size(np.eye(1, 10)[0]) == pytest.approx(1)


def test_weighted_pose_mean_is_circular_in_yaw() -> None:
    p = np.array([[0.0, 0.0, math.pi - 0.1], [1.0, 2.0, -math.pi + 0.1]])
    m = weighted_pose_mean(p, np.array([0.5, 0.5]))
    assert m[:2] == pytest.approx([0.5, 1.0])
    assert abs(wrap(m[2] - math.pi)) < 1e-12


def test_gaussian_initialisation_statistics(table_grid) -> None:
    pf = ParticleFilter(table_grid, MCLParams(n_particles=20_000), np.random.default_rng(5))
    cov = np.diag([0.03**2, 0.05**2, 0.2**2])
    pf.init_gaussian(np.array([0.1, -0.2, 3.0]), cov)
    p = pf.particles
    assert p[:, 0].mean() == pytest.approx(0.1, abs=4 * 0.03 / math.sqrt(20_000))
    assert p[:, 1].std() == pytest.approx(0.05, rel=0.03)
    assert wrap(p[:, 2] - 3.0).std() == pytest.approx(0.2, rel=0.03)
    assert np.all((p[:, 2] >= -math.pi) & (p[:, 2] < math.pi))


def test_global_initialisation_stays_in_free_space(table_grid) -> None:
    params = MCLParams(n_particles=3000)
    pf = ParticleFilter(table_grid, params, np.random.default_rng(6))
    pf.init_global()
    rc = table_grid.world_to_pixel(pf.particles[:, :2])
    assert np.all(table_grid.occupancy[rc[:, 0], rc[:, 1]] == 0)
    # Cell centres keep the clearance; a particle is anywhere in its cell.
    clearance = pf.field.distance[rc[:, 0], rc[:, 1]]
    assert clearance.min() >= params.inject_clearance - table_grid.resolution
    assert pf.particles[:, 2].std() == pytest.approx(2 * math.pi / math.sqrt(12), rel=0.05)


def test_update_concentrates_on_the_truth(table_grid, scan_factory) -> None:
    truth = np.array([0.25, -0.3, 0.6])
    scan = scan_factory(table_grid, truth)
    pf = ParticleFilter(table_grid, MCLParams(n_particles=2000), np.random.default_rng(7))
    pf.init_gaussian(truth + np.array([0.03, -0.02, 0.05]),
                     np.diag([0.05**2, 0.05**2, 0.1**2]))
    for _ in range(3):
        pf.update(scan)
    est = pf.estimate()
    assert math.hypot(*(est[:2] - truth[:2])) < 0.01
    assert abs(wrap(est[2] - truth[2])) < 0.02
    assert pf.n_resamples >= 1


def test_recovery_triggers_only_when_the_fit_drops(asym_grid, scan_factory) -> None:
    truth = np.array([-0.3, 0.2, 1.0])
    scan = scan_factory(asym_grid, truth)
    good = ParticleFilter(asym_grid, MCLParams(), np.random.default_rng(8))
    good.init_gaussian(truth, np.diag([0.005**2, 0.005**2, 0.01**2]))
    good.update(scan)
    assert good.injection_probability < 0.05
    wrong = ParticleFilter(asym_grid, MCLParams(), np.random.default_rng(8))
    wrong.init_gaussian(truth + np.array([0.5, 0.0, math.pi / 2]),
                        np.diag([0.005**2, 0.005**2, 0.01**2]))
    wrong.update(scan)
    assert wrong.last_fit < 0.8 * good.last_fit
    assert wrong.injection_probability > 0.05
    assert wrong.n_injected > 0


def test_same_seed_same_filter(table_grid, scan_factory) -> None:
    scan = scan_factory(table_grid, np.array([0.0, 0.1, 0.2]), n_beams=90)
    runs = []
    for _ in range(2):
        pf = ParticleFilter(table_grid, MCLParams(n_particles=300), np.random.default_rng(9))
        pf.init_global()
        pf.predict(np.zeros(3), np.array([0.05, 0.0, 0.1]))
        pf.update(scan)
        runs.append(pf.particles.copy())
    np.testing.assert_array_equal(*runs)


def test_scan_without_returns_changes_nothing(table_grid) -> None:
    pf = ParticleFilter(table_grid, MCLParams(n_particles=100), np.random.default_rng(1))
    pf.init_gaussian(np.zeros(3))
    before = pf.particles.copy()

    class Empty:
        ranges = np.full(360, np.inf)
        angles = np.linspace(0, 2 * math.pi, 360, endpoint=False)
        sensor_offset = np.zeros(2)

    assert pf.update(Empty()) is False
    np.testing.assert_array_equal(pf.particles, before)
    assert pf.n_updates == 0


@pytest.mark.parametrize("kwargs", [dict(n_particles=0), dict(n_beams=-1),
                                    dict(alpha_slow=0.5, alpha_fast=0.1),
                                    dict(resample_threshold=1.5), dict(estimate_radius=0.0)])
def test_bad_filter_parameters_raise(kwargs) -> None:
    with pytest.raises(ConfigError, match="MCLParams"):
        MCLParams(**kwargs)


def test_filter_needs_a_generator_and_an_initialisation(table_grid) -> None:
    with pytest.raises(ConfigError, match="Generator"):
        ParticleFilter(table_grid, MCLParams(), None)
    pf = ParticleFilter(table_grid, MCLParams(n_particles=10), np.random.default_rng(0))
    with pytest.raises(RuntimeError, match="initialise"):
        pf.estimate()


def test_compiled_estimate_equals_the_numpy_reference() -> None:
    from simlab.localization.filter import _mean_shift, mean_shift_numpy

    rng = np.random.default_rng(12)
    p = np.concatenate([rng.normal([0.2, 0.1, 3.1], [0.03, 0.03, 0.05], (300, 3)),
                        rng.uniform(-0.7, 0.7, (200, 3))])
    p[:, 2] = wrap(p[:, 2])
    w = rng.random(500)
    w /= w.sum()
    fast = _mean_shift(p, w, 0.01, 0.5, 3)
    ref = mean_shift_numpy(p, w, 0.01, 0.5, 3)
    np.testing.assert_allclose(fast[:2], ref[:2], atol=1e-12)
    assert abs(wrap(fast[2] - ref[2])) < 1e-12
    assert math.hypot(fast[0] - 0.2, fast[1] - 0.1) < 0.02  # the dense mode, not the mean
