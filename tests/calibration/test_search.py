"""Calibration search: recovery of hidden parameters, common random numbers, input checks.

The kinematic simulator makes the recovery test fast (a 10-hour walk in about a second);
the physics recovery lives in test_physics_recovery.py (slow).
"""

from __future__ import annotations

import numpy as np
import pytest

from simlab.base.actions import SIMLAB16, parse_action_set
from simlab.base.errors import ConfigError
from simlab.calibration.config import CalibrationConfig, RealTable
from simlab.calibration.space import ParameterSpace, ParamSpec
from simlab.calibration.stages import calibrate
from simlab.data.walkers import KinematicParams
from tests.calibration.conftest import hidden_walk, real_table

CCW8 = parse_action_set(8, "ccw-east")
# drive time and the detector's clearance shape T; the heading noise would not do for a
# recovery test: on 0.4 m cells its profile is flat within the sampling noise (measured:
# 0.0 to 0.5 rad give distances within 0.02 of each other, below the matched floor's spread).
SPACE = ParameterSpace((ParamSpec("drive_time", 0.2, 2.0, "log"),
                        ParamSpec("clearance", 0.0, 0.5)))


@pytest.mark.slow
def test_hidden_kinematic_parameters_are_recovered(lattice16) -> None:
    hidden = KinematicParams(drive_time=1.2, clearance=0.25)
    real = real_table(hidden_walk(lattice16, hidden, CCW8, 10.0, 99, "kinematic"), CCW8)
    cfg = CalibrationConfig(hours_per_candidate=10.0, candidates=20, workers=2, seed=0,
                            simulator="kinematic", n_boot=100, progress=False)
    res = calibrate(real, "table", lattice16, space=SPACE, config=cfg)
    assert res.params.drive_time == pytest.approx(1.2, rel=0.2)
    assert res.params.clearance == pytest.approx(0.25, abs=0.08)
    # the starting point (defaults) is measurably off; the winner is not
    assert res.candidates[0].values["drive_time"] == pytest.approx(0.5)
    assert res.candidates[0].distance > res.matched_floor.high
    # the winner, re-simulated on a fresh seed, lies within sampling noise of a perfect fit
    assert res.final.stage == "pooled"  # its confirming walks on fresh seeds, pooled
    # the signature at the robot's visits: a twin of the hidden robot shows its stays
    gap = res.final.gap
    assert gap is not None and abs(gap.self_share - gap.self_share_real) < 0.05
    # (20 % above the band's top: the winner's parameters carry the search's own error)
    assert res.final.distance <= 1.2 * res.matched_floor.high
    assert res.matched_floor.median >= res.floor.median  # fewer simulated visits than real
    assert res.agreement > 0.8
    # decision latency fitted from the real rate (the hidden walk's 3.0 s)
    assert res.latency_fitted
    assert res.params.decision_latency == pytest.approx(3.0, abs=0.3)
    # on the fresh seed the winner beats the starting point it was compared with there
    assert res.start_confirmed is not None and res.start_confirmed.stage == "pooled"
    assert res.final.score < res.start_confirmed.score


def test_the_starting_point_is_kept_unless_beaten_on_the_fresh_seed(lattice9) -> None:
    """Real data made with the defaults: nothing is better than the start, and the
    calibration never returns parameters that score worse than it on the fresh seed."""
    real = real_table(hidden_walk(lattice9, KinematicParams(), CCW8, 2.0, 21, "kinematic"), CCW8)
    cfg = CalibrationConfig(hours_per_candidate=2.0, candidates=6, workers=1, seed=3,
                            simulator="kinematic", n_boot=20, progress=False)
    res = calibrate(real, "table", lattice9, space=SPACE, config=cfg)
    start = res.start_confirmed if res.best != 0 else res.final
    assert start is not None and res.final.score <= start.score
    if res.best == 0:
        assert res.params.drive_time == KinematicParams().drive_time
        assert any("beat the starting point" in n for n in res.notes) or \
            res.candidates[0].score <= min(c.score for c in res.candidates)


def test_same_seed_same_search_and_common_random_numbers(lattice9) -> None:
    real = real_table(hidden_walk(lattice9, KinematicParams(drive_time=0.9), SIMLAB16, 1.0, 5,
                                  "kinematic"), SIMLAB16)
    cfg = CalibrationConfig(hours_per_candidate=0.5, candidates=4, workers=1, seed=3,
                            simulator="kinematic", n_boot=20, progress=False, confirm=False)
    space = ParameterSpace((ParamSpec("drive_time", 0.2, 2.0, "log"),))
    a = calibrate(real, "table", lattice9, space=space, config=cfg)
    b = calibrate(real, "table", lattice9, space=space, config=cfg)
    assert [c.distance for c in a.candidates] == [c.distance for c in b.candidates]
    assert [c.values for c in a.candidates] == [c.values for c in b.candidates]
    # every candidate walks the same seed: same number of decisions drawn per part, so
    # equal drive times give identical tables
    again = calibrate(real, "table", lattice9, space=space,
                      config=CalibrationConfig(**{**cfg.__dict__, "candidates": 2}))
    np.testing.assert_array_equal(again.candidates[0].sim.counts, a.candidates[0].sim.counts)


@pytest.mark.slow
def test_the_search_does_not_depend_on_the_number_of_workers(lattice9) -> None:
    """Candidates are proposed in batches of their own size, so one process and two give
    the same candidates, scores, promotions and winner (and the same run twice does)."""
    real = real_table(hidden_walk(lattice9, KinematicParams(), SIMLAB16, 0.5, 5, "kinematic"),
                      SIMLAB16)
    space = ParameterSpace((ParamSpec("drive_time", 0.2, 2.0, "log"),))
    kw = dict(hours_per_candidate=0.3, candidates=6, seed=1, simulator="kinematic",
              n_boot=10, progress=False, confirm=False, batch=3, confirm_top=1)
    one = calibrate(real, "table", lattice9, space=space,
                    config=CalibrationConfig(workers=1, **kw))
    two = calibrate(real, "table", lattice9, space=space,
                    config=CalibrationConfig(workers=2, **kw))
    assert [c.values for c in one.candidates] == [c.values for c in two.candidates]
    assert [c.score for c in one.candidates] == [c.score for c in two.candidates]
    assert one.search is not None and two.search is not None
    assert [[c.index for c in r] for r in one.search.rungs] == \
        [[c.index for c in r] for r in two.search.rungs]
    assert one.best == two.best and one.params == two.params


def test_successive_halving_promotes_the_best_third_on_pooled_walks(lattice9) -> None:
    """Rung 2 walks the best third of rung 1 (by score, distinct points) on the rung's own
    seed, three times the rung-1 size, and scores each on both its walks pooled."""
    real = real_table(hidden_walk(lattice9, KinematicParams(drive_time=0.9), SIMLAB16, 1.0,
                                  5, "kinematic"), SIMLAB16)
    space = ParameterSpace((ParamSpec("drive_time", 0.2, 2.0, "log"),))
    cfg = CalibrationConfig(hours_per_candidate=0.2, candidates=9, workers=1, seed=4,
                            simulator="kinematic", n_boot=10, progress=False, confirm=False,
                            batch=3, eta=3, rungs=2, confirm_top=1)
    res = calibrate(real, "table", lattice9, space=space, config=cfg)
    found = res.search
    assert found is not None and len(found.rungs) == 1
    promoted = [c.index for c in found.rungs[0]]
    ranked = sorted(found.candidates, key=lambda c: (c.score, c.index))
    assert promoted == [c.index for c in ranked[:3]]
    for c in found.rungs[0]:
        first = found.candidates[c.index].sim
        assert c.sim.rows > first.rows          # its rung-1 walk and the rung-2 walk
        assert c.seed == cfg.seed + 1           # the rung's common seed
        assert c.stage == "rung 2"
    assert found.sizes[0] == (0.2, None) and found.sizes[1][0] == pytest.approx(0.6)
    assert res.best == found.picks[0] == min(found.rungs[0], key=lambda c: (c.score,
                                                                            c.index)).index


def test_inconsistent_inputs_are_refused_before_simulating(lattice9) -> None:
    counts = np.ones((16, 8, 16), dtype=np.int64)
    with pytest.raises(ConfigError, match="9 states, the real table 16"):
        calibrate(RealTable(counts, CCW8), "table", lattice9,
                  config=CalibrationConfig(simulator="kinematic", progress=False))
    with pytest.raises(ConfigError, match="8 actions in the counts"):
        RealTable(counts, SIMLAB16)
    with pytest.raises(ConfigError, match="no field 'slip'"):
        calibrate(RealTable(np.ones((9, 8, 9), dtype=np.int64), CCW8), "table", lattice9,
                  space=ParameterSpace((ParamSpec("slip", 0.0, 0.5),)),
                  config=CalibrationConfig(simulator="kinematic", progress=False))
    with pytest.raises(ConfigError, match=r"calibration\.candidates"):
        CalibrationConfig(candidates=1)


def test_data_need_recovers_limit_and_slope_of_a_one_over_n_curve() -> None:
    """Rows lying exactly on ratio = 1.05 + 500 / N give back the limit and the slope, and
    the transitions at which the excess is the tolerance: 500 / 0.01 = 50,000."""
    from simlab.calibration.stages import data_need

    curve = [{"transitions": n, "mean_ratio": 1.05 + 500 / n} for n in (8000, 16000, 40000)]
    need = data_need(curve, tolerance=0.01)
    assert need is not None
    assert need["limit"] == pytest.approx(1.05) and need["c"] == pytest.approx(500)
    assert need["transitions"] == pytest.approx(50_000)


@pytest.mark.parametrize("ratios", [
    [1.10, 1.12],                 # more data, worse: no 1/N law to extrapolate
    [1.10, float("inf")],         # a pool that never arrives
    [1.10],                       # one size only
])
def test_data_need_refuses_curves_it_cannot_extrapolate(ratios: list[float]) -> None:
    from simlab.calibration.stages import data_need

    curve = [{"transitions": 8000 * (k + 1), "mean_ratio": r} for k, r in enumerate(ratios)]
    assert data_need(curve) is None


@pytest.mark.slow
def test_the_search_on_ray_tasks_is_the_local_search(lattice9) -> None:
    """The same candidates, scores, promotions and winner whether the walks run as Ray
    tasks or as local processes: the search depends on its seed only."""
    ray = pytest.importorskip("ray")
    from simlab.calibration.search import search
    from simlab.calibration.walks import WalkRunner

    real = real_table(hidden_walk(lattice9, KinematicParams(drive_time=0.9), SIMLAB16, 0.5, 5,
                                  "kinematic"), SIMLAB16)
    space = ParameterSpace((ParamSpec("drive_time", 0.2, 2.0, "log"),
                            ParamSpec("clearance", 0.0, 0.5)))
    cfg = CalibrationConfig(hours_per_candidate=0.2, candidates=6, workers=2, seed=2,
                            simulator="kinematic", progress=False, batch=3, confirm_top=1)
    found = {}
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        for backend in ("ray", "local"):
            runner = WalkRunner(2, backend=backend)
            try:
                found[backend] = search(real, "table", lattice9, space=space,
                                        base=KinematicParams(), config=cfg, runner=runner)
            finally:
                runner.close()
    finally:
        ray.shutdown()
    a, b = found["ray"], found["local"]
    assert [c.values for c in a.candidates] == [c.values for c in b.candidates]
    assert [c.score for c in a.candidates] == [c.score for c in b.candidates]
    assert [[c.score for c in r] for r in a.rungs] == [[c.score for c in r] for r in b.rungs]
    assert a.picks == b.picks


def test_every_sampler_is_made_and_cmaes_without_its_package_is_one_clear_error(
        monkeypatch) -> None:
    import importlib.util
    import sys

    from simlab.calibration.config import SAMPLERS
    from simlab.calibration.search import make_sampler

    for name in SAMPLERS:
        if name == "cmaes" and importlib.util.find_spec("cmaes") is None:
            continue   # an optional package: its absence is the error checked below
        sampler = make_sampler(name, seed=3, n_candidates=12, batch=4)
        assert type(sampler).__name__.lower().startswith(
            {"tpe": "tpe", "cmaes": "cmaes", "qmc": "qmc", "random": "random"}[name])
    monkeypatch.setitem(sys.modules, "cmaes", None)   # as if the package were not installed
    with pytest.raises(ConfigError, match="pip install cmaes"):
        make_sampler("cmaes", seed=3, n_candidates=12, batch=4)
