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


# ---- the options as DriveConfig: --config FILE, --help, the Python function

def _drive_config(argv):
    import argparse

    from simlab.cli.drive import add_arguments
    from simlab.physics.drive import DriveConfig

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    return DriveConfig.from_args(parser.parse_args(argv)), parser.format_help()


def test_drive_config_file_and_the_command_line_wins(tmp_path, capsys):
    toml = tmp_path / "drive.toml"
    toml.write_text('steps = 5\nseed = 4\nprogress = false\ndrive-time = 0.3\n')
    cfg, text = _drive_config(["--config", str(toml), "--steps", "2"])
    assert (cfg.steps, cfg.seed, cfg.progress, cfg.arena) == (2, 4, False, "table")
    assert cfg.resolved_params() == PrimitiveParams(drive_time=0.3)
    assert "(default 100)" in text and "(default table)" in text and "--max-drive-time" in text
    # the run prints what the same options give from Python
    assert main(["drive", "--config", str(toml), "--steps", "2"]) == 0
    s = drive("table", 2, 4, drive_time=0.3, progress=False)
    assert f"2 primitives, {s.distance:.2f} m driven" in capsys.readouterr().out


def test_drive_config_unknown_key_names_file_and_key(tmp_path, capsys):
    toml = tmp_path / "drive.toml"
    toml.write_text("stepz = 3\n")
    assert main(["drive", "--config", str(toml)]) == 2
    err = capsys.readouterr().err
    assert str(toml) in err and "'stepz'" in err and err.count("\n") == 1


def test_drive_takes_the_config_or_its_fields():
    from simlab.base.errors import ConfigError
    from simlab.physics.drive import DriveConfig

    by_config = drive(DriveConfig(steps=3, seed=2, slow_speed=0.15, progress=False))
    by_fields = drive("table", 3, 2, slow_speed=0.15, progress=False)
    by_params = drive("table", 3, 2, params=PrimitiveParams(slow_speed=0.15), progress=False)
    np.testing.assert_array_equal(by_config.trail, by_fields.trail)
    np.testing.assert_array_equal(by_config.trail, by_params.trail)
    assert not np.array_equal(by_config.trail, drive("table", 3, 2, progress=False).trail)
    with pytest.raises(ConfigError, match="once"):  # both ways of giving the parameters
        DriveConfig(params=PrimitiveParams(), slow_speed=0.1)
    with pytest.raises(ValueError, match="steps"):
        drive("table", -1)
