"""Arenas built from map_server maps: walls vs the map, the map frame, LIDAR, validation.

The maps are synthetic and written here (PGM + YAML through discretize.mapio.write_map).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from discretize.gridmap import OccupancyMap
from discretize.mapio import write_map
from simlab.base.errors import ConfigError
from simlab.physics.arena import load_arena, merge_rectangles
from simlab.physics.world import World

RES = 0.05
#: A map frame far from the origin, so a centred arena would be visibly wrong.
ORIGIN = (-3.0, 12.0)


def _fill(occ: np.ndarray, x0: float, y0: float, x1: float, y1: float, value: int) -> None:
    """Set the pixels whose centres lie in [x0, x1) x [y0, y1) (map coordinates, m)."""
    h, w = occ.shape
    xs = ORIGIN[0] + (np.arange(w) + 0.5) * RES
    ys = ORIGIN[1] + (h - 1 - np.arange(h) + 0.5) * RES
    cols = (xs >= x0) & (xs < x1)
    rows = (ys >= y0) & (ys < y1)
    occ[np.ix_(rows, cols)] = value


def room_map(speckles: float = 0.0, seed: int = 0) -> OccupancyMap:
    """A 3 x 2 m room (free x in [-2.5, 0.5), y in [12.5, 14.5)) with 0.1 m walls, a
    0.3 x 0.3 m pillar at x [-0.5, -0.2), y [13.0, 13.3), unknown all around; optional
    single-pixel speckles (GMapping-like noise) in the free space."""
    occ = np.full((60, 80), -1, dtype=np.int8)
    _fill(occ, -2.6, 12.4, 0.6, 14.6, 100)
    _fill(occ, -2.5, 12.5, 0.5, 14.5, 0)
    _fill(occ, -0.5, 13.0, -0.2, 13.3, 100)
    if speckles:
        rng = np.random.default_rng(seed)
        occ[(occ == 0) & (rng.random(occ.shape) < speckles)] = 100
        _fill(occ, -2.2, 13.3, -1.8, 13.7, 0)  # keep the start and the goal free
        _fill(occ, -1.1, 12.95, -0.7, 13.35, 0)
    return OccupancyMap(occ, RES, (ORIGIN[0], ORIGIN[1], 0.0))


def write_arena(tmp_path: Path, grid: OccupancyMap, start: str = "[-2.0, 13.5, 0.0]",
                extra: str = "", map_extra: str = "") -> Path:
    write_map(tmp_path / "maps" / "room.yaml", grid, overwrite=True)
    path = tmp_path / "room.toml"
    path.write_text(f"""name = "room"
[map]
yaml = "maps/room.yaml"
{map_extra}
[walls]
height = 0.25
thickness = 0.05
[start]
pose = {start}
[[goals]]
name = "pillar_side"
center = [-0.9, 13.15]
radius = 0.2
{extra}""")
    return path


def boxes_raster(arena, grid: OccupancyMap) -> np.ndarray:
    """The built wall boxes rasterised back onto the map grid (pixel centres inside)."""
    h, w = grid.occupancy.shape
    xs = grid.origin[0] + (np.arange(w) + 0.5) * grid.resolution
    ys = grid.origin[1] + (h - 1 - np.arange(h) + 0.5) * grid.resolution
    gx, gy = np.meshgrid(xs, ys)
    out = np.zeros((h, w), dtype=bool)
    for x0, y0, x1, y1 in arena.map_walls.boxes:
        out |= (gx > x0) & (gx < x1) & (gy > y0) & (gy < y1)
    return out


def test_merge_rectangles_covers_the_mask_exactly_with_disjoint_boxes() -> None:
    rng = np.random.default_rng(3)
    mask = rng.random((30, 40)) < 0.3
    mask[5:20, 10:12] = True
    rects = merge_rectangles(mask)
    cover = np.zeros(mask.shape, dtype=int)
    for r0, c0, r1, c1 in rects:
        cover[r0:r1, c0:c1] += 1
    np.testing.assert_array_equal(cover, mask.astype(int))  # exact and disjoint
    assert len(rects) < mask.sum()
    assert len(merge_rectangles(np.ones((7, 9), bool))) == 1


@pytest.mark.parametrize("speckles", [0.0, 0.02])
def test_walls_match_the_map_occupied_cells(tmp_path: Path, speckles: float) -> None:
    grid = room_map(speckles)
    arena = load_arena(write_arena(tmp_path, grid))
    built = boxes_raster(arena, grid)
    truth = grid.occupancy >= 65
    tp = int((built & truth).sum())
    precision, recall = tp / built.sum(), tp / truth.sum()
    assert precision >= 0.98 and recall >= 0.98
    # few boxes: a wall line is one box per straight run, not one per pixel
    assert len(arena.map_walls.boxes) < 0.2 * truth.sum()
    # the occupancy query agrees with the map at every pixel centre of the known part
    known = grid.occupancy >= 0
    h, w = grid.occupancy.shape
    gx, gy = np.meshgrid(ORIGIN[0] + (np.arange(w) + 0.5) * RES,
                         ORIGIN[1] + (h - 1 - np.arange(h) + 0.5) * RES)
    occ = arena.occupied(np.stack([gx, gy], axis=-1))
    np.testing.assert_array_equal(occ[known], truth[known])


def test_map_frame_is_kept_and_unknown_as_wall(tmp_path: Path) -> None:
    grid = room_map()
    arena = load_arena(write_arena(tmp_path, grid))
    x0, y0, x1, y1 = arena.bounds
    # the known part (walls included) plus one pixel, in map coordinates: no centring
    assert (x0, y0, x1, y1) == pytest.approx((-2.65, 12.35, 0.65, 14.65), abs=1e-9)
    assert arena.start[:2] == (-2.0, 13.5)
    with World(arena) as world:
        np.testing.assert_allclose(world.pose(), [-2.0, 13.5, 0.0], atol=1e-6)
    # unknown pixels are floor by default, walls with the option
    outside = np.array([-2.62, 14.62])  # an unknown pixel inside the cropped bounds
    assert not arena.map_walls.contains(outside)
    walled = load_arena(write_arena(tmp_path, grid, map_extra="unknown_as_wall = true"))
    assert walled.map_walls.contains(outside)
    assert walled.source_sha256 != arena.source_sha256


@pytest.mark.parametrize("pose", [(-2.0, 13.5, 0.0), (-1.2, 14.0, 2.5), (0.1, 12.8, -1.0)])
def test_lidar_reads_the_distances_to_the_map_walls(tmp_path: Path, pose) -> None:
    arena = load_arena(write_arena(tmp_path, room_map(),
                                   start=f"[{pose[0]}, {pose[1]}, {math.degrees(pose[2])}]"))
    with World(arena) as world:
        scan = world.scan(None)
        x, y, yaw = pose
        off = world.robot_spec.lidar_offset[0]
        sx, sy = x + math.cos(yaw) * off, y + math.sin(yaw) * off
    phi = yaw + scan.angles
    c, s = np.cos(phi), np.sin(phi)
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = np.where(c > 0, (0.5 - sx) / c, np.where(c < 0, (-2.5 - sx) / c, np.inf))
        ty = np.where(s > 0, (14.5 - sy) / s, np.where(s < 0, (12.5 - sy) / s, np.inf))
    expected = np.minimum(tx, ty)
    # the pillar x [-0.5, -0.2), y [13.0, 13.3): slab-method ray/box intersection
    with np.errstate(divide="ignore", invalid="ignore"):
        ax, bx = (-0.5 - sx) / c, (-0.2 - sx) / c
        ay, by = (13.0 - sy) / s, (13.3 - sy) / s
        t_in = np.maximum(np.minimum(ax, bx), np.minimum(ay, by))
        t_out = np.minimum(np.maximum(ax, bx), np.maximum(ay, by))
    hits_pillar = (t_in <= t_out) & (t_in > 0)
    expected = np.where(hits_pillar, np.minimum(expected, t_in), expected)
    assert hits_pillar.sum() >= 3
    ok = expected <= 3.5
    err = np.abs(scan.ranges[ok] - expected[ok])
    # a beam grazing a box corner or the seam of two merged boxes may read ~1 mm short
    assert err.max() < 5e-3
    assert np.mean(err < 1e-3) >= 0.98


def test_start_in_a_wall_and_other_bad_inputs_are_refused(tmp_path: Path) -> None:
    grid = room_map()
    with pytest.raises(ConfigError, match=r"start\.pose.*overlap a wall"):
        load_arena(write_arena(tmp_path, grid, start="[-2.45, 13.5, 0.0]"))  # body in the wall
    with pytest.raises(ConfigError, match=r"start\.pose.*inside"):
        load_arena(write_arena(tmp_path, grid, start="[-0.35, 13.15, 0.0]"))  # in the pillar
    path = write_arena(tmp_path, grid, extra="[floor]\nsize = [1.0, 1.0]\n")
    with pytest.raises(ConfigError, match=r"exactly one of \[floor\]"):
        load_arena(path)
    path = write_arena(tmp_path, grid)
    path.write_text(path.read_text().replace("maps/room.yaml", "maps/none.yaml"))
    with pytest.raises(ConfigError, match=r"map\.yaml.*not found"):
        load_arena(path)
    path = write_arena(tmp_path, grid, map_extra="colour = 1")
    with pytest.raises(ConfigError, match=r"map: unknown key"):
        load_arena(path)
    path = write_arena(tmp_path, grid, extra="[[goals]]\nname='w'\ncenter=[-2.55, 13.0]\n"
                                             "radius=0.1\n")
    with pytest.raises(ConfigError, match=r"goals\[1\]\.center.*wall"):
        load_arena(path)


def test_arena_from_map_writes_a_loadable_arena(tmp_path: Path) -> None:
    from simlab.cli import main
    from simlab.physics.map_arena import arena_from_map

    grid = room_map()
    write_map(tmp_path / "room.yaml", grid)
    (tmp_path / "sub").mkdir()
    out = arena_from_map(tmp_path / "room.yaml", tmp_path / "sub" / "auto.toml")
    arena = load_arena(out)
    assert arena.map_walls is not None and len(arena.goals) >= 4
    for g in arena.goals:  # the freest points, well away from the walls
        assert not arena.occupied(np.array([g.x, g.y]))
    assert main(["arena-from-map", str(tmp_path / "room.yaml"), "--out", str(out)]) == 2
    before = out.read_text()
    assert out.read_text() == before  # refused, not overwritten


# ---- the options as ArenaFromMapConfig: --config FILE, --help, the Python function

def test_arena_from_map_config_file_and_the_command_line_wins(tmp_path: Path, capsys) -> None:
    import argparse

    from simlab.cli import main
    from simlab.cli.arena import add_arguments
    from simlab.physics.map_arena import ArenaFromMapConfig

    write_map(tmp_path / "room.yaml", room_map())
    toml = tmp_path / "a.toml"
    toml.write_text(f'out = "{tmp_path / "lab.toml"}"\nname = "lab"\ngoal-radius = 0.2\n'
                    'start = [-2.0, 13.5, 0.0]\n')
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    assert "(default 0.15)" in parser.format_help()
    cfg = ArenaFromMapConfig.from_args(parser.parse_args(
        [str(tmp_path / "room.yaml"), "--config", str(toml), "--start=-1.5,13.4,90"]))
    assert (cfg.name, cfg.goal_radius, cfg.start) == ("lab", 0.2, (-1.5, 13.4, 90.0))
    assert main(["arena-from-map", str(tmp_path / "room.yaml"), "--config", str(toml),
                 "--goal-radius", "0.25"]) == 0
    assert "arena lab" in capsys.readouterr().out
    arena = load_arena(tmp_path / "lab.toml")
    assert {g.radius for g in arena.goals} == {0.25}
    assert arena.start[:2] == pytest.approx((-2.0, 13.5))


def test_arena_from_map_config_refusals(tmp_path: Path, capsys) -> None:
    from simlab.cli import main
    from simlab.physics.map_arena import ArenaFromMapConfig

    write_map(tmp_path / "room.yaml", room_map())
    toml = tmp_path / "a.toml"
    toml.write_text('out = "x.toml"\ngoal-radiuss = 0.2\n')
    assert main(["arena-from-map", str(tmp_path / "room.yaml"), "--config", str(toml)]) == 2
    err = capsys.readouterr().err
    assert str(toml) in err and "goal-radiuss: unknown option" in err and err.count("\n") == 1
    with pytest.raises(ConfigError, match="start"):
        ArenaFromMapConfig(map_yaml="m.yaml", out="a.toml", start=(0.0, 1.0))
    with pytest.raises(ConfigError, match="goal_radius"):
        ArenaFromMapConfig(map_yaml="m.yaml", out="a.toml", goal_radius=0.0)


def test_arena_from_map_takes_the_config_or_its_fields(tmp_path: Path) -> None:
    from simlab.physics.map_arena import ArenaFromMapConfig, arena_from_map

    write_map(tmp_path / "room.yaml", room_map())
    a = arena_from_map(ArenaFromMapConfig(map_yaml=tmp_path / "room.yaml", out=tmp_path / "a.toml",
                                          name="lab", unknown_as_wall=True))
    b = arena_from_map(tmp_path / "room.yaml", tmp_path / "b.toml", name="lab",
                       unknown_as_wall=True)
    assert a.read_text() == b.read_text() and 'name = "lab"' in a.read_text()
