"""Centre files with ids, map checks that list every bad centre and spot a flipped image,
and figures cropped to the known part of the map."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from discretize.gridmap import FREE, OCCUPIED, UNKNOWN, OccupancyMap
from discretize.mapcheck import check_points
from discretize.mapio import read_map, write_map
from discretize.plot import draw_states, known_bounds
from discretize.voronoi import Discretizer, load_centres_txt, load_states, read_centres_table
from simlab.base.errors import ConfigError
from simlab.cli import main

XY = np.array([[0.5, 0.5], [1.5, 0.5], [2.5, 0.5], [0.5, 1.5], [1.5, 1.5]])


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_id_x_y_theta_file_is_numbered_by_ids(tmp_path: Path) -> None:
    order = [3, 0, 4, 1, 2]
    body = "".join(f"{i} {XY[i, 0]} {XY[i, 1]} {0.1 * i}\n" for i in order)
    for text in (body, "# ISIR export\nid x y theta\n" + body, "id,x,y,yaw\n" +
                 body.replace(" ", ",")):
        centres, theta = read_centres_table(_write(tmp_path / "c.txt", text))
        np.testing.assert_array_equal(centres, XY)
        np.testing.assert_allclose(theta, 0.1 * np.arange(5))
    # header in another order
    text = "x y id theta\n" + "".join(f"{XY[i, 0]} {XY[i, 1]} {i} 0\n" for i in order)
    np.testing.assert_array_equal(load_centres_txt(_write(tmp_path / "d.txt", text)), XY)


def test_x_y_file_keeps_file_order(tmp_path: Path) -> None:
    text = "x y\n" + "".join(f"{x} {y}\n" for x, y in XY[::-1])
    centres, theta = read_centres_table(_write(tmp_path / "c.txt", text))
    np.testing.assert_array_equal(centres, XY[::-1])
    assert theta is None


@pytest.mark.parametrize(("text", "message"), [
    ("0 0 0 0\n0 1 1 0\n", "line 2: id 0 appears twice"),
    ("0 0 0 0\n2 1 1 0\n", r"ids must be 0\.\.1, got 0\.\.2"),
    ("0 0 0 0\n1.5 1 1 0\n", "line 2: id 1.5 is not a whole number"),
    ("0 0 0\n", r"line 1: expected 'x y' or 'id x y theta' \(2 or 4 numbers\)"),
    ("0 0 0 0\n1 1 1\n", "line 2: expected 4 numbers 'id x y theta'"),
    ("id x z theta\n", "line 1: header 'id x z theta'"),
    ("# nothing\n", "no centres"),
])
def test_bad_centre_files_name_file_and_line(tmp_path: Path, text: str, message: str) -> None:
    path = _write(tmp_path / "c.txt", text)
    with pytest.raises(ConfigError, match=message) as exc:
        read_centres_table(path)
    assert str(path) in str(exc.value)


def test_load_states_reads_json_and_text(tmp_path: Path) -> None:
    disc = Discretizer(centres=XY)
    disc.save(tmp_path / "s.json")
    (tmp_path / "noext").write_text(json.dumps(disc.to_json()))
    _write(tmp_path / "c.txt", "".join(f"{i} {x} {y} 0\n" for i, (x, y) in enumerate(XY)))
    for name in ("s.json", "noext", "c.txt"):
        assert load_states(tmp_path / name).content_hash() == disc.content_hash()


def _lab() -> OccupancyMap:
    """40 x 30 px at 0.1 m: free box in the top 10 rows (y 2..3 m), walls, unknown rest."""
    occ = np.full((30, 40), UNKNOWN, dtype=np.int8)
    occ[0:12, :] = OCCUPIED
    occ[1:11, 1:39] = FREE
    return OccupancyMap(occupancy=occ, resolution=0.1, origin=(0.0, 0.0, 0.0))


def test_every_bad_centre_is_listed() -> None:
    grid = _lab()
    xy = np.array([[1.0, 2.5], [0.05, 2.5], [1.0, 0.5], [2.0, 2.5], [9.0, 9.0]])
    check = check_points(grid, xy)
    assert check.status.tolist() == [0, 1, 2, 0, 3]
    text = check.message()
    assert text.startswith("3 of 5 centres are not on free pixels")
    for piece in ("centre 1 (0.05, 2.5) occupied", "centre 2 (1, 0.5) unknown",
                  "centre 4 (9, 9) outside the map"):
        assert piece in text
    assert "flip" not in text
    with pytest.raises(ConfigError) as exc:
        Discretizer.from_centres(xy, grid=grid, source="c.txt")
    assert "centre 1 " in str(exc.value) and "centre 4 " in str(exc.value)


def test_flipped_image_is_detected_and_flip_y_fixes_it(tmp_path: Path) -> None:
    true_map = _lab()
    # the real centres lie in the free box (y 2..3 m); the file holds the image upside down
    upside_down = OccupancyMap(occupancy=true_map.occupancy[::-1], resolution=0.1,
                               origin=(0.0, 0.0, 0.0))
    yaml = tmp_path / "map.yaml"
    write_map(yaml, upside_down)
    centres = np.array([[0.3 + 0.3 * k, 2.2 + 0.12 * (k % 5)] for k in range(12)])
    grid = read_map(yaml)
    check = check_points(grid, centres)
    assert check.bad.size == 12 and check.flip_suggested
    assert "12 of these 12 are free when the map image is flipped" in check.message()
    assert "--flip-y" in check.message()
    assert check_points(read_map(yaml, flip_y=True), centres).ok
    path = _write(tmp_path / "c.txt", "".join(f"{k} {x} {y} 0\n"
                                              for k, (x, y) in enumerate(centres)))
    base = ["discretize", "--map", str(yaml), "--centres", str(path), "--no-progress"]
    assert main([*base, "--out", str(tmp_path / "a.json")]) == 2
    assert not (tmp_path / "a.json").exists()
    assert main([*base, "--out", str(tmp_path / "b.json"), "--flip-y"]) == 0
    np.testing.assert_allclose(Discretizer.load(tmp_path / "b.json").centres, centres)


def test_cli_error_lists_all_and_suggests_flip(tmp_path: Path, capsys) -> None:
    yaml = tmp_path / "map.yaml"
    write_map(yaml, OccupancyMap(occupancy=_lab().occupancy[::-1], resolution=0.1))
    path = _write(tmp_path / "c.txt", "x y\n1 2.5\n2 2.5\n3 2.5\n")
    code = main(["discretize", "--map", str(yaml), "--centres", str(path), "--out",
                 str(tmp_path / "s.json"), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "centre 0 " in err and "centre 1 " in err and "centre 2 " in err and "--flip-y" in err


def test_figure_is_cropped_to_the_known_map() -> None:
    from matplotlib.figure import Figure

    grid = _lab()
    assert known_bounds(grid, margin_px=0) == pytest.approx((0.0, 4.0, 1.8, 3.0))
    disc = Discretizer(centres=np.array([[1.0, 2.5], [3.0, 2.5]]))
    ax = Figure().add_subplot(1, 1, 1)
    draw_states(ax, grid, disc, robot_radius=None)
    assert ax.get_xlim() == pytest.approx((-0.5, 4.5))
    assert ax.get_ylim() == pytest.approx((1.3, 3.5))
    ax = Figure().add_subplot(1, 1, 1)
    draw_states(ax, grid, disc, robot_radius=None, crop=False)
    assert ax.get_ylim()[0] == pytest.approx(0.0)
