"""The twin ensemble in ``primitives.toml``: ``[[ensemble]]``, one full record per member
(the winner first), read back by ``PrimitiveParams.ensemble_from_toml``."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from simlab.base.actions import parse_action_set
from simlab.calibration.report import primitives_toml
from simlab.calibration.search import params_at
from simlab.calibration.space import ParameterSpace, ParamSpec
from simlab.cli import main
from simlab.data.walkers import KinematicParams
from simlab.physics.motion import PrimitiveParams
from tests.calibration.conftest import hidden_walk, write_counts_csv

SPACE = ParameterSpace((ParamSpec("fast_speed", 0.10, 0.26), ParamSpec("wall_slide", 0.0, 0.5),
                        ParamSpec("mode", choices=("fixed", "until_state_change"))))
#: the winner's latency, fitted from the real hours (a searched record keeps the base's 3.02)
FITTED = 2.25


def _result(units: list[list[float]]) -> SimpleNamespace:
    """What ``primitives_toml`` reads of a physics calibration whose ensemble is the
    candidates at ``units`` (the winner first; candidate ``#k + 4``, distance ``0.1 + k/100``)."""
    base = PrimitiveParams()
    members = [SimpleNamespace(index=k + 4, unit=np.array(u), distance=0.1 + k / 100)
               for k, u in enumerate(units)]
    winner = params_at(SPACE, base, members[0].unit).replace(decision_latency=FITTED)
    return SimpleNamespace(
        real=SimpleNamespace(source="real.csv"), params=winner, base=base, space=SPACE,
        final=SimpleNamespace(distance=members[0].distance),
        floor=SimpleNamespace(median=0.05), matched_floor=SimpleNamespace(median=0.06),
        perfect_floor=SimpleNamespace(median=0.065),
        config=SimpleNamespace(simulator="physics"), ensemble=members, latency_fitted=True)


def test_the_ensemble_round_trips_with_the_winners_latency(tmp_path: Path) -> None:
    units = [[0.9, 0.1, 0.8], [0.2, 0.7, 0.8], [0.5, 0.4, 0.1]]
    result = _result(units)
    path = tmp_path / "primitives.toml"
    path.write_text(primitives_toml(result))
    members = PrimitiveParams.ensemble_from_toml(path)
    expected = tuple(params_at(SPACE, PrimitiveParams(), np.array(u)).replace(
        decision_latency=FITTED) for u in units)
    assert members == expected
    assert members[0] == result.params == PrimitiveParams.from_toml(path)
    assert len({m.fast_speed for m in members}) == 3 and members[2].mode == "fixed"
    text = path.read_text()
    for k in range(3):
        assert f"# member {k}: candidate #{k + 4}, distance {0.1 + k / 100:.6f}" in text
    assert text.count("(the winner)") == 1
    doc = tomllib.loads(text)
    assert doc["calibration"]["simulator"] == "physics"
    # every field of every member, as in [primitives]
    assert all(set(m) == set(doc["primitives"]) for m in doc["ensemble"])


def test_the_winner_alone_writes_no_ensemble() -> None:
    alone = _result([[0.9, 0.1, 0.8]])
    unconfirmed = _result([[0.9, 0.1, 0.8]])
    unconfirmed.ensemble = []  # --no-confirm forms no ensemble
    for result in (alone, unconfirmed):
        text = primitives_toml(result)
        assert "[[ensemble]]" not in text and "ensemble" not in tomllib.loads(text)


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory: pytest.TempPathFactory, lattice9) -> Path:
    """A tiny kinematic calibration (3 candidates, confirmed) of a hidden walk."""
    d = tmp_path_factory.mktemp("cal")
    lattice9.save(d / "states.json")
    aset = parse_action_set(8, "ccw-east")
    sim = hidden_walk(lattice9, KinematicParams(drive_time=0.9), aset, 1.0, 4, "kinematic")
    real = write_counts_csv(d / "real.csv", sim.counts)
    assert main(["calibrate", "--real", str(real), "--states", str(d / "states.json"),
                 "--out", str(d / "out"), "--simulator", "kinematic", "--n-actions", "8",
                 "--convention", "ccw-east", "--hours-per-candidate", "0.5", "--candidates",
                 "3", "--workers", "1", "--n-boot", "20", "--no-progress", "--real-hours",
                 f"{sim.hours}"]) == 0
    return d / "out"


def test_calibrate_writes_its_ensemble_members_as_the_report_lists_them(
        calibrated: Path) -> None:
    report = json.loads((calibrated / "report.json").read_text())
    doc = tomllib.loads((calibrated / "primitives.toml").read_text())
    listed = report["ensemble"]["members"]
    written = doc.get("ensemble", [])
    assert len(written) == (len(listed) if len(listed) >= 2 else 0)
    if written:
        assert written[0] == doc["primitives"]  # the winner first
    for record, member in zip(written, listed, strict=False):
        for name, value in member["values"].items():
            assert record[name] == pytest.approx(value)
        assert record["decision_latency"] == doc["primitives"]["decision_latency"]
        assert set(record) == set(doc["primitives"])
