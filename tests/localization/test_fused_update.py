"""Issue 17 part 2: the compiled reweighting and spread equal their numpy definitions
within float rounding."""

from __future__ import annotations

import math

import numpy as np

from simlab.localization.filter import (
    MCLParams,
    ParticleFilter,
    _reweight,
    effective_sample_size,
)


def test_reweight_matches_numpy() -> None:
    rng = np.random.default_rng(3)
    w = rng.random(400)
    w[::7] = 0.0  # particles of weight zero stay at zero
    w /= w.sum()
    loglik = -80.0 * rng.random(400)
    out = np.empty_like(w)
    total, ess = _reweight(w, loglik, out)
    with np.errstate(divide="ignore"):
        logw = np.log(w) + loglik
    top = logw.max()
    ref_total = top + math.log(np.exp(logw - top).sum())
    ref = np.exp(logw - ref_total)
    assert abs(total - ref_total) <= 1e-12 * abs(ref_total)
    np.testing.assert_allclose(out, ref, rtol=1e-12, atol=0)
    assert np.all(out[::7] == 0.0)
    assert math.isclose(ess, effective_sample_size(ref), rel_tol=1e-12)


def test_spread_is_the_covariance_trace(table_grid) -> None:
    pf = ParticleFilter(table_grid, MCLParams(n_particles=300), np.random.default_rng(4))
    pf.init_gaussian(np.array([0.1, -0.1, 3.1]), np.diag([0.02**2, 0.03**2, 0.2**2]))
    pf.weights = np.random.default_rng(5).random(300)  # unnormalised on purpose
    c = pf.covariance()
    pos, yaw = pf.spread()
    assert math.isclose(pos, math.sqrt(c[0, 0] + c[1, 1]), rel_tol=1e-12)
    assert math.isclose(yaw, math.sqrt(c[2, 2]), rel_tol=1e-12)  # yaw wraps around +-pi
    assert 0.02 < pos < 0.05 and 0.1 < yaw < 0.3
