"""Issue 17 part 3: the replay's MCL hot path without numpy glue gives the very same bits
as the numpy formulas it replaced (equality, not closeness: the replay digests depend on it)."""

from __future__ import annotations

import math

import numpy as np

from simlab.localization.filter import (
    MCLParams,
    ParticleFilter,
    _low_variance_indices,
    _mean_shift,
    _resample_into,
    _reweight,
    _weigh,
)
from simlab.localization.likelihood import (
    LikelihoodField,
    scan_log_likelihoods,
    scan_log_likelihoods_numpy,
)
from simlab.localization.motion import (
    OdometryMotionParams,
    compose,
    compose3,
    odometry_delta,
    relative,
    relative3,
    sample_odometry_motion,
    wrap,
    wrap1,
)


def _numpy_trig_is_libm() -> bool:
    """Whether numpy's float64 cos/sin give the C library's bits here (the compiled code
    calls libm). True on the x86-64 hosts checked (SIMD level X86_V3); numpy's AVX-512
    kernels may differ in the last bit, and there the replay is still deterministic per
    host but these comparisons can only be within an ulp or two."""
    x = np.random.default_rng(0).uniform(-20.0, 20.0, 20_000)
    return (np.array_equal(np.cos(x), np.array([math.cos(v) for v in x]))
            and np.array_equal(np.sin(x), np.array([math.sin(v) for v in x])))


LIBM_TRIG = _numpy_trig_is_libm()


def _assert_same(fast: np.ndarray, ref: np.ndarray) -> None:
    """Bit equality where numpy's trig is libm's, else at most 4 ulp apart."""
    if LIBM_TRIG:
        assert np.array_equal(fast, ref)
    else:  # pragma: no cover - AVX-512 hosts
        np.testing.assert_array_max_ulp(fast, ref, maxulp=4)


def _poses(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    p = rng.uniform(-1.0, 1.0, (n, 3))
    p[:, 2] *= 4.0  # yaw beyond +-pi too
    p[:8, 2] = [math.pi, -math.pi, 0.0, -0.0, 2 * math.pi, 3 * math.pi, 1e-300, -1e-17]
    return p


def test_single_pose_math_is_the_array_math() -> None:
    a, b = _poses(2000, 1), _poses(2000, 2)
    comp, rel = compose(a, b), relative(a, b)  # the vectorised (N, 3) path
    for i in range(len(a)):
        _assert_same(np.array(compose3(a[i].tolist(), b[i].tolist())), comp[i])
        _assert_same(np.array(relative3(a[i].tolist(), b[i].tolist())), rel[i])
        _assert_same(compose(a[i], b[i]), comp[i])
        assert wrap1(float(a[i, 2])) == float(wrap(a[i, 2]))


def _numpy_motion(p, odom_prev, odom_now, params, rng):
    """The numpy formulas the compiled motion replaced (the reference)."""
    rot1, trans, rot2 = odometry_delta(odom_prev, odom_now, params.min_translation)
    r1n = min(abs(rot1), abs(float(wrap(rot1 - math.pi))))
    r2n = min(abs(rot2), abs(float(wrap(rot2 - math.pi))))
    sd_rot1 = math.sqrt(params.alpha1 * r1n**2 + params.alpha2 * trans**2)
    sd_trans = math.sqrt(params.alpha3 * trans**2 + params.alpha4 * (r1n**2 + r2n**2))
    sd_rot2 = math.sqrt(params.alpha1 * r2n**2 + params.alpha2 * trans**2)
    noise = rng.standard_normal((p.shape[0], 3))
    heading = p[:, 2] + (rot1 - sd_rot1 * noise[:, 0])
    h_trans = trans - sd_trans * noise[:, 1]
    out = np.empty_like(p)
    out[:, 0] = p[:, 0] + h_trans * np.cos(heading)
    out[:, 1] = p[:, 1] + h_trans * np.sin(heading)
    out[:, 2] = wrap(heading + (rot2 - sd_rot2 * noise[:, 2]))
    return out


def test_compiled_motion_is_the_numpy_motion() -> None:
    params = OdometryMotionParams()
    p = _poses(3000, 3)
    prev = np.array([0.1, -0.2, 0.3])
    for k, step in enumerate(([0.03, 0.01, 0.2], [-0.05, 0.0, 3.0], [0.001, 0.0, -0.4])):
        now = prev + np.asarray(step)
        fast = sample_odometry_motion(p, prev, now, params, np.random.default_rng(k))
        ref = _numpy_motion(p, prev, now, params, np.random.default_rng(k))
        _assert_same(fast, ref)


def test_fused_weighing_is_the_three_kernels(table_grid) -> None:
    field = LikelihoodField(table_grid)
    pf = ParticleFilter(field, MCLParams(), np.random.default_rng(6))
    pf.init_gaussian(np.array([0.1, -0.2, 0.5]), np.diag([0.05**2, 0.05**2, 0.3**2]))
    rng = np.random.default_rng(7)
    ranges = rng.uniform(0.1, 0.9, 360)
    ranges[rng.random(360) < 0.2] = np.inf
    angles = np.arange(360) * (2 * np.pi / 360)
    offset = np.array([-0.032, 0.0])
    beams = pf.beam_subset(360)
    out = np.empty(500)
    k, total, ess, est = _weigh(pf.particles, pf.weights, ranges, angles, beams, offset,
                                field.log_table, field.geometry, 0.01, 0.5, 3, out)
    loglik = scan_log_likelihoods(field, pf.particles, ranges[beams], angles[beams], offset)
    ref_w = np.empty(500)
    ref_total, ref_ess = _reweight(pf.weights, loglik, ref_w)
    assert k == int(np.isfinite(ranges[beams]).sum())
    assert (total, ess) == (ref_total, ref_ess)
    assert np.array_equal(out, ref_w)
    assert np.array_equal(est, _mean_shift(pf.particles, ref_w, 0.01, 0.5, 3))


def test_fused_weighing_without_returns_changes_nothing(table_grid) -> None:
    pf = ParticleFilter(table_grid, MCLParams(), np.random.default_rng(6))
    pf.init_gaussian(np.zeros(3))
    scan = type("Scan", (), {"ranges": np.full(360, np.inf), "angles": np.zeros(360),
                             "sensor_offset": np.zeros(2)})
    before = pf.weights.copy()
    assert pf.update(scan) is False
    assert np.array_equal(pf.weights, before) and pf.n_updates == 0


def test_likelihood_kernel_is_the_numpy_field_summed_in_beam_order(table_grid) -> None:
    """Bit equality with the numpy formulas (per beam), summed beam after beam as the
    kernel sums: end points inside, on and beyond the map's edges."""
    field = LikelihoodField(table_grid)
    rng = np.random.default_rng(8)
    particles = np.column_stack([rng.uniform(-0.9, 0.9, (400, 2)),
                                 rng.uniform(-4.0, 4.0, 400)])
    ranges = rng.uniform(0.05, 2.0, 60)
    angles = rng.uniform(-math.pi, math.pi, 60)
    offset = np.array([-0.032, 0.01])
    fast = scan_log_likelihoods(field, particles, ranges, angles, offset)
    ref = np.zeros(len(particles))
    for j in range(len(ranges)):
        ref = ref + scan_log_likelihoods_numpy(field, particles, ranges[j:j + 1],
                                               angles[j:j + 1], offset)
    _assert_same(fast, ref)


def test_compiled_resampling_is_numpy_search_or_declines() -> None:
    rng = np.random.default_rng(9)
    p = _poses(300, 10)
    cases = [rng.random(300), np.full(300, 1 / 300), np.eye(1, 300, 17)[0],
             rng.random(300) ** 40]
    cases[3][::3] = 0.0
    for w in cases:
        w = w / w.sum()
        for u in (0.0, 0.5, rng.random(), 1.0 - 2**-53):
            out = np.empty((300, 3))
            if _resample_into(w, u, p, out):
                assert np.array_equal(out, p[_low_variance_indices(w, 300, u)])
            else:  # only when the last pointer rounds up to 1 (numpy's path fails too)
                assert (u + 299) / 300 >= 1.0
    bad = np.full(300, 1 / 300)
    for value in (np.nan, -0.1):
        bad[5] = value
        assert not _resample_into(bad, 0.3, p, np.empty((300, 3)))
