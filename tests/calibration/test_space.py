"""Parameter spaces: scales, validation, TOML."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.calibration.space import (
    ParameterSpace,
    ParamSpec,
    default_space,
    load_space,
)
from simlab.physics.motion import PrimitiveParams


def test_log_and_linear_scales_round_trip() -> None:
    log = ParamSpec("drive_time", 0.1, 10.0, "log")
    assert log.value(0.5) == pytest.approx(1.0)
    lin = ParamSpec("detector_margin", 0.0, 0.2)
    assert lin.value(0.25) == pytest.approx(0.05)
    for spec in (log, lin):
        for u in (0.0, 0.3, 1.0):
            assert spec.unit(spec.value(u)) == pytest.approx(u)
        assert spec.value(2.0) == spec.high  # clipped


def test_apply_replaces_only_the_searched_fields() -> None:
    space = ParameterSpace((ParamSpec("drive_time", 0.2, 2.0, "log"),
                            ParamSpec("detector_margin", 0.0, 0.1)))
    p = space.apply(PrimitiveParams(), np.array([1.0, 0.5]))
    assert (p.drive_time, p.detector_margin) == (pytest.approx(2.0), pytest.approx(0.05))
    assert p.slow_speed == PrimitiveParams().slow_speed


@pytest.mark.parametrize("kwargs, match", [
    (dict(low=1.0, high=1.0), "must be <"),
    (dict(low=0.0, high=1.0, scale="log"), "low > 0"),
    (dict(low=0.0, high=1.0, scale="cubic"), "scale"),
    (dict(low="a", high=1.0), "finite number"),
])
def test_bad_specs_name_the_field(kwargs: dict, match: str) -> None:
    with pytest.raises(ConfigError, match=match) as info:
        ParamSpec("drive_time", **kwargs)
    assert "parameters.drive_time" in str(info.value)


def test_unknown_field_is_refused_with_the_list() -> None:
    space = ParameterSpace((ParamSpec("warp_speed", 0.1, 1.0),))
    with pytest.raises(ConfigError, match=r"no field 'warp_speed'.*drive_time"):
        space.check_fields(PrimitiveParams())


def test_load_space_reads_toml_and_names_the_file(tmp_path: Path) -> None:
    good = tmp_path / "space.toml"
    good.write_text('[parameters.drive_time]\nlow = 0.3\nhigh = 1.5\nscale = "log"\n'
                    "[parameters.detector_margin]\nlow = 0.0\nhigh = 0.1\n")
    space = load_space(good)
    assert space.names == ("drive_time", "detector_margin")
    assert space.specs[0].scale == "log"
    bad = tmp_path / "bad.toml"
    bad.write_text("[parameters.drive_time]\nlow = 0.3\n")
    with pytest.raises(ConfigError, match=r"bad\.toml.*parameters\.drive_time"):
        load_space(bad)
    with pytest.raises(ConfigError, match="not found"):
        load_space(tmp_path / "missing.toml")


def test_default_physics_space_holds_the_mode_and_sizes_its_ranges_from_the_cells() -> None:
    phys = default_space(np.arange(16), "physics")
    assert phys.names == ("mode", "drive_time", "max_drive_time", "detector_margin",
                          "pose_noise_xy", "wheel_noise")
    assert phys.specs[0].choices == ("fixed", "until_state_change")
    # 16 actions: the speeds are the thesis robot's published ones, not searched
    assert not {"slow_speed", "fast_speed"} & set(phys.names)
    # an 8-action fast robot on 0.7 m cells: its one speed is searched, and the drive
    # times reach two cells at the slowest speed of the range (0.22 m/s)
    fast8 = default_space(np.arange(8, 16), "physics", cell_size=0.7,
                          speed_fields=("fast_speed",))
    specs = {p.name: p for p in fast8.specs}
    assert "fast_speed" in specs
    assert specs["max_drive_time"].high == pytest.approx(2 * 0.7 / 0.22)
    assert specs["drive_time"].high == pytest.approx(2 * 0.7 / 0.22)
    assert specs["pose_noise_xy"].high == pytest.approx(0.25 * 0.7)
    kin = default_space(np.arange(8), "kinematic")
    assert kin.names == ("drive_time", "distance_noise", "heading_noise")


def test_a_categorical_field_round_trips_and_reads_from_toml(tmp_path: Path) -> None:
    spec = ParamSpec("mode", choices=("fixed", "until_state_change"))
    assert spec.value(0.0) == "fixed" and spec.value(0.49) == "fixed"
    assert spec.value(0.5) == "until_state_change" and spec.value(1.0) == "until_state_change"
    assert spec.value(spec.unit("until_state_change")) == "until_state_change"
    path = tmp_path / "space.toml"
    path.write_text('[parameters.mode]\nchoices = ["fixed", "until_state_change"]\n'
                    "[parameters.max_drive_time]\nlow = 1.0\nhigh = 4.0\n")
    space = load_space(path)
    p = space.apply(PrimitiveParams(), np.array([0.9, 0.5]))
    assert p.mode == "until_state_change" and p.max_drive_time == pytest.approx(2.5)
    with pytest.raises(ConfigError, match=r"parameters\.mode\.choices"):
        ParamSpec("mode", choices=("fixed",))
    with pytest.raises(ConfigError, match="not a number"):
        ParameterSpace((ParamSpec("mode", 0.0, 1.0),)).check_fields(PrimitiveParams())


def test_the_space_of_a_robot_that_drives_until_its_state_changes() -> None:
    """The mode is the signature's and drive_time only sizes the detector's corridor with
    its margin: neither is searched; the fields of such a robot's moves are, each range a
    value the record takes (its corners too: wall_slide + wall_back <= 1)."""
    from simlab.physics.motion import PrimitiveParams

    space = default_space(np.arange(8, 16), "physics", cell_size=0.7,
                          speed_fields=("fast_speed",), mode="until_state_change")
    assert space.names == ("max_drive_time", "detector_margin", "pose_noise_xy",
                           "pose_noise_persistence", "localization_hz", "wall_slide",
                           "wall_back", "min_drive", "fast_speed")
    specs = {p.name: p for p in space.specs}
    assert specs["min_drive"].high == pytest.approx(0.35)
    assert specs["wall_slide"].high + specs["wall_back"].high <= 1.0
    space.check_fields(PrimitiveParams(mode="until_state_change"))


def test_a_space_whose_corner_the_record_refuses_fails_at_load(tmp_path: Path) -> None:
    from simlab.physics.motion import PrimitiveParams

    path = tmp_path / "space.toml"
    path.write_text("[parameters.wall_slide]\nlow = 0.0\nhigh = 0.8\n"
                    "[parameters.wall_back]\nlow = 0.0\nhigh = 0.5\n")
    with pytest.raises(ConfigError, match=r"parameters: 'highs'.*wall_slide \+ wall_back"):
        load_space(path).check_fields(PrimitiveParams())
    path.write_text('[parameters.mode]\nchoices = ["fixed", "teleport"]\n')
    with pytest.raises(ConfigError, match=r"parameters\.mode: 'teleport'"):
        load_space(path).check_fields(PrimitiveParams())
