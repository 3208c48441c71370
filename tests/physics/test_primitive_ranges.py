"""Primitive settings a TurtleBot3 cannot have are refused where the record is built.

``turn_rate = 1e-9`` in a primitives file never finished the first turn, ``localization_hz
= 1e-9`` never read a new state; ``stop_delay``, ``min_drive`` and ``max_drive_time``
took any size. Each field has the range of a TurtleBot3 (v_max 0.22 m/s, w_max 2.84
rad/s), wide enough for every value the calibration searches."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import pytest

from simlab.base.errors import ConfigError
from simlab.physics.motion import PrimitiveParams


@pytest.mark.parametrize(("field", "value", "range_text"), [
    ("turn_rate", 1e-9, "0.05 to 2.84 rad/s (or 0)"),
    ("stop_delay", 1e9, "0 to 5 s"),
    ("localization_hz", 1e-9, "0.2 to 100 Hz (or 0)"),
    ("min_drive", 100, "0 to 2 m"),
    ("max_drive_time", 1e9, "0 to 60 s"),
    ("turn_rate", 30.0, "0.05 to 2.84 rad/s"),
    ("fast_speed", 2.2, "0 to 0.3 m/s"),
])
def test_a_primitives_file_with_a_value_out_of_range_is_refused_naming_field_and_range(
        tmp_path: Path, field: str, value: float, range_text: str) -> None:
    path = tmp_path / "primitives.toml"
    path.write_text(f"[primitives]\nmode = \"until_state_change\"\n{field} = {value!r}\n")
    with pytest.raises(ConfigError) as err:
        PrimitiveParams.from_toml(path)
    text = str(err.value)
    assert "primitives.toml" in text and f"primitives.{field}" in text, text
    assert "outside the range a TurtleBot3 can have" in text and range_text in text, text
    assert f"give {field} from" in text, text


def test_zero_keeps_its_meaning_where_it_has_one() -> None:
    """0 is "the robot's w_max", "every control tick", "no delay", "no minimum"."""
    p = PrimitiveParams(turn_rate=0.0, localization_hz=0.0, stop_delay=0.0, min_drive=0.0)
    assert (p.turn_rate, p.localization_hz, p.stop_delay, p.min_drive) == (0, 0, 0, 0)
    assert PrimitiveParams(turn_rate=2.84, localization_hz=100.0, stop_delay=5.0,
                           min_drive=2.0, max_drive_time=60.0).max_drive_time == 60.0


@pytest.mark.parametrize("cell_size", [None, 0.15, 0.35, 0.5])
def test_every_corner_of_the_calibrations_default_search_is_a_valid_robot(
        cell_size: float | None) -> None:
    """The bounds contain the calibration's default search for cells up to 0.5 m (two
    cells at 0.10 m/s: max_drive_time 10 s), at every corner of it, for both modes."""
    from simlab.calibration.space import default_space

    for mode, prims in itertools.product((None, "until_state_change"),
                                         (range(16), range(8, 16))):
        space = default_space(list(prims), cell_size=cell_size, mode=mode,
                              speed_fields=("fast_speed",))
        numeric = [s for s in space.specs if not s.categorical]
        for corner in itertools.product(*[(s.low, s.high) for s in numeric]):
            values = {s.name: v for s, v in zip(numeric, corner, strict=True)}
            if values.get("wall_slide", 0) + values.get("wall_back", 0) > 1:
                continue
            PrimitiveParams(mode="until_state_change", **values)
    assert math.isclose(default_space(list(range(8)), cell_size=0.5).specs[2].high, 10.0)
