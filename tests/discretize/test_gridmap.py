"""OccupancyMap: map_server pixel conventions and content hash."""

from __future__ import annotations

import numpy as np
import pytest

from discretize.gridmap import OccupancyMap


def _map(h=4, w=6, res=0.5, origin=(1.0, -2.0, 0.0)):
    occ = np.zeros((h, w), dtype=np.int8)
    return OccupancyMap(occ, res, origin)


def test_pixel_centres_follow_map_server_orientation():
    m = _map()
    # Row 0 is the top: its pixels' centres have the largest y.
    np.testing.assert_allclose(m.pixel_to_world([0, 0]), [1.25, -2.0 + 3.5 * 0.5])
    # Lower-left pixel: centre half a pixel from the origin in x and y.
    np.testing.assert_allclose(m.pixel_to_world([3, 0]), [1.25, -1.75])
    np.testing.assert_allclose(m.pixel_to_world([3, 5]), [3.75, -1.75])
    # The origin itself is the lower-left corner of pixel (H-1, 0).
    np.testing.assert_array_equal(m.world_to_pixel([1.0 + 1e-9, -2.0 + 1e-9]), [3, 0])
    assert m.extent() == (1.0, 4.0, -2.0, 0.0)


@pytest.mark.parametrize("yaw", [0.0, 0.3, -2.0])
def test_world_pixel_round_trip(yaw):
    m = _map(h=30, w=40, res=0.05, origin=(0.3, -0.7, yaw))
    rows, cols = np.meshgrid(np.arange(30), np.arange(40), indexing="ij")
    rc = np.stack([rows.ravel(), cols.ravel()], axis=-1)
    np.testing.assert_array_equal(m.world_to_pixel(m.pixel_to_world(rc)), rc)
    assert m.in_bounds(rc).all()
    assert not m.in_bounds(np.array([[-1, 0], [0, 40], [30, 0]])).any()


def test_rotated_origin_moves_pixels_about_the_corner():
    m = _map(h=2, w=2, res=1.0, origin=(0.0, 0.0, np.pi / 2))
    # Pixel (1, 0) (lower-left) has centre (0.5, 0.5) in the map frame; rotated by
    # 90 degrees about the origin it sits at (-0.5, 0.5).
    np.testing.assert_allclose(m.pixel_to_world([1, 0]), [-0.5, 0.5], atol=1e-12)


def test_content_hash_identifies_content():
    m = _map()
    same = OccupancyMap(m.occupancy.copy(), 0.5, (1.0, -2.0, 0.0))
    assert m.content_hash() == same.content_hash()
    occ = m.occupancy.copy()
    occ[1, 2] = 100
    assert OccupancyMap(occ, 0.5, m.origin).content_hash() != m.content_hash()
    assert OccupancyMap(m.occupancy, 0.25, m.origin).content_hash() != m.content_hash()
    assert OccupancyMap(m.occupancy, 0.5, (1.0, -2.0, 0.1)).content_hash() != m.content_hash()


def test_occupancy_is_read_only_copy():
    occ = np.zeros((3, 3), dtype=np.int8)
    m = OccupancyMap(occ, 0.1)
    occ[0, 0] = 100
    assert m.occupancy[0, 0] == 0
    with pytest.raises(ValueError):
        m.occupancy[0, 0] = 100


@pytest.mark.parametrize(
    ("occ", "res", "origin"),
    [
        (np.zeros((0, 3), np.int8), 0.1, (0, 0, 0)),
        (np.zeros((3,), np.int8), 0.1, (0, 0, 0)),
        (np.full((2, 2), 101), 0.1, (0, 0, 0)),
        (np.zeros((2, 2)), 0.1, (0, 0, 0)),
        (np.zeros((2, 2), np.int8), 0.0, (0, 0, 0)),
        (np.zeros((2, 2), np.int8), 0.1, (0, 0)),
        (np.zeros((2, 2), np.int8), 0.1, (0, float("nan"), 0)),
    ],
)
def test_invalid_maps_rejected(occ, res, origin):
    with pytest.raises(ValueError):
        OccupancyMap(occ, res, origin)
