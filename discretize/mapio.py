"""Read and write maps in the ROS ``map_server`` format (``map.yaml`` + image).

The YAML file holds ``image`` (path, relative to the YAML's directory unless
absolute), ``resolution`` (m/pixel), ``origin`` ``[x, y, yaw]`` (world pose of the
lower-left pixel corner), ``negate`` (0/1), ``occupied_thresh``, ``free_thresh`` and
optionally ``mode`` (``trinary`` default, ``scale``, ``raw``). Images may be PGM
(binary ``P5`` or ASCII ``P2``, 8 or 16 bit, read here) or anything OpenCV reads
(PNG, ...); colour pixels are the mean of their colour channels.

Interpretation follows ROS 1 ``map_server``: with ``v`` the pixel value (0..255),
``p = (255 - v) / 255`` if ``negate == 0`` else ``v / 255``;

* trinary: occupied (100) if ``p > occupied_thresh``, free (0) if
  ``p < free_thresh``, else unknown (-1);
* scale: as trinary, but in-between values become ``int(1 + 98 * ratio)`` with
  ``ratio = (p - free_thresh) / (occupied_thresh - free_thresh)``;
* raw: the value itself (after ``negate``) when in 0..100, else unknown (as Nav2).

Decision where ROS versions disagree: an alpha channel is not averaged in with the
colours; a pixel that is not fully opaque reads as unknown (trinary and scale).

Writing produces what ``map_saver`` produces (trinary: occupied 0, free 254,
unknown 205, ``negate: 0``, thresholds 0.65 / 0.196), so reading gives back the same
occupancy exactly; ``mode="raw"`` stores occupancy values 0..100 (unknown 255) and
round-trips maps with intermediate values too. Both files are written atomically,
the image first and the YAML last, and existing files are never replaced unless
``overwrite=True``.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from discretize.gridmap import FREE, OCCUPIED, UNKNOWN, OccupancyMap
from simlab.base import validation
from simlab.base.errors import ConfigError, DataError
from simlab.base.io import NESTED_TOO_DEEPLY, atomic_write, atomic_write_text, ensure_new

MODES = ("trinary", "scale", "raw")
#: Pixel values ``map_saver`` writes in trinary mode.
SAVE_OCCUPIED = 0
SAVE_FREE = 254
SAVE_UNKNOWN = 205
#: Thresholds written with trinary maps (those of ``map_saver``); consistent with the
#: pixel values above: 205 reads p = 0.19608, between 0.196 and 0.65.
SAVE_OCCUPIED_THRESH = 0.65
SAVE_FREE_THRESH = 0.196

_REQUIRED_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")


@dataclass(frozen=True)
class MapYaml:
    """The parsed, validated content of a map_server YAML file.

    Attributes:
        path: the YAML file.
        image: absolute-or-resolved path of the image (relative paths are taken
            from the YAML's directory).
        resolution: metres per pixel.
        origin: ``(x, y, yaw)`` metres, radians.
        negate: whether white means occupied.
        occupied_thresh, free_thresh: probability thresholds in [0, 1].
        mode: ``"trinary"``, ``"scale"`` or ``"raw"``.
    """

    path: Path
    image: Path
    resolution: float
    origin: tuple[float, float, float]
    negate: bool
    occupied_thresh: float
    free_thresh: float
    mode: str = "trinary"


# ---------------------------------------------------------------------------- YAML
def read_map_yaml(path: str | os.PathLike[str]) -> MapYaml:
    """Parse and validate a map_server YAML file (the image is not read).

    Raises :class:`ConfigError` naming the file and key for malformed YAML,
    missing keys, wrong types or inconsistent thresholds; a missing image file
    raises :class:`ConfigError` too (the YAML points at nothing).
    """
    path = Path(path)
    validation.existing_file(path, what="map file", fix="give the path of a map.yaml")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not a text file ({exc.reason})", path=path) from None
    try:
        doc = yaml.safe_load(text)
    except RecursionError:
        raise ConfigError(NESTED_TOO_DEEPLY, path=path) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        raise ConfigError(f"malformed YAML{where}", path=path) from None
    if not isinstance(doc, dict):
        raise ConfigError(
            "expected a mapping of map_server keys",
            path=path,
            fix=f"the file needs the keys {', '.join(_REQUIRED_KEYS)}",
        )
    missing = [k for k in _REQUIRED_KEYS if k not in doc]
    if missing:
        raise ConfigError("missing required key", path=path, key=missing[0])

    image = doc["image"]
    if not isinstance(image, str) or not image.strip():
        raise ConfigError(f"expected a file name, got {image!r}", path=path, key="image")
    image_path = Path(image)
    if not image_path.is_absolute():
        image_path = path.parent / image_path

    resolution = validation.positive(doc["resolution"], "resolution", path=path)

    origin = doc["origin"]
    if not isinstance(origin, list | tuple) or len(origin) != 3:
        raise ConfigError(
            f"expected [x, y, yaw] (three numbers), got {origin!r}", path=path, key="origin"
        )
    origin_t = tuple(validation.number(v, "origin", path=path) for v in origin)

    negate = doc["negate"]
    if isinstance(negate, bool):
        negate_b = negate
    elif isinstance(negate, int) and negate in (0, 1):
        negate_b = bool(negate)
    else:
        raise ConfigError(f"expected 0 or 1, got {negate!r}", path=path, key="negate")

    occ_t = validation.probability(doc["occupied_thresh"], "occupied_thresh", path=path)
    free_t = validation.probability(doc["free_thresh"], "free_thresh", path=path)
    if free_t >= occ_t:
        raise ConfigError(
            f"free_thresh ({free_t}) must be smaller than occupied_thresh ({occ_t})",
            path=path,
            key="free_thresh",
        )

    mode = doc.get("mode", "trinary")
    if mode is None:
        mode = "trinary"
    if not isinstance(mode, str) or mode.lower() not in MODES:
        raise ConfigError(f"expected one of {', '.join(MODES)}, got {mode!r}", path=path, key="mode")

    return MapYaml(
        path=path,
        image=image_path,
        resolution=resolution,
        origin=origin_t,  # type: ignore[arg-type]
        negate=negate_b,
        occupied_thresh=occ_t,
        free_thresh=free_t,
        mode=mode.lower(),
    )


# --------------------------------------------------------------------------- images
_PNM_WS = b" \t\r\n\v\f"


def _parse_pnm(data: bytes, path: Path) -> np.ndarray:
    """Decode a P5 (binary) or P2 (ASCII) greymap into ``(H, W)`` uint8 pixels 0..255.

    Why not ``cv2.imread(path, cv2.IMREAD_UNCHANGED)``: measured by
    ``benchmarks/pgm_reader.py`` (OpenCV 5.0), it gives the same pixels for maxval 255 and
    65535, comments anywhere in the header and ASCII P2, but a P5 of any other maxval comes
    back unscaled (maxval 100: off by up to 155 of 255) and a P2 truncated (off by 1).
    map_server scales every maxval to 0..255 (ROS 1 through SDL_image, Nav2 through
    GraphicsMagick), and the occupancy thresholds assume that scale. Speed does not decide
    it: 0.8 ms here, 1.1 ms OpenCV for a 2000 x 2000 P5.
    """
    pos = 0

    def token() -> bytes:
        nonlocal pos
        while pos < len(data):
            if data[pos : pos + 1] in (b"#",):
                end = data.find(b"\n", pos)
                pos = len(data) if end < 0 else end + 1
            elif data[pos] in _PNM_WS:
                pos += 1
            else:
                break
        start = pos
        while pos < len(data) and data[pos] not in _PNM_WS and data[pos : pos + 1] != b"#":
            pos += 1
        return data[start:pos]

    magic = token()
    if magic not in (b"P5", b"P2"):
        raise DataError(f"{path}: not a PGM greymap (magic {magic[:8]!r}, expected P5 or P2)")
    try:
        width, height, maxval = int(token()), int(token()), int(token())
    except ValueError:
        raise DataError(f"{path}: malformed PGM header") from None
    if width <= 0 or height <= 0:
        raise DataError(f"{path}: image size {width} x {height} is empty")
    if not 0 < maxval < 65536:
        raise DataError(f"{path}: PGM maxval {maxval} outside 1..65535")
    n = width * height
    if magic == b"P5":
        pos += 1  # exactly one whitespace byte separates the header from the pixels
        dtype = np.dtype(np.uint8) if maxval < 256 else np.dtype(">u2")
        need = n * dtype.itemsize
        payload = data[pos : pos + need]
        if len(payload) != need:
            raise DataError(
                f"{path}: image size inconsistent: header says {width} x {height} "
                f"({need} bytes of pixels), file holds {len(payload)}"
            )
        img = np.frombuffer(payload, dtype=dtype).reshape(height, width)
    else:
        try:
            values = np.array(data[pos:].split(), dtype=np.int64)
        except ValueError:
            raise DataError(f"{path}: malformed ASCII PGM pixel data") from None
        if values.size != n:
            raise DataError(
                f"{path}: image size inconsistent: header says {width} x {height} "
                f"({n} pixels), file holds {values.size}"
            )
        img = values.reshape(height, width)
    if img.max(initial=0) > maxval:
        raise DataError(f"{path}: pixel values exceed the PGM maxval {maxval}")
    # Scale to 0..255 like any 8-bit image (exact for maxval 255).
    if maxval == 255:
        return img.astype(np.uint8)
    return np.rint(img.astype(np.float64) * (255.0 / maxval)).astype(np.uint8)


def read_image(path: str | os.PathLike[str]) -> np.ndarray:
    """Read a map image as ``(H, W)`` grey or ``(H, W, C)`` colour uint8 pixels.

    PGM files are parsed here (P5 and P2, any maxval, scaled to 0..255); other
    formats go through OpenCV (colour channels in BGR(A) order; 16-bit scaled to
    8-bit). Raises :class:`DataError` if the file is missing or unreadable.
    """
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: map image not found")
    data = path.read_bytes()
    if data[:2] in (b"P5", b"P2"):
        return _parse_pnm(data, path)
    import cv2

    buf = np.frombuffer(data, dtype=np.uint8)
    img = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED) if buf.size else None
    if img is None:
        raise DataError(f"{path}: cannot read the map image (not an image or unsupported format)")
    if img.dtype == np.uint16:
        img = np.rint(img.astype(np.float64) / 257.0).astype(np.uint8)
    elif img.dtype != np.uint8:
        raise DataError(f"{path}: unsupported pixel type {img.dtype}")
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    if img.ndim not in (2, 3) or img.shape[0] == 0 or img.shape[1] == 0:
        raise DataError(f"{path}: unsupported image shape {img.shape}")
    return img


def image_to_occupancy(
    img: np.ndarray,
    *,
    negate: bool = False,
    occupied_thresh: float = SAVE_OCCUPIED_THRESH,
    free_thresh: float = SAVE_FREE_THRESH,
    mode: str = "trinary",
) -> np.ndarray:
    """Interpret image pixels as ROS map_server does (see the module docstring).

    Args:
        img: ``(H, W)`` grey or ``(H, W, C)`` uint8 with C = 3 (colour) or 4 (colour
            + alpha, alpha last).
    Returns:
        ``(H, W)`` int8 occupancy (-1 unknown, 0 free, 100 occupied, 1..99 scale).
    """
    if mode not in MODES:
        raise ValueError(f"mode: expected one of {MODES}, got {mode!r}")
    img = np.asarray(img)
    alpha = None
    if img.ndim == 3:
        n_ch = img.shape[2]
        if n_ch in (2, 4):
            alpha = img[:, :, -1]
            colour = img[:, :, : n_ch - 1]
        else:
            colour = img
        # ROS averages the channels with integer division.
        value = colour.astype(np.int64).sum(axis=2) // colour.shape[2]
    else:
        value = img.astype(np.int64)
    if negate:
        value = 255 - value
    if mode == "raw":
        occ = np.where((value >= 0) & (value <= 100), value, UNKNOWN).astype(np.int8)
    else:
        p = (255.0 - value) / 255.0
        occ = np.full(value.shape, UNKNOWN, dtype=np.int8)
        if mode == "scale":
            ratio = (p - free_thresh) / (occupied_thresh - free_thresh)
            mid = (1.0 + 98.0 * ratio).astype(np.int64)
            between = (p >= free_thresh) & (p <= occupied_thresh)
            occ[between] = np.clip(mid[between], 1, 99).astype(np.int8)
        occ[p > occupied_thresh] = OCCUPIED
        occ[p < free_thresh] = FREE
    if alpha is not None and mode != "raw":
        occ[alpha < 255] = UNKNOWN
    return occ


def read_map(path: str | os.PathLike[str], *, flip_y: bool = False) -> OccupancyMap:
    """Load a map_server map (``map.yaml`` and its image) as an :class:`OccupancyMap`.

    ``flip_y`` flips the image vertically before use, for images stored bottom row first
    (some GMapping exports; :mod:`discretize.mapcheck` suggests it when centres or poses
    land on walls but would be free on the flipped image). ``origin`` keeps its meaning
    (the lower-left corner of the flipped image).

    Raises :class:`ConfigError` (bad YAML, keys, thresholds, missing image) or
    :class:`DataError` (unreadable or inconsistent image), naming the file.
    """
    meta = read_map_yaml(path)
    if not meta.image.is_file():
        raise ConfigError(
            f"map image {str(meta.image)!r} not found",
            path=meta.path,
            key="image",
            fix="a relative image path is taken from the YAML's directory",
        )
    img = read_image(meta.image)
    occ = image_to_occupancy(
        img,
        negate=meta.negate,
        occupied_thresh=meta.occupied_thresh,
        free_thresh=meta.free_thresh,
        mode=meta.mode,
    )
    if flip_y:
        occ = occ[::-1]
    return OccupancyMap(occupancy=occ, resolution=meta.resolution, origin=meta.origin)


# --------------------------------------------------------------------------- writing
def occupancy_to_image(occupancy: np.ndarray, mode: str = "trinary") -> np.ndarray:
    """Pixel values ``(H, W)`` uint8 that read back as ``occupancy`` (``negate: 0``).

    trinary: values >= 65 -> 0 (occupied), 0..19 -> 254 (free), the rest (unknown
    and 20..64) -> 205, as ``map_saver`` with its default thresholds; raw: the
    value itself, unknown -> 255.
    """
    occ = np.asarray(occupancy).astype(np.int64)
    if mode == "trinary":
        img = np.full(occ.shape, SAVE_UNKNOWN, dtype=np.uint8)
        img[(occ >= 0) & (occ < SAVE_FREE_THRESH * 100)] = SAVE_FREE
        img[occ >= SAVE_OCCUPIED_THRESH * 100] = SAVE_OCCUPIED
        return img
    if mode == "raw":
        return np.where(occ < 0, 255, occ).astype(np.uint8)
    raise ValueError(f"mode: can write 'trinary' or 'raw', got {mode!r}")


def encode_pgm(img: np.ndarray, comment: str | None = None) -> bytes:
    """Binary PGM (P5, maxval 255) bytes of an ``(H, W)`` uint8 image."""
    img = np.ascontiguousarray(img, dtype=np.uint8)
    if img.ndim != 2:
        raise ValueError(f"img: expected (H, W), got shape {img.shape}")
    head = "P5\n"
    if comment:
        head += "".join(f"# {line}\n" for line in comment.splitlines())
    head += f"{img.shape[1]} {img.shape[0]}\n255\n"
    return head.encode("ascii") + img.tobytes()


def _yaml_float(value: float) -> str:
    """A float literal YAML 1.1 (PyYAML, yaml-cpp) reads back to the same double."""
    text = repr(float(value))
    if "e" in text:
        mantissa, exp = text.split("e")
        if "." not in mantissa:
            mantissa += ".0"
        if exp[0] not in "+-":
            exp = "+" + exp
        text = f"{mantissa}e{exp}"
    return text


_PLAIN_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.\-/]*$")


def map_yaml_text(
    image: str,
    resolution: float,
    origin: tuple[float, float, float],
    *,
    mode: str = "trinary",
    negate: int = 0,
    occupied_thresh: float = SAVE_OCCUPIED_THRESH,
    free_thresh: float = SAVE_FREE_THRESH,
) -> str:
    """The text of a map_server YAML file (floats written so they read back exactly)."""
    import json

    image_text = image if _PLAIN_NAME.match(image) else json.dumps(image)
    origin_text = ", ".join(_yaml_float(v) for v in origin)
    return (
        f"image: {image_text}\n"
        f"mode: {mode}\n"
        f"resolution: {_yaml_float(resolution)}\n"
        f"origin: [{origin_text}]\n"
        f"negate: {int(negate)}\n"
        f"occupied_thresh: {_yaml_float(occupied_thresh)}\n"
        f"free_thresh: {_yaml_float(free_thresh)}\n"
    )


def write_map(
    path: str | os.PathLike[str],
    grid: OccupancyMap,
    *,
    image: str | None = None,
    mode: str = "trinary",
    overwrite: bool = False,
) -> tuple[Path, Path]:
    """Write ``grid`` as a map_server map: the image, then ``path`` (the YAML).

    Args:
        path: the YAML file to write (e.g. ``maps/table/map.yaml``).
        grid: the map.
        image: image file name, relative to the YAML's directory; default the
            YAML's stem + ``.pgm``. A ``.png`` suffix writes PNG (OpenCV).
        mode: ``"trinary"`` (``map_saver`` values; intermediate occupancy is
            thresholded at 20/65 %) or ``"raw"`` (exact for any occupancy).
        overwrite: replace existing files; otherwise existing ones raise
            :class:`ConfigError` before anything is written.
    Returns:
        ``(yaml_path, image_path)``.
    """
    path = Path(path)
    if mode not in ("trinary", "raw"):
        raise ConfigError(f"can write 'trinary' or 'raw', got {mode!r}", key="mode")
    image_name = image if image is not None else path.stem + ".pgm"
    image_path = path.parent / image_name
    if image_path.resolve() == path.resolve():
        raise ConfigError("the image and the YAML file would be the same file", path=path)
    ensure_new(path, overwrite=overwrite, what="map file")
    ensure_new(image_path, overwrite=overwrite, what="map image")
    pixels = occupancy_to_image(grid.occupancy, mode)
    suffix = image_path.suffix.lower()
    if suffix == ".pgm":
        payload = encode_pgm(
            pixels, comment=f"simlab occupancy map, {grid.resolution} m/pixel, mode {mode}"
        )
    elif suffix == ".png":
        import cv2

        ok, buf = cv2.imencode(".png", pixels)
        if not ok:  # pragma: no cover - OpenCV failure
            raise DataError(f"{image_path}: PNG encoding failed")
        payload = buf.tobytes()
    else:
        raise ConfigError(
            f"unsupported image type {suffix!r}", key="image", fix="use a .pgm or .png file name"
        )
    with atomic_write(image_path, "wb") as fh:
        fh.write(payload)
    text = map_yaml_text(image_name, grid.resolution, grid.origin, mode=mode)
    atomic_write_text(path, text)
    return path, image_path
