"""The exploration run (physics -> occupancy map) and ``simlab map``."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from scipy import ndimage

from discretize.gridmap import OccupancyMap
from discretize.mapio import read_map
from discretize.occupancy import map_accuracy
from discretize.voronoi import Discretizer, eroded_free_mask
from simlab.cli import main
from simlab.orchestration.mapping import build_map, sensor_pose
from simlab.physics.arena import load_arena


@pytest.fixture(scope="module")
def table_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("maps") / "table"
    return build_map("table", minutes=3.0, seed=7, out=out, progress=False)


def test_map_of_the_table_matches_its_geometry(table_run):
    grid = read_map(table_run.yaml_path)
    assert grid.same_as(table_run.map)
    arena = load_arena("table")
    truth = arena.rasterize(grid.resolution, grid.origin[:2], grid.shape)
    # Independent check (numpy only), with the +-1 pixel band at the wall boundary:
    # the inner area's pixels farther than one pixel from a wall must be mapped free,
    # and the wall surface (wall pixels touching the inner area) must have an occupied
    # map pixel within one pixel.
    box = np.ones((3, 3), dtype=bool)
    inner = ~truth
    scored_free = inner & ~ndimage.binary_dilation(truth, box)
    free_ok = (grid.occupancy[scored_free] == 0).mean()
    surface = truth & ndimage.binary_dilation(inner, box)
    occ_near = ndimage.binary_dilation(grid.occupancy == 100, box)
    wall_seen = occ_near[surface].mean()
    observed_wall = truth & (grid.occupancy != -1)
    wall_ok = occ_near[observed_wall].mean()
    assert free_ok >= 0.95 and wall_seen >= 0.95 and wall_ok >= 0.95
    # The library's metric agrees with the independent one.
    acc = map_accuracy(grid, truth)
    assert acc.free_correct == pytest.approx(free_ok)
    assert acc.wall_coverage == pytest.approx(wall_seen)
    assert acc.wall_correct == pytest.approx(wall_ok)
    assert table_run.accuracy == acc
    # Nothing is mapped beyond the walls: beams stop there.
    far_outside = ~ndimage.binary_dilation(~truth, np.ones((25, 25), dtype=bool))
    assert (grid.occupancy[far_outside] == -1).all()


def test_run_record(table_run):
    meta = json.loads(table_run.meta_path.read_text())
    assert meta["seed"] == 7 and meta["pose_source"] == "truth" and meta["arena"] == "table"
    assert meta["map_hash"] == table_run.map.content_hash()
    assert meta["n_scans"] == table_run.n_scans > 0
    assert 180.0 <= table_run.robot_seconds
    assert table_run.sim_seconds < table_run.robot_seconds
    assert sorted(p.name for p in table_run.yaml_path.parent.iterdir()) == [
        "exploration.json",
        "map.pgm",
        "map.yaml",
    ]


def test_discretizing_the_explored_map(table_run):
    grid = table_run.map
    disc = Discretizer.from_map(grid, 41)
    assert disc.n_states == 41
    eroded = eroded_free_mask(grid)
    rc = grid.world_to_pixel(disc.centres)
    assert eroded[rc[:, 0], rc[:, 1]].all()
    # The eroded free space lies inside the arena shrunk by the robot radius.
    assert (np.abs(disc.centres) <= 0.75 - 0.113 + 1e-9).all()


def test_same_seed_same_map(tmp_path):
    a = build_map("table", minutes=0.5, seed=3, out=tmp_path / "a", progress=False)
    b = build_map("table", minutes=0.5, seed=3, out=tmp_path / "b", progress=False)
    assert a.image_path.read_bytes() == b.image_path.read_bytes()
    assert a.yaml_path.read_text() == b.yaml_path.read_text()


def test_odometry_pose_source_maps_with_the_drifting_estimate(tmp_path):
    truth = build_map("table", minutes=1.0, seed=5, out=tmp_path / "t", progress=False)
    odo = build_map("table", minutes=1.0, seed=5, out=tmp_path / "o", pose_source="odometry",
                    progress=False)
    assert odo.final_drift == truth.final_drift > 0  # same motion, same drift
    assert not odo.map.same_as(truth.map)
    assert json.loads(odo.meta_path.read_text())["pose_source"] == "odometry"


def test_sensor_pose_composes_the_mounting_offset():
    np.testing.assert_allclose(sensor_pose(np.array([1.0, 2.0, math.pi / 2]), np.array([-0.032, 0.0])),
                               [1.0, 2.0 - 0.032, math.pi / 2], atol=1e-12)
    np.testing.assert_allclose(sensor_pose(np.array([0.0, 0.0, math.pi]), np.array([0.1, 0.2])),
                               [-0.1, -0.2, math.pi], atol=1e-12)


def test_map_accuracy_by_hand():
    truth = np.zeros((6, 6), dtype=bool)
    truth[:, 0] = True  # a wall in column 0
    occ = np.zeros((6, 6), dtype=np.int8)
    occ[:, 0] = 100
    occ[0, 0] = 0  # one wall pixel mapped free, but an occupied pixel is next to it
    occ[5, 5] = -1  # one free pixel unknown
    occ[3, 4] = 100  # a false wall in free space
    grid = OccupancyMap(occ, 0.1)
    acc = map_accuracy(grid, truth)
    assert acc.wall_correct == 1.0 and acc.wall_coverage == 1.0
    # Scored free pixels: columns 2..5 (column 1 is in the band): 24, of which 2 wrong.
    assert acc.n_free == 24 and acc.free_correct == pytest.approx(22 / 24)
    strict = map_accuracy(grid, truth, tolerance_px=0)
    assert strict.wall_correct == pytest.approx(5 / 6)
    assert strict.n_free == 30 and strict.free_correct == pytest.approx(28 / 30)


def test_cli_map(tmp_path, capsys):
    out = tmp_path / "maps" / "table"
    argv = ["map", "--arena", "table", "--minutes", "0.5", "--seed", "1", "--out", str(out), "--no-progress"]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert str(out / "map.yaml") in printed and "walls" in printed
    before = (out / "map.pgm").read_bytes()
    assert main(argv) == 2
    assert "already exists" in capsys.readouterr().err
    assert (out / "map.pgm").read_bytes() == before
    assert main([*argv, "--overwrite", "--seed", "2"]) == 0
    assert json.loads((out / "exploration.json").read_text())["seed"] == 2


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--minutes", "0"], "minutes"),
        (["--arena", "no_such_arena"], "unknown arena"),
        (["--resolution", "0"], "resolution"),
        (["--seed", "-1"], "seed"),
    ],
)
def test_cli_map_bad_input(tmp_path, capsys, extra, message):
    out = tmp_path / "m"
    assert main(["map", "--out", str(out), "--no-progress", *extra]) == 2
    err = capsys.readouterr().err
    assert err.startswith("simlab map: error:") and message in err
    assert not out.exists()


def test_discretize_package_does_not_import_pybullet():
    code = (
        "import sys, discretize, discretize.gridmap, discretize.mapio, discretize.occupancy, "
        "discretize.voronoi, discretize.plot\n"
        "bad = [m for m in sys.modules if m.startswith(('pybullet', 'simlab.physics'))]\n"
        "assert not bad, bad\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
