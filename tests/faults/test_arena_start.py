"""An arena whose start puts the robot off the floor, in an obstacle or with its body through
a box or a wall is refused at load, naming the file, the key and what is wrong."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.faults.conftest import assert_refused, run_cli


def _arena(work: Path, start: str, clearance: str = "") -> Path:
    path = work / "a.toml"
    path.write_text('name = "a"\n[floor]\nsize = [1.5, 1.5]\n[walls]\nheight = 0.25\n'
                    'thickness = 0.05\n'
                    f'[start]\npose = [{start}, 90.0]\n{clearance}'
                    '[[obstacles]]\nkind = "box"\ncenter = [0.3, 0.3]\nsize = [0.2, 0.2]\n'
                    'height = 0.3\n[[goals]]\nname = "G"\ncenter = [-0.4, -0.4]\n'
                    'radius = 0.1\n')
    return path


@pytest.mark.parametrize(("start", "needles"), [
    ("2.0, 0.0", ("start.pose", "outside the floor")),
    ("0.3, 0.3", ("start.pose", "inside an obstacle")),
    ("0.3, 0.16", ("start.pose", "would overlap a wall or obstacle")),  # body in the box
    ("0.7, 0.0", ("start.pose", "would overlap a wall or obstacle")),   # body in the wall
])
def test_a_start_that_puts_the_robot_in_a_box_or_off_the_floor_is_named(
        work: Path, capsys, start: str, needles: tuple[str, ...]) -> None:
    arena = _arena(work, start)
    res = run_cli(f"drive --arena {arena} --steps 2".split(), capsys)
    assert_refused(res, "a.toml", *needles)
