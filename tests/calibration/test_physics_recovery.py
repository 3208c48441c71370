"""Physics recovery: a "real" table made by PyBullet with a hidden drive time is recovered.

Slow (about 1-2 minutes on 2 cores): a 2-hour hidden walk and 6 candidates of 1.5 hours.
"""

from __future__ import annotations

import math

import pytest

from simlab.base.actions import SIMLAB16
from simlab.calibration.config import CalibrationConfig
from simlab.calibration.space import ParameterSpace, ParamSpec
from simlab.calibration.stages import calibrate
from simlab.physics.motion import PrimitiveParams
from tests.calibration.conftest import hidden_walk, real_table


@pytest.mark.slow
def test_hidden_drive_time_is_recovered_in_physics(lattice9) -> None:
    hidden = PrimitiveParams(drive_time=1.0)
    real = real_table(hidden_walk(lattice9, hidden, SIMLAB16, 2.0, 99, "physics"), SIMLAB16)
    space = ParameterSpace((ParamSpec("drive_time", 0.3, 1.5, "log"),))
    cfg = CalibrationConfig(hours_per_candidate=1.5, candidates=6, workers=2, seed=0,
                            n_boot=100, progress=False)
    res = calibrate(real, "table", lattice9, space=space, config=cfg)
    # within 30 %: measured profile on this budget is flat to within the noise over 0.8-1.2 s
    assert abs(math.log(res.params.drive_time / 1.0)) < math.log(1.3)
    assert res.candidates[0].values["drive_time"] == pytest.approx(0.5)
    assert res.candidates[0].distance > res.matched_floor.high
    assert res.final.distance <= 1.2 * res.matched_floor.high
    assert res.params.decision_latency == pytest.approx(hidden.decision_latency, abs=0.3)
