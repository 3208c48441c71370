"""``simlab discretize`` end to end: outputs, exit code 2 on bad input, nothing half-written."""

from __future__ import annotations

import json

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from discretize.mapio import read_map, write_map
from discretize.voronoi import Discretizer
from simlab.base.errors import ConfigError
from simlab.cli import main


@pytest.fixture
def map_yaml(tmp_path, make_room):
    # A coarse (2 cm) room keeps these runs fast.
    path, _ = write_map(tmp_path / "maps" / "map.yaml", make_room(side_px=75, wall_px=3, margin_px=10, resolution=0.02))
    return path


def _outputs(tmp_path):
    return sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*") if p.is_file())


def test_discretize_writes_states_and_figure(tmp_path, map_yaml, capsys):
    out = tmp_path / "states" / "table.json"
    png = tmp_path / "states" / "table.png"
    code = main(["discretize", "--map", str(map_yaml), "--states", "12", "--out", str(out),
                 "--png", str(png), "--no-progress"])
    assert code == 0
    disc = Discretizer.load(out)
    assert disc.n_states == 12
    assert png.read_bytes()[:4] == b"\x89PNG"
    printed = capsys.readouterr().out
    assert "12 states" in printed and disc.content_hash()[:16] in printed
    # Same inputs, same file content.
    out2 = tmp_path / "again.json"
    assert main(["discretize", "--map", str(map_yaml), "--states", "12", "--out", str(out2),
                 "--no-progress"]) == 0
    assert json.loads(out2.read_text())["centres"] == json.loads(out.read_text())["centres"]


def test_default_is_41_states(tmp_path, map_yaml):
    out = tmp_path / "s.json"
    assert main(["discretize", "--map", str(map_yaml), "--out", str(out), "--no-progress"]) == 0
    assert Discretizer.load(out).n_states == 41


def test_dataset_colours_the_figure(tmp_path, map_yaml, capsys):
    (tmp_path / "ds").mkdir()
    pq.write_table(pa.table({"s": np.array([0, 0, 3, 5], np.int64)}), tmp_path / "ds" / "p0.parquet")
    code = main(["discretize", "--map", str(map_yaml), "--states", "6", "--out", str(tmp_path / "s.json"),
                 "--png", str(tmp_path / "s.png"), "--dataset", str(tmp_path / "ds"), "--no-progress"])
    assert code == 0
    assert "visits: 4 total, 3 states unvisited" in capsys.readouterr().out


def test_centres_file(tmp_path, map_yaml):
    (tmp_path / "c.txt").write_text("0.2 0.2\n-0.2 -0.2\n")
    out = tmp_path / "s.json"
    assert main(["discretize", "--map", str(map_yaml), "--centres", str(tmp_path / "c.txt"),
                 "--out", str(out)]) == 0
    np.testing.assert_array_equal(Discretizer.load(out).centres, [[0.2, 0.2], [-0.2, -0.2]])


def _bad_yaml(tmp_path, map_yaml, text):
    path = map_yaml.parent / "bad.yaml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("case", "message"),
    [
        ("malformed", "malformed YAML"),
        ("missing_image", "not found"),
        ("thresholds", "must be smaller"),
        ("truncated", "image size inconsistent"),
        ("empty_free", "no free space left"),
        ("too_many", "states requested"),
        ("bad_centres", "line 2"),
        ("states_and_radius", "not allowed with argument"),
    ],
)
def test_bad_input_exit_2_and_no_output(tmp_path, map_yaml, capsys, case, message):
    base = map_yaml.read_text()
    args = ["--states", "5"]
    the_map = map_yaml
    if case == "malformed":
        the_map = _bad_yaml(tmp_path, map_yaml, "image: map.pgm\norigin: [0, 0\n")
    elif case == "missing_image":
        the_map = _bad_yaml(tmp_path, map_yaml, base.replace("image: map.pgm", "image: gone.pgm"))
    elif case == "thresholds":
        the_map = _bad_yaml(tmp_path, map_yaml, base.replace("free_thresh: 0.196", "free_thresh: 0.9"))
    elif case == "truncated":
        data = (map_yaml.parent / "map.pgm").read_bytes()
        (map_yaml.parent / "cut.pgm").write_bytes(data[:-10])
        the_map = _bad_yaml(tmp_path, map_yaml, base.replace("image: map.pgm", "image: cut.pgm"))
    elif case == "empty_free":
        args = ["--robot-radius", "1.0"]
    elif case == "too_many":
        args = ["--states", "100000"]
    elif case == "bad_centres":
        (tmp_path / "c.txt").write_text("0 0\n1 2 3\n")
        args = ["--centres", str(tmp_path / "c.txt")]
    elif case == "states_and_radius":
        args = ["--states", "5", "--radius", "0.1"]
    before = _outputs(tmp_path)
    out = tmp_path / "out" / "s.json"
    argv = ["discretize", "--map", str(the_map), "--out", str(out), "--png", str(tmp_path / "out" / "s.png"),
            "--no-progress", *args]
    if case == "states_and_radius":
        with pytest.raises(SystemExit) as info:
            main(argv)
        assert info.value.code == 2
    else:
        assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err
    if case != "states_and_radius":
        assert err.startswith("simlab discretize: error:") and err.count("\n") == 1
    assert _outputs(tmp_path) == before


def test_existing_output_kept_without_overwrite(tmp_path, map_yaml, capsys):
    out = tmp_path / "s.json"
    out.write_text("precious")
    argv = ["discretize", "--map", str(map_yaml), "--states", "4", "--out", str(out), "--no-progress"]
    assert main(argv) == 2
    assert "already exists" in capsys.readouterr().err
    assert out.read_text() == "precious"
    assert main([*argv, "--overwrite"]) == 0
    assert Discretizer.load(out).n_states == 4


# ---- the options as DiscretizeConfig: --config FILE, --help, the Python function

def test_config_file_and_the_command_line_wins(tmp_path, map_yaml, capsys):
    toml = tmp_path / "d.toml"
    toml.write_text(f'map = "{map_yaml}"\nout = "{tmp_path / "s.json"}"\nstates = 7\n'
                    "robot-radius = 0.05\nprogress = false\n")
    assert main(["discretize", "--config", str(toml), "--states", "6"]) == 0
    assert "6 states" in capsys.readouterr().out
    disc = Discretizer.load(tmp_path / "s.json")
    assert disc.n_states == 6
    direct = Discretizer.from_map(read_map(map_yaml), 6, robot_radius=0.05)  # file's radius
    np.testing.assert_array_equal(disc.centres, direct.centres)
    # one way to get the centres, across the file and the command line too
    assert main(["discretize", "--config", str(toml), "--radius", "0.1", "--overwrite"]) == 2
    assert "not both" in capsys.readouterr().err


def test_help_shows_defaults_and_unknown_key_is_refused(tmp_path, map_yaml, capsys):
    with pytest.raises(SystemExit):
        main(["discretize", "--help"])
    text = capsys.readouterr().out
    assert "(default 0.113)" in text and "--all-components" in text and "--config FILE" in text
    toml = tmp_path / "d.toml"
    toml.write_text("robot_radious = 0.05\n")
    assert main(["discretize", "--config", str(toml), "--map", str(map_yaml),
                 "--out", str(tmp_path / "s.json")]) == 2
    err = capsys.readouterr().err
    assert str(toml) in err and "robot_radious" in err and err.count("\n") == 1
    assert not (tmp_path / "s.json").exists()


def test_command_takes_the_config_or_its_fields(tmp_path, map_yaml):
    from discretize.command import DiscretizeConfig, discretize_command

    a = discretize_command(DiscretizeConfig(map=map_yaml, out=tmp_path / "a.json", states=5,
                                            all_components=True, progress=False))
    b = discretize_command(map_yaml, tmp_path / "b.json", 5, all_components=True,
                           progress=False)
    c = discretize_command(map_yaml, tmp_path / "c.json", states=5, all_components=True,
                           progress=False)
    assert (tmp_path / "a.json").read_bytes() == (tmp_path / "b.json").read_bytes() \
        == (tmp_path / "c.json").read_bytes()
    assert a.discretizer.n_states == b.discretizer.n_states == c.discretizer.n_states == 5
    with pytest.raises(ConfigError, match="give --png too"):
        DiscretizeConfig(map=map_yaml, out=tmp_path / "d.json", dataset=tmp_path)
