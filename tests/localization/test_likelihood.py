"""The likelihood-field sensor model: analytic values, numba = numpy, edge cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from discretize.gridmap import OccupancyMap
from simlab.base.errors import ConfigError
from simlab.localization.likelihood import (
    LikelihoodField,
    SensorModelParams,
    scan_log_likelihoods,
    scan_log_likelihoods_numpy,
)


def test_log_density_analytic_values() -> None:
    p = SensorModelParams(sigma_hit=0.03, z_hit=0.9, z_rand=0.1, z_max=3.5, max_distance=0.4)
    at0 = math.log(0.9 / (math.sqrt(2 * math.pi) * 0.03) + 0.1 / 3.5)
    assert p.log_density(0.0) == pytest.approx(at0, rel=1e-12)
    d = np.linspace(0, 0.6, 61)
    v = p.log_density(d)
    assert np.all(np.diff(v[d <= 0.15]) < 0)  # strictly decreasing while the Gaussian counts
    assert np.all(np.diff(v) <= 0)  # then flat at the random part (float resolution)
    assert np.all(v[d >= 0.4] == v[-1])  # clipped beyond max_distance
    assert p.outside_log_density == pytest.approx(math.log(0.1 / 3.5))


def test_nominal_fit_matches_monte_carlo() -> None:
    p = SensorModelParams()
    rng = np.random.default_rng(3)
    samples = p.log_density(np.abs(rng.normal(0.0, 0.014, 200_000)))
    se = samples.std() / math.sqrt(samples.size)
    assert abs(p.nominal_beam_log_likelihood(0.014) - samples.mean()) < 4 * se


def test_numba_kernel_equals_numpy_reference(table_grid: OccupancyMap) -> None:
    field = LikelihoodField(table_grid)
    rng = np.random.default_rng(0)
    particles = np.column_stack([rng.uniform(-0.9, 0.9, (300, 2)), rng.uniform(-4, 4, 300)])
    ranges = rng.uniform(0.12, 2.5, 45)
    ranges[::7] = np.inf
    angles = rng.uniform(0, 2 * math.pi, 45)
    off = np.array([-0.032, 0.01])
    fast = scan_log_likelihoods(field, particles, ranges, angles, off)
    ref = scan_log_likelihoods_numpy(field, particles, ranges, angles, off)
    np.testing.assert_allclose(fast, ref, rtol=1e-12, atol=1e-9)


def test_true_pose_scores_every_beam_near_the_peak(table_grid, scan_factory) -> None:
    field = LikelihoodField(table_grid)
    truth = np.array([0.2, -0.1, 0.7])
    scan = scan_factory(table_grid, truth, n_beams=60)
    k = int(np.isfinite(scan.ranges).sum())
    ll = field.log_likelihoods(truth[None], scan.ranges, scan.angles, scan.sensor_offset)[0]
    # Every end point lies on a wall surface: within half a pixel diagonal plus the 0.5 mm
    # ray-marching step of an occupied pixel centre.
    worst = field.params.log_density(0.5 * math.sqrt(2) * table_grid.resolution + 0.0005)
    assert ll >= k * worst
    shifted = truth + np.array([[0.1, 0, 0], [0, -0.05, 0], [0, 0, 0.2]])
    others = field.log_likelihoods(shifted, scan.ranges, scan.angles, scan.sensor_offset)
    assert np.all(others < ll)


def test_beams_without_return_are_skipped(table_grid) -> None:
    field = LikelihoodField(table_grid)
    p = np.array([[0.0, 0.0, 0.3], [0.1, 0.2, -1.0]])
    ranges = np.array([0.5, 0.7, 1.0])
    angles = np.array([0.0, 1.0, 2.0])
    base = field.log_likelihoods(p, ranges, angles, np.zeros(2))
    more = field.log_likelihoods(p, np.append(ranges, [np.inf, np.inf]),
                                 np.append(angles, [3.0, 4.0]), np.zeros(2))
    np.testing.assert_array_equal(base, more)


def test_end_points_outside_the_map_score_the_random_part(table_grid) -> None:
    field = LikelihoodField(table_grid)
    far = np.array([[50.0, 50.0, 0.0]])
    ll = field.log_likelihoods(far, np.full(10, 1.0), np.linspace(0, 6, 10), np.zeros(2))
    assert ll[0] == pytest.approx(10 * field.params.outside_log_density)


@pytest.mark.parametrize("kwargs", [dict(sigma_hit=0.0), dict(z_rand=0.0), dict(z_hit=1.5),
                                    dict(max_distance=-1.0), dict(occupied_threshold=0)])
def test_bad_sensor_parameters_raise(kwargs) -> None:
    with pytest.raises(ConfigError, match="SensorModelParams"):
        SensorModelParams(**kwargs)


def test_map_without_obstacles_is_refused() -> None:
    grid = OccupancyMap(np.zeros((20, 20), dtype=np.int8), 0.05)
    with pytest.raises(ConfigError, match="no occupied cell"):
        LikelihoodField(grid)
