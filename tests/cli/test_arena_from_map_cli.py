"""``simlab arena-from-map``: the map's flip recorded in the arena, a start at a state's
centre, names that TOML must escape, errors said of the user's inputs."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from discretize.gridmap import OccupancyMap
from discretize.mapio import write_map
from discretize.voronoi import Discretizer
from simlab.cli import main
from simlab.physics.arena import load_arena
from simlab.physics.map_arena import toml_string


@pytest.fixture()
def lopsided(tmp_path: Path) -> Path:
    """A 2 m x 2 m room (0.05 m pixels, origin (-1, -1)) with one wall block in its top
    half only (image rows 8-11 of 40, x -0.5..0.5 m): flipping the image moves it down."""
    occ = np.zeros((40, 40), dtype=np.int8)
    occ[[0, -1], :] = 100
    occ[:, [0, -1]] = 100
    occ[8:12, 10:30] = 100
    write_map(tmp_path / "room.yaml", OccupancyMap(occ, 0.05, (-1.0, -1.0, 0.0)))
    return tmp_path / "room.yaml"


def _inner_boxes_y(arena_toml: Path) -> list[float]:
    walls = load_arena(arena_toml).map_walls
    return [(b[1] + b[3]) / 2 for b in walls.boxes if b[2] - b[0] < 1.5 and b[3] - b[1] < 1.5
            and abs((b[0] + b[2]) / 2) < 0.6 and abs((b[1] + b[3]) / 2) < 0.8]


def test_flip_y_is_recorded_and_moves_the_walls(lopsided: Path, tmp_path: Path) -> None:
    assert main(["arena-from-map", str(lopsided), "--out", str(tmp_path / "a.toml")]) == 0
    assert main(["arena-from-map", str(lopsided), "--out", str(tmp_path / "f.toml"),
                 "--flip-y"]) == 0
    assert "flip_y" not in tomllib.loads((tmp_path / "a.toml").read_text())["map"]
    assert tomllib.loads((tmp_path / "f.toml").read_text())["map"]["flip_y"] is True
    plain, flipped = _inner_boxes_y(tmp_path / "a.toml"), _inner_boxes_y(tmp_path / "f.toml")
    # rows 8-11 of 40 from the top: y in [0.4, 0.6] m; flipped: [-0.6, -0.4] m
    assert plain and all(0.4 <= y <= 0.6 for y in plain)
    assert flipped and all(-0.6 <= y <= -0.4 for y in flipped)


def test_start_state_is_that_centre_facing_up(lopsided: Path, tmp_path: Path) -> None:
    states = Discretizer(centres=np.array([[-0.5, -0.5], [0.5, -0.5], [0.0, 0.0]])).save(
        tmp_path / "s.json")
    assert main(["arena-from-map", str(lopsided), "--out", str(tmp_path / "a.toml"),
                 "--states", str(states), "--start-state", "1"]) == 0
    pose = load_arena(tmp_path / "a.toml").start
    assert tuple(pose[:2]) == pytest.approx((0.5, -0.5))
    assert pose[2] == pytest.approx(np.pi / 2)


def test_a_name_with_quotes_and_control_characters_is_a_valid_toml_string(
        lopsided: Path, tmp_path: Path) -> None:
    name = 'the "big" lab\\ \t\x7f é'
    assert main(["arena-from-map", str(lopsided), "--out", str(tmp_path / "a.toml"),
                 "--name", name]) == 0
    assert load_arena(tmp_path / "a.toml").name == name
    for text in ('"', "\\", "\x00\n", "plain"):
        assert tomllib.loads(f"x = {toml_string(text)}")["x"] == text


def test_errors_name_the_users_inputs_not_the_check_file(lopsided: Path, tmp_path: Path,
                                                          capsys) -> None:
    far = Discretizer(centres=np.array([[0.0, 0.0], [3.0, 3.0]])).save(tmp_path / "far.json")
    code = main(["arena-from-map", str(lopsided), "--out", str(tmp_path / "a.toml"),
                 "--states", str(far)])
    err = capsys.readouterr().err
    assert code == 2 and "far.json" in err and "centre 1" in err, err
    assert ".check" not in err and not list(tmp_path.glob(".*"))
    code = main(["arena-from-map", str(lopsided), "--out", str(tmp_path / "a.toml"),
                 "--start", "5,5,0"])
    err = capsys.readouterr().err
    assert code == 2 and "outside the map" in err and "--start" in err, err
