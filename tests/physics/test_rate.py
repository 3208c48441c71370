"""The physics rate: its minimum, its solver iterations, and every physics stage using,
recording and keying on the same rate."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from discretize.voronoi import Discretizer
from simlab.base.errors import ConfigError
from simlab.physics.motion import PrimitiveParams, execute_primitive
from simlab.physics.rate import (
    DEFAULT_HZ,
    MAX_HZ,
    MIN_HZ,
    RECORDLESS_HZ,
    SETTINGS,
    check_rate,
    settings_for,
)
from simlab.physics.world import World


def test_a_rate_below_the_minimum_is_refused_naming_the_minimum() -> None:
    assert check_rate(MIN_HZ) == MIN_HZ and check_rate(int(DEFAULT_HZ)) == DEFAULT_HZ
    with pytest.raises(ConfigError, match=rf"physics_hz: .*the range is {MIN_HZ:g} to "
                       rf"{MAX_HZ:g} Hz"):
        check_rate(MIN_HZ - 1)
    for bad in ("fast", True, math.nan, math.inf, None):
        with pytest.raises(ConfigError, match="physics_hz"):
            check_rate(bad)


def test_a_rate_above_the_maximum_is_refused_naming_the_range() -> None:
    """1e9 Hz ran every physics command until it was killed: the finest rate is bounded."""
    assert check_rate(MAX_HZ) == MAX_HZ
    for hz in (MAX_HZ + 1, 1e9):
        with pytest.raises(ConfigError, match=rf"physics_hz: .*finer than any step measured: "
                           rf"the maximum is {MAX_HZ:g} Hz .*the range is {MIN_HZ:g} to "
                           rf"{MAX_HZ:g} Hz"):
            check_rate(hz)


@pytest.mark.parametrize("command", [
    "online --arena table --states {states} --goal 12 --start-states 0 --decisions 4 "
    "--seeds 1 --workers 1 --no-plots --out {out}",
    "map --minutes 0.1 --out {out}",
    "collect --states {states} --transitions 4 --out {out} --no-progress"])
def test_every_physics_command_refuses_a_rate_above_the_maximum(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str) -> None:
    from simlab.cli import main

    states = _lattice().save(tmp_path / "s.json")
    argv = [*command.format(states=states, out=tmp_path / "o").split(), "--physics-hz", "1e9"]
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert "physics_hz" in err and f"the range is {MIN_HZ:g} to {MAX_HZ:g} Hz" in err, err
    assert not (tmp_path / "o").exists()


def test_the_minimum_is_the_coarsest_measured_row() -> None:
    """The settings table ends at the minimum: no rate below it has measured settings."""
    assert SETTINGS[-1][0] == MIN_HZ <= DEFAULT_HZ


@pytest.mark.parametrize("hz", [MIN_HZ, DEFAULT_HZ, 200.0])
def test_scans_and_control_ticks_fall_on_whole_steps(hz: float) -> None:
    """The LIDAR's 0.2 s and the drive's 0.1 s hold ticks fall on whole physics steps at
    the rates the step-size benchmark measured: the scans keep their times."""
    p = PrimitiveParams()
    for period in (0.2, 1 / p.hold_hz):
        assert period * hz == pytest.approx(round(period * hz), abs=1e-9)
    stamps: list[float] = []
    with World("table", physics_hz=hz) as world:
        res = execute_primitive(world, 8, np.random.default_rng(0),
                                on_scan=lambda scan, _odom: stamps.append(scan.stamp))
    assert len(stamps) == int(res.duration / 0.2 + 1e-9)
    np.testing.assert_allclose(stamps, 0.2 * np.arange(1, len(stamps) + 1), rtol=0, atol=1e-9)


def test_each_rate_takes_the_settings_of_its_row() -> None:
    rates = [r for r, _, _ in SETTINGS]
    its = [i for _, i, _ in SETTINGS]
    assert rates == sorted(rates, reverse=True) and its == sorted(its)  # coarser, more
    for r, i, t in SETTINGS:
        assert (settings_for(r).solver_iterations, settings_for(r).contact_threshold) == (i, t)
        assert settings_for(r + 1).solver_iterations <= i
    # 200 Hz is exactly the physics every dataset had before the rate was recorded
    assert settings_for(200.0).to_json() == {"hz": 200.0, "solver_iterations": 5,
                                             "contact_threshold": None}
    with World("table") as w:
        assert w.physics_hz == DEFAULT_HZ and w.settings == settings_for(DEFAULT_HZ)
    with World("table", physics_hz=200.0) as w:
        assert (w.dt, w.solver_iterations) == (1 / 200, 5)
        assert w.settings.contact_threshold is None  # Bullet's contacts, untouched


def test_a_contact_threshold_leaves_separated_points_out_of_the_solver() -> None:
    """A separated manifold point (a wheel's contact of the step before, lifted off the
    floor) takes no impulse: leaving it out changes the primitive by far less than the
    step's own error (mm)."""
    ends = []
    for threshold in (0.0, math.inf):
        with World("table", physics_hz=60.0, solver_iterations=20,
                   contact_threshold=threshold) as w:
            ends.append(execute_primitive(w, 9, np.random.default_rng(0)).pose_after)
    assert np.hypot(*(ends[0][:2] - ends[1][:2])) < 0.005


def _lattice() -> Discretizer:
    g = np.linspace(-0.6, 0.6, 5)
    return Discretizer(centres=np.array([(x, y) for y in g[::-1] for x in g]))


def test_a_dataset_records_its_rate_and_refuses_a_resume_at_another(tmp_path: Path) -> None:
    from simlab.data.collect import collect
    from simlab.data.manifest import physics_rate, read_manifest

    res = collect("table", _lattice(), out=tmp_path / "d", transitions=6, seed=1, workers=1,
                  part_size=3, progress=False)
    manifest = read_manifest(tmp_path / "d")
    assert manifest["parameters"]["physics"] == settings_for(DEFAULT_HZ).to_json()
    assert physics_rate(manifest) == res.physics_hz == DEFAULT_HZ
    other = 200.0 if DEFAULT_HZ != 200.0 else MIN_HZ
    with pytest.raises(ConfigError, match=r"parameters\.physics\.hz: cannot resume"):
        collect("table", _lattice(), out=tmp_path / "d", transitions=6, seed=1, workers=1,
                part_size=3, progress=False, resume=True, physics_hz=other)
    # a manifest from before the record stepped at 200 Hz; a kinematic walk has no rate
    del manifest["parameters"]["physics"]
    assert physics_rate(manifest) == RECORDLESS_HZ == 200.0
    assert physics_rate({**manifest, "simulator": "kinematic"}) is None
    with pytest.raises(ConfigError, match="physics_hz: the kinematic simulator"):
        collect("table", _lattice(), out=tmp_path / "k", transitions=6, simulator="kinematic",
                physics_hz=DEFAULT_HZ, progress=False)


def test_the_commands_refuse_a_coarse_rate_and_a_dataset_at_another_says_so(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from simlab.cli import main

    states = _lattice().save(tmp_path / "s.json")
    code = main(["collect", "--states", str(states), "--out", str(tmp_path / "x"),
                 "--transitions", "4", "--physics-hz", f"{MIN_HZ / 2:g}", "--no-progress"])
    assert code == 2 and f"the range is {MIN_HZ:g} to {MAX_HZ:g} Hz" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()
    other = 200.0 if DEFAULT_HZ != 200.0 else MIN_HZ
    assert main(["collect", "--states", str(states), "--out", str(tmp_path / "y"),
                 "--transitions", "2", "--physics-hz", f"{other:g}", "--no-progress"]) == 0
    assert f"physics stepped at {other:g} Hz" in capsys.readouterr().out
    from simlab.envs.table_arena import TableArenaEnv
    from simlab.orchestration.pipeline import PipelineConfig
    from simlab.physics.drive import drive

    with pytest.raises(ConfigError, match="physics_hz"):
        drive("table", 1, 0, physics_hz=MIN_HZ / 2, progress=False)
    with pytest.raises(ConfigError, match="physics_hz"):
        PipelineConfig(out=tmp_path / "p", physics_hz=MIN_HZ / 2).physics_settings()
    with pytest.raises(ConfigError, match="physics_hz"):
        TableArenaEnv(physics_hz=MIN_HZ / 2)


def test_the_pipeline_keys_its_physics_stages_on_the_rate(tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """The map, the walk and the replay are cached per rate (the stages without physics
    follow through their parents' keys)."""
    import hashlib
    import json

    from simlab.orchestration.stages import PhysicsChain, PhysicsSettings, Stage

    keys: dict[tuple[float, str], dict] = {}

    def cached_stage(self, stage, key, build):
        keys[(self.s.physics_hz, stage)] = key
        digest = hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:16]
        return Stage(tmp_path / digest, digest, {}, False, 0.0)

    monkeypatch.setattr(PhysicsChain, "cached_stage", cached_stage)
    other = 200.0 if DEFAULT_HZ != 200.0 else MIN_HZ
    for hz in (DEFAULT_HZ, other):
        PhysicsChain(tmp_path, PhysicsSettings.create(physics_hz=hz), 0).replay(0)
    for stage in ("map", "dataset", "replay"):
        assert keys[(DEFAULT_HZ, stage)]["physics_hz"] == DEFAULT_HZ
        assert keys[(other, stage)]["physics_hz"] == other
    assert keys[(DEFAULT_HZ, "mdp")] != keys[(other, "mdp")]  # through the dataset's key


def test_a_replay_steps_at_its_datasets_rate() -> None:
    from simlab.replay.inputs import ModelInputs, physics_rate_for

    model = ModelInputs(T=np.zeros((1, 16, 1)), source=None,
                        dataset_seconds_per_transition=None, dataset="d", physics_hz=200.0)
    assert physics_rate_for(model, None) == (200.0, "dataset")
    assert physics_rate_for(model, 200) == (200.0, "given")
    hz, source = physics_rate_for(model, MIN_HZ)
    assert hz == MIN_HZ and "the dataset stepped at 200 Hz" in source
    assert physics_rate_for(None, None) == (DEFAULT_HZ, "default")
    with pytest.raises(ConfigError, match=f"minimum is {MIN_HZ:g} Hz"):
        physics_rate_for(model, MIN_HZ - 1)
