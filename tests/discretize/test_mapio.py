"""ROS map_server format: exact round trips, ROS interpretation, clear errors."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from discretize.gridmap import OccupancyMap
from discretize.mapio import (
    encode_pgm,
    image_to_occupancy,
    map_yaml_text,
    read_map,
    read_map_yaml,
    write_map,
)
from simlab.base.errors import ConfigError, DataError


def _random_trinary(rng, shape=(37, 53)) -> np.ndarray:
    return rng.choice(np.array([-1, 0, 100], dtype=np.int8), size=shape)


# Awkward numbers on purpose: the YAML must carry them exactly.
_ORIGIN = (-12.345678901234567, 0.1 + 0.2, 1e-05)
_RES = 0.049999999999999996


def test_trinary_round_trip_is_exact(tmp_path, rng):
    m = OccupancyMap(_random_trinary(rng), _RES, _ORIGIN)
    yaml_path, image_path = write_map(tmp_path / "map.yaml", m)
    assert image_path == tmp_path / "map.pgm"
    back = read_map(yaml_path)
    assert back.same_as(m)
    assert back.content_hash() == m.content_hash()
    # Values map_saver writes.
    assert image_path.read_bytes().startswith(b"P5")


def test_raw_round_trip_keeps_intermediate_values(tmp_path, rng):
    occ = rng.integers(-1, 101, size=(20, 30)).astype(np.int8)
    m = OccupancyMap(occ, 0.02, (0.0, 0.0, 0.0))
    write_map(tmp_path / "m.yaml", m, mode="raw")
    assert read_map_yaml(tmp_path / "m.yaml").mode == "raw"
    assert read_map(tmp_path / "m.yaml").same_as(m)


def test_png_reads_the_same_occupancy(tmp_path, rng):
    m = OccupancyMap(_random_trinary(rng), 0.01, (-1.0, -1.0, 0.0))
    write_map(tmp_path / "a.yaml", m)
    write_map(tmp_path / "b.yaml", m, image="b.png")
    assert (tmp_path / "b.png").read_bytes()[:4] == b"\x89PNG"
    a, b = read_map(tmp_path / "a.yaml"), read_map(tmp_path / "b.yaml")
    assert a.same_as(b) and b.same_as(m)


def test_negate_reads_the_same_occupancy(tmp_path, rng):
    m = OccupancyMap(_random_trinary(rng), 0.01, (0.0, 0.0, 0.0))
    write_map(tmp_path / "map.yaml", m)
    pixels = np.frombuffer((tmp_path / "map.pgm").read_bytes()[-m.occupancy.size :], np.uint8)
    inverted = 255 - pixels.reshape(m.shape)
    (tmp_path / "neg.pgm").write_bytes(encode_pgm(inverted))
    (tmp_path / "neg.yaml").write_text(
        map_yaml_text("neg.pgm", 0.01, (0.0, 0.0, 0.0)).replace("negate: 0", "negate: 1")
    )
    assert read_map(tmp_path / "neg.yaml").same_as(m)


def test_colour_and_ascii_images_read_the_same(tmp_path, rng):
    m = OccupancyMap(_random_trinary(rng), 0.01, (0.0, 0.0, 0.0))
    write_map(tmp_path / "map.yaml", m)
    grey = np.frombuffer((tmp_path / "map.pgm").read_bytes()[-m.occupancy.size :], np.uint8)
    grey = grey.reshape(m.shape)
    # RGB PNG with the grey value in every channel.
    cv2.imwrite(str(tmp_path / "rgb.png"), np.repeat(grey[:, :, None], 3, axis=2))
    (tmp_path / "rgb.yaml").write_text(map_yaml_text("rgb.png", 0.01, (0.0, 0.0, 0.0)))
    # ASCII P2 with a comment in the header.
    body = "\n".join(" ".join(str(v) for v in row) for row in grey)
    (tmp_path / "asc.pgm").write_text(f"P2\n# made by hand\n{m.width} {m.height}\n255\n{body}\n")
    (tmp_path / "asc.yaml").write_text(map_yaml_text("asc.pgm", 0.01, (0.0, 0.0, 0.0)))
    # 16-bit binary PGM (values scaled by 257).
    wide = (grey.astype(">u2") * 257).tobytes()
    (tmp_path / "w.pgm").write_bytes(f"P5\n{m.width} {m.height}\n65535\n".encode() + wide)
    (tmp_path / "w.yaml").write_text(map_yaml_text("w.pgm", 0.01, (0.0, 0.0, 0.0)))
    for name in ("rgb", "asc", "w"):
        assert read_map(tmp_path / f"{name}.yaml").same_as(m), name


def test_a_pgm_of_a_small_maxval_is_scaled_as_map_server_does(tmp_path):
    # the reason the PGM reader is ours (benchmarks/pgm_reader.py): OpenCV returns the
    # pixels of a P5 whose maxval is not 255 or 65535 unscaled, map_server scales them
    from discretize.mapio import read_image

    values = np.array([[0, 20, 100]], dtype=np.uint8)
    (tmp_path / "m.pgm").write_bytes(b"P5\n3 1\n100\n" + values.tobytes())
    np.testing.assert_array_equal(read_image(tmp_path / "m.pgm"), [[0, 51, 255]])
    (tmp_path / "a.pgm").write_bytes(b"P2\n# ascii\n3 1\n100\n0 20 100\n")
    np.testing.assert_array_equal(read_image(tmp_path / "a.pgm"), [[0, 51, 255]])


def test_ros_interpretation_by_hand():
    # p = (255 - v) / 255: v=0 -> 1.0, v=254 -> 0.0039, v=205 -> 0.19608, v=166 -> 0.349,
    # v=100 -> 0.6078, v=80 -> 0.686.
    img = np.array([[0, 254, 205, 166, 100, 80]], dtype=np.uint8)
    tri = image_to_occupancy(img, occupied_thresh=0.65, free_thresh=0.196)
    np.testing.assert_array_equal(tri, [[100, 0, -1, -1, -1, 100]])
    tri2 = image_to_occupancy(img, occupied_thresh=0.6, free_thresh=0.35)
    np.testing.assert_array_equal(tri2, [[100, 0, 0, 0, 100, 100]])
    neg = image_to_occupancy(255 - img, negate=True, occupied_thresh=0.65, free_thresh=0.196)
    np.testing.assert_array_equal(neg, tri)
    # scale: ratio = (p - 0.196) / (0.65 - 0.196); v=166: int(1 + 98 * 0.33767) = 34;
    # v=100: int(1 + 98 * 0.90703) = 89; v=205: int(1 + 98 * 0.0001727) = 1.
    sc = image_to_occupancy(img, occupied_thresh=0.65, free_thresh=0.196, mode="scale")
    np.testing.assert_array_equal(sc, [[100, 0, 1, 34, 89, 100]])
    raw = image_to_occupancy(np.array([[0, 42, 100, 101, 255]], np.uint8), mode="raw")
    np.testing.assert_array_equal(raw, [[0, 42, 100, -1, -1]])


def test_transparent_pixels_are_unknown():
    rgba = np.zeros((1, 3, 4), dtype=np.uint8)
    rgba[0, :, :3] = [[0, 0, 0], [254, 254, 254], [254, 254, 254]]
    rgba[0, :, 3] = [255, 255, 0]
    np.testing.assert_array_equal(image_to_occupancy(rgba), [[100, 0, -1]])


def test_yaml_image_path_is_relative_to_the_yaml(tmp_path, rng):
    m = OccupancyMap(_random_trinary(rng), 0.05, (0.0, 0.0, 0.0))
    write_map(tmp_path / "img" / "m.yaml", m)
    (tmp_path / "cfg").mkdir()
    (tmp_path / "cfg" / "m.yaml").write_text(map_yaml_text("../img/m.pgm", 0.05, (0.0, 0.0, 0.0)))
    assert read_map(tmp_path / "cfg" / "m.yaml").same_as(m)


def test_written_yaml_is_what_map_server_expects(tmp_path, rng):
    m = OccupancyMap(_random_trinary(rng), 0.05, (-1.5, -2.25, 0.0))
    write_map(tmp_path / "map.yaml", m)
    doc = yaml.safe_load((tmp_path / "map.yaml").read_text())
    assert doc == {
        "image": "map.pgm",
        "mode": "trinary",
        "resolution": 0.05,
        "origin": [-1.5, -2.25, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }


def test_write_refuses_to_replace_and_leaves_files_alone(tmp_path, rng):
    m = OccupancyMap(_random_trinary(rng), 0.05, (0.0, 0.0, 0.0))
    write_map(tmp_path / "map.yaml", m)
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    other = OccupancyMap(np.zeros(m.shape, np.int8), 0.05, (0.0, 0.0, 0.0))
    with pytest.raises(ConfigError, match="already exists"):
        write_map(tmp_path / "map.yaml", other)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before
    write_map(tmp_path / "map.yaml", other, overwrite=True)
    assert read_map(tmp_path / "map.yaml").same_as(other)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map.pgm", "map.yaml"]


def test_unsupported_image_type_writes_nothing(tmp_path, rng):
    m = OccupancyMap(_random_trinary(rng), 0.05, (0.0, 0.0, 0.0))
    with pytest.raises(ConfigError, match="unsupported image type"):
        write_map(tmp_path / "map.yaml", m, image="map.bmp")
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------------- errors
_GOOD = {
    "image": "map.pgm",
    "resolution": 0.05,
    "origin": [0.0, 0.0, 0.0],
    "negate": 0,
    "occupied_thresh": 0.65,
    "free_thresh": 0.196,
}


def _write_case(tmp_path: Path, **changes) -> Path:
    (tmp_path / "map.pgm").write_bytes(encode_pgm(np.full((4, 5), 254, np.uint8)))
    doc = {**_GOOD, **changes}
    doc = {k: v for k, v in doc.items() if v is not _DROP}
    path = tmp_path / "map.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


_DROP = object()


def test_good_case_reads(tmp_path):
    assert (read_map(_write_case(tmp_path)).occupancy == 0).all()


@pytest.mark.parametrize(
    ("changes", "key", "text"),
    [
        ({"resolution": _DROP}, "resolution", "missing required key"),
        ({"image": _DROP}, "image", "missing required key"),
        ({"resolution": "fine"}, "resolution", "expected a finite number"),
        ({"resolution": -0.05}, "resolution", "> 0"),
        ({"origin": [0.0, 0.0]}, "origin", "three numbers"),
        ({"origin": [0.0, "a", 0.0]}, "origin", "expected a finite number"),
        ({"negate": 2}, "negate", "0 or 1"),
        ({"free_thresh": 0.7}, "free_thresh", "must be smaller"),
        ({"occupied_thresh": 1.5}, "occupied_thresh", "[0, 1]"),
        ({"free_thresh": -0.1}, "free_thresh", "[0, 1]"),
        ({"mode": "fancy"}, "mode", "trinary"),
        ({"image": "nothere.pgm"}, "image", "not found"),
    ],
)
def test_bad_yaml_values_name_file_and_key(tmp_path, changes, key, text):
    path = _write_case(tmp_path, **changes)
    with pytest.raises(ConfigError) as info:
        read_map(path)
    msg = str(info.value)
    assert str(path) in msg and f"{key}:" in msg and text in msg


@pytest.mark.parametrize(
    "content", ["image: map.pgm\nresolution: [0.05\n", "- just\n- a list\n", "", "\tbad: tab\n"]
)
def test_malformed_yaml(tmp_path, content):
    path = tmp_path / "map.yaml"
    path.write_text(content)
    with pytest.raises(ConfigError) as info:
        read_map(path)
    assert str(path) in str(info.value)


def test_missing_yaml(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        read_map(tmp_path / "nope.yaml")


@pytest.mark.parametrize(
    ("payload", "text"),
    [
        (b"P5\n5 4\n255\n" + bytes(7), "image size inconsistent"),
        (b"P2\n2 2\n255\n1 2 3\n", "image size inconsistent"),
        (b"P5\n0 4\n255\n", "empty"),
        (b"P5\nfive 4\n255\n" + bytes(20), "malformed PGM header"),
        (b"P2\n2 1\n100\n1 200\n", "exceed"),
        (b"not an image at all", "cannot read the map image"),
        (b"", "cannot read the map image"),
    ],
)
def test_bad_images_raise_data_error(tmp_path, payload, text):
    path = _write_case(tmp_path)
    (tmp_path / "map.pgm").write_bytes(payload)
    with pytest.raises(DataError) as info:
        read_map(path)
    assert text in str(info.value) and "map.pgm" in str(info.value)
