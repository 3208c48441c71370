"""``simlab drive`` end to end through the CLI entry point."""

from __future__ import annotations

import subprocess
import sys

import cv2
import numpy as np
import pytest

from simlab.cli import main
from simlab.physics.drive import drive
from simlab.physics.motion import PrimitiveParams


def test_drive_function_summary():
    s = drive("table", steps=20, seed=3, progress=False)
    assert s.steps == 20 and s.trail.shape == (21, 3)
    path = np.hypot(*np.diff(s.trail[:, :2], axis=0).T).sum()
    assert s.distance == pytest.approx(path)
    assert 0 <= s.blocked <= 20
    assert s.sim_time == pytest.approx(s.stepped_time + 20 * PrimitiveParams().decision_latency)
    again = drive("table", steps=20, seed=3, progress=False)
    np.testing.assert_array_equal(s.trail, again.trail)


def test_drive_cli_writes_png_and_refuses_to_overwrite(tmp_path, capsys):
    png = tmp_path / "walk.png"
    assert main(["drive", "--steps", "8", "--seed", "1", "--png", str(png), "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "8 primitives" in out and "blocked" in out
    image = cv2.imread(str(png))
    assert image is not None and image.shape[0] > 300
    before = png.read_bytes()
    assert main(["drive", "--steps", "3", "--png", str(png), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "already exists" in err and err.count("\n") == 1
    assert png.read_bytes() == before
    assert not list(tmp_path.glob(".walk.png*"))  # no temporary left behind


def test_drive_cli_bad_input_exit_2(tmp_path, capsys):
    assert main(["drive", "--arena", "kitchen", "--no-progress"]) == 2
    assert "unknown arena name 'kitchen'" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "x"\n[floor]\nsize = [1.5, 1.5]\n')
    assert main(["drive", "--arena", str(bad), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "bad.toml" in err and "walls: missing table" in err


def test_console_script_help_lists_subcommands():
    out = subprocess.run([sys.executable, "-m", "simlab", "--help"], capture_output=True,
                         text=True, check=True).stdout
    assert "drive" in out
    out = subprocess.run([sys.executable, "-m", "simlab", "drive", "--help"], capture_output=True,
                         text=True, check=True).stdout
    assert "--steps" in out and "--png" in out
