"""Arena files: the built-ins load; every malformed file names the file and the key."""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.physics.arena import load_arena


def write_arena(path: Path, body: str) -> Path:
    path.write_text(textwrap.dedent(body))
    return path


TABLE_TOML = """\
    name = "t"
    [floor]
    size = [1.5, 1.5]
    [walls]
    height = 0.25
    thickness = 0.05
    [start]
    pose = [0.0, 0.0, 90.0]
    [[goals]]
    name = "C"
    center = [0.0, 0.0]
    radius = 0.15
"""


def test_builtin_arenas():
    table = load_arena("table")
    assert table.bounds == (-0.75, -0.75, 0.75, 0.75)
    assert len(table.goals) == 9 and len(set(table.goal_names)) == 9
    assert table.wall_height > 0.182
    assert table.start == pytest.approx((0.0, 0.0, math.pi / 2))
    assert table.obstacles == ()
    obst = load_arena("table_obstacles")
    assert {o.kind for o in obst.obstacles} == {"box", "cylinder"}
    # every goal centre is free in both arenas
    for arena in (table, obst):
        centres = np.array([[g.x, g.y] for g in arena.goals])
        assert not arena.occupied(centres).any()


def test_goal_contains_and_lookup():
    table = load_arena("table")
    c = table.goal("C")
    assert c.contains([0.0, 0.0]) and c.contains([0.15, 0.0]) and not c.contains([0.16, 0.0])
    with pytest.raises(ConfigError, match=r"unknown goal 'X'.*valid goals: NW, N, NE"):
        table.goal("X")


def test_rasterize_matches_geometry():
    arena = load_arena("table_obstacles")
    res = 0.01
    grid = arena.rasterize(res, (-0.8, -0.8), (160, 160))
    assert grid.shape == (160, 160)
    # row 0 is the top (y = 0.795 at pixel centres): outside the floor -> occupied
    assert grid[0].all() and grid[-1].all() and grid[:, 0].all() and grid[:, -1].all()
    # the centre pixel (x = 0.005, y = 0.005 -> col 80, row 79) is free
    assert not grid[79, 80]
    # the cylinder obstacle at (0.24, -0.22), r 0.07: its centre pixel is occupied
    col, row = int((0.24 + 0.8) / res), int(160 - 1 - (-0.22 + 0.8) / res)
    assert grid[row, col]
    # occupied area inside the floor = area of the two obstacles (within pixel error)
    inner = grid[5:155, 5:155]
    expected = (0.24 * 0.10 + math.pi * 0.07**2) / res**2
    assert inner.sum() == pytest.approx(expected, rel=0.03)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda s: s.replace("height = 0.25\n", ""), r"walls\.height: missing key"),
        (lambda s: s.replace("height = 0.25", 'height = "tall"'),
         r"walls\.height: expected a finite number > 0, got 'tall'"),
        (lambda s: s.replace("height = 0.25", "height = 0.1"), r"walls\.height: .*LIDAR plane"),
        (lambda s: s.replace("size = [1.5, 1.5]", "size = [1.5]"),
         r"floor\.size: expected a list of 2 numbers"),
        (lambda s: s.replace("thickness = 0.05", "thickness = 0.05\ncolour = 1"),
         r"walls: unknown key\(s\) \['colour'\]"),
        (lambda s: s.replace("center = [0.0, 0.0]", "center = [2.0, 0.0]"),
         r"goals\[0\]\.center: .*outside the floor"),
        (lambda s: s.replace("radius = 0.15", "radius = -1"),
         r"goals\[0\]\.radius: expected a finite number > 0"),
        (lambda s: s + '[[obstacles]]\nkind = "cone"\ncenter = [0.3, 0.3]\nheight = 0.3\n',
         r"obstacles\[0\]\.kind: unknown obstacle kind 'cone'"),
        (lambda s: s + '[[obstacles]]\nkind = "box"\ncenter = [0.0, 0.0]\nsize = [0.2, 0.2]\n'
         'height = 0.3\n', r"start\.pose: .*inside an obstacle"),
        (lambda s: s.replace("[start]", "[start"), r"not valid TOML"),
        (lambda s: s.replace('name = "t"', "name = 3"), r"name: expected a non-empty string"),
    ],
)
def test_malformed_arena_names_file_and_key(tmp_path, edit, message):
    path = write_arena(tmp_path / "bad_arena.toml", edit(TABLE_TOML.replace("    ", "")))
    with pytest.raises(ConfigError, match=message) as info:
        load_arena(path)
    assert "bad_arena.toml" in str(info.value)


def test_unknown_arena_name_lists_known_ones(tmp_path):
    with pytest.raises(ConfigError, match=r"unknown arena name 'kitchen'.*table, table_obstacles"):
        load_arena("kitchen")
    with pytest.raises(ConfigError, match=r"missing\.toml: file not found"):
        load_arena(tmp_path / "missing.toml")
