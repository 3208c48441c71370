"""Voronoi discretizer: erosion, placement, numbering, state_of, files, errors."""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest

from discretize.gridmap import OCCUPIED, OccupancyMap
from discretize.voronoi import (
    TURTLEBOT3_BURGER_RADIUS,
    Discretizer,
    eroded_free_mask,
    load_centres_txt,
    row_major_order,
)
from simlab.base.errors import ConfigError, DataError


@pytest.fixture(scope="module")
def table_states(make_room):
    room = make_room()
    return room, Discretizer.from_map(room, 41)


def test_default_robot_radius_is_the_burger_half_diagonal():
    assert TURTLEBOT3_BURGER_RADIUS == pytest.approx(0.113, abs=5e-4)


def test_erosion_of_a_square_is_the_shrunk_square(room):
    # Pixel centres sit 0.005 + 0.01 k from the wall; clearance >= 0.113 needs k >= 11,
    # so 11 pixel rows go on each side: 150 - 22 = 128.
    eroded = eroded_free_mask(room, 0.113)
    rows, cols = np.nonzero(eroded)
    assert eroded.sum() == 128 * 128
    assert rows.max() - rows.min() + 1 == 128 and cols.max() - cols.min() + 1 == 128
    assert eroded_free_mask(room, 0.0).sum() == 150 * 150
    assert eroded_free_mask(room, 0.75).sum() == 0


def test_unknown_and_image_border_block_like_walls():
    occ = np.zeros((50, 50), dtype=np.int8)  # free up to the image border
    m = OccupancyMap(occ, 0.01)
    assert eroded_free_mask(m, 0.1).sum() == 30 * 30
    occ2 = occ.copy()
    occ2[:, :10] = -1
    assert eroded_free_mask(OccupancyMap(occ2, 0.01), 0.1).sum() == 30 * 20


def test_largest_component_only_by_default():
    occ = np.full((60, 100), OCCUPIED, dtype=np.int8)
    occ[5:55, 5:55] = 0  # big room
    occ[20:40, 70:90] = 0  # small room
    m = OccupancyMap(occ, 0.01)
    assert eroded_free_mask(m, 0.02).sum() == 46 * 46
    assert eroded_free_mask(m, 0.02, component="all").sum() == 46 * 46 + 16 * 16


def test_count_met_and_centres_in_eroded_free_space(table_states):
    room, disc = table_states
    assert disc.n_states == 41
    eroded = eroded_free_mask(room, 0.113)
    rc = room.world_to_pixel(disc.centres)
    assert eroded[rc[:, 0], rc[:, 1]].all()
    # Centres are pixel centres (snapped).
    np.testing.assert_allclose(room.pixel_to_world(rc), disc.centres, atol=1e-12)
    assert disc.map_hash == room.content_hash()


def test_centroidal_cells_are_balanced(table_states):
    # A centroidal Voronoi tessellation of a square into 41 cells has cells of similar
    # area: every cell's share of the eroded pixels is within a factor 2 of 1/41.
    room, disc = table_states
    pts = room.pixel_centres(eroded_free_mask(room, 0.113))
    counts = np.bincount(disc.state_of(pts), minlength=41)
    share = counts / counts.sum()
    assert share.min() > 0.5 / 41 and share.max() < 2.0 / 41


def test_same_inputs_same_centres_and_numbering(table_states, make_room):
    _room, disc = table_states
    again = Discretizer.from_map(make_room(), 41)
    np.testing.assert_array_equal(again.centres, disc.centres)
    assert again.content_hash() == disc.content_hash()


def test_numbering_is_row_major_from_top_left(table_states):
    _, disc = table_states
    c = disc.centres
    tol = disc.params["row_tolerance"]
    # Already numbered: renumbering is the identity.
    np.testing.assert_array_equal(row_major_order(c, tol), np.arange(41))
    # State 0 is in the top row, at its left end.
    top = c[:, 1] >= c[:, 1].max() - tol
    assert c[0, 1] >= c[:, 1].max() - tol and c[0, 0] == c[top, 0].min()
    # y never increases by more than the tolerance, x increases within a row.
    for a, b in itertools.pairwise(c):
        same_row = b[0] > a[0]
        if same_row:
            assert b[1] >= a[1] - 2 * tol
        else:
            assert b[1] < a[1]


def test_row_major_order_of_a_jittered_lattice(rng):
    xs, ys = np.meshgrid([0.0, 1.0, 2.0, 3.0], [2.0, 1.0, 0.0])  # row 0 is the top (y=2)
    lattice = np.stack([xs.ravel(), ys.ravel()], axis=-1)
    # Jitter +-0.15: rows spread <= 0.3 < tolerance (~0.4) < gap between rows (>= 0.7).
    jittered = lattice + rng.uniform(-0.15, 0.15, size=lattice.shape)
    perm = rng.permutation(len(lattice))
    order = row_major_order(jittered[perm])
    np.testing.assert_array_equal(perm[order], np.arange(12))


def test_state_of_equals_brute_force(table_states, rng):
    _, disc = table_states
    xy = rng.uniform(-1.2, 1.2, size=(10_000, 2))
    brute = np.argmin(((xy[:, None, :] - disc.centres[None, :, :]) ** 2).sum(-1), axis=1)
    np.testing.assert_array_equal(disc.state_of(xy), brute)
    # Shapes: (..., 2) in, (...) out; extra columns (yaw) ignored.
    poses = np.concatenate([xy, rng.uniform(-3, 3, size=(10_000, 1))], axis=1)
    np.testing.assert_array_equal(disc.state_of(poses.reshape(100, 100, 3)), brute.reshape(100, 100))
    assert disc.state_of(xy[0]).shape == ()


def test_every_free_pose_has_exactly_one_state(table_states):
    room, disc = table_states
    pts = room.pixel_centres(room.free_mask())
    s = disc.state_of(pts)
    assert s.dtype == np.int64 and s.shape == (len(pts),)
    assert ((s >= 0) & (s < 41)).all()
    d_own = np.linalg.norm(pts - disc.centres[s], axis=1)
    d_all = np.linalg.norm(pts[:, None, :] - disc.centres[None], axis=2)
    np.testing.assert_allclose(d_own, d_all.min(axis=1))


def test_state_of_rejects_non_finite(table_states):
    _, disc = table_states
    with pytest.raises(ValueError, match="finite"):
        disc.state_of(np.array([[0.0, np.nan]]))


def test_radius_rule_count(room):
    # Eroded area 1.28^2 m^2; N = round(1.6384 / (pi 0.09^2)) = round(64.39) = 64.
    disc = Discretizer.from_map(room, radius=0.09)
    assert disc.n_states == 64 and disc.method == "radius"
    assert disc.n_states == round(1.28**2 / (math.pi * 0.09**2))


def test_obstacle_map_centres_avoid_the_obstacle(room):
    occ = room.occupancy.copy()
    occ[80:120, 80:120] = OCCUPIED  # a 0.4 m box in the middle
    m = OccupancyMap(occ, room.resolution, room.origin)
    disc = Discretizer.from_map(m, 30)
    eroded = eroded_free_mask(m, 0.113)
    rc = m.world_to_pixel(disc.centres)
    assert eroded[rc[:, 0], rc[:, 1]].all()
    assert (np.abs(disc.centres).max(axis=1) > 0.2 + 0.113 - 1e-9).all()


def test_save_load_round_trip(tmp_path, table_states):
    _, disc = table_states
    path = disc.save(tmp_path / "states" / "table.json")
    doc = json.loads(path.read_text())
    assert doc["n_states"] == 41 and len(doc["centres"]) == 41
    assert doc["map_hash"] == disc.map_hash and doc["content_hash"] == disc.content_hash()
    back = Discretizer.load(path)
    np.testing.assert_array_equal(back.centres, disc.centres)
    assert back.content_hash() == disc.content_hash()
    assert back.params == disc.params
    with pytest.raises(ConfigError, match="already exists"):
        disc.save(path)


def test_load_rejects_edited_or_corrupt_files(tmp_path, table_states):
    _, disc = table_states
    doc = disc.to_json()
    doc["centres"][0][0] += 0.01
    (tmp_path / "edited.json").write_text(json.dumps(doc))
    with pytest.raises(DataError, match="content_hash"):
        Discretizer.load(tmp_path / "edited.json")
    del doc["content_hash"]
    (tmp_path / "accepted.json").write_text(json.dumps(doc))
    assert Discretizer.load(tmp_path / "accepted.json").centres[0, 0] == doc["centres"][0][0]
    for name, text in [("a", "{"), ("b", "[1, 2]"), ("c", '{"centres": [[1, 2, 3]]}'),
                       ("d", '{"centres": [[0, 0], [0, 0]]}'), ("e", '{"centres": [["x", 1]]}')]:
        (tmp_path / f"{name}.json").write_text(text)
        with pytest.raises(DataError):
            Discretizer.load(tmp_path / f"{name}.json")


def test_centres_text_file(tmp_path, room):
    path = tmp_path / "c.txt"
    path.write_text("# x y\n0.5 0.5\n\n-0.5, -0.5  # comma allowed\n0.5 -0.5\n-0.5 0.5\n")
    c = load_centres_txt(path)
    np.testing.assert_array_equal(c, [[0.5, 0.5], [-0.5, -0.5], [0.5, -0.5], [-0.5, 0.5]])
    kept = Discretizer.from_centres(c, grid=room)
    np.testing.assert_array_equal(kept.centres, c)  # file order by default
    assert kept.map_hash == room.content_hash()
    renum = Discretizer.from_centres(c, grid=room, renumber=True)
    np.testing.assert_array_equal(renum.centres, [[-0.5, 0.5], [0.5, 0.5], [-0.5, -0.5], [0.5, -0.5]])


@pytest.mark.parametrize(
    ("text", "where"),
    [
        ("0.1 0.2\n0.3\n", "line 2"),
        ("0.1 0.2\n0.3 abc\n", "line 2"),
        ("0.1 0.2 0.3\n", "line 1"),
        ("nan 0\n", "line 1"),
        ("# nothing\n\n", "no centres"),
    ],
)
def test_malformed_centres_file(tmp_path, text, where):
    path = tmp_path / "c.txt"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_centres_txt(path)
    assert str(path) in str(info.value) and where in str(info.value)


def test_file_centres_must_fit_the_map(room):
    with pytest.raises(ConfigError, match="outside the map"):
        Discretizer.from_centres(np.array([[0.0, 0.0], [5.0, 0.0]]), grid=room)
    with pytest.raises(ConfigError, match="occupied"):
        Discretizer.from_centres(np.array([[0.0, 0.0], [0.77, 0.0]]), grid=room)
    with pytest.raises(ConfigError, match="coincide"):
        Discretizer.from_centres(np.array([[0.0, 0.0], [0.0, 0.0]]), grid=room)


def test_placement_errors(room, make_room):
    tiny = make_room(side_px=20)
    with pytest.raises(ConfigError, match="no free space left"):
        Discretizer.from_map(tiny, 3)
    small = make_room(side_px=30)  # 8 x 8 eroded pixels at r = 0.113
    with pytest.raises(ConfigError, match="only 64 pixels"):
        Discretizer.from_map(small, 65)
    assert Discretizer.from_map(small, 64).n_states == 64
    with pytest.raises(ConfigError, match="not both"):
        Discretizer.from_map(room, 10, radius=0.1)
    for bad in (0, -3, 2.5):
        with pytest.raises(ConfigError):
            Discretizer.from_map(room, bad)
    with pytest.raises(ConfigError):
        Discretizer.from_map(room, radius=-0.1)
