"""Does OpenCV read every map_server PGM as discretize.mapio's own reader does?

For each kind of PGM a map may come as (binary P5 and ASCII P2; maxval 255, below 255,
16-bit; comments in the header, also between its numbers), the script writes one file and
prints whether ``cv2.imread(path, cv2.IMREAD_UNCHANGED)`` (16-bit scaled to 8-bit the way
``read_image`` scales other 16-bit images) gives the same pixels as ``read_image``, and the
largest difference; then the time of both readers on a 2000 x 2000 P5 map.

Run: ``python benchmarks/pgm_reader.py``.
"""

from __future__ import annotations

import tempfile
import timeit
from pathlib import Path

import cv2
import numpy as np

from discretize.mapio import read_image


def _p5(img: np.ndarray, maxval: int, comment: bytes = b"") -> bytes:
    h, w = img.shape
    pixels = img.astype(">u2" if maxval > 255 else np.uint8).tobytes()
    return b"P5\n" + comment + f"{w} {h}\n{maxval}\n".encode() + pixels


def _p2(img: np.ndarray, maxval: int) -> bytes:
    h, w = img.shape
    rows = "\n".join(" ".join(str(int(v)) for v in row) for row in img)
    return f"P2\n# ascii\n{w} {h}\n{maxval}\n{rows}\n".encode()


def _opencv(path: Path) -> np.ndarray | None:
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is not None and img.dtype == np.uint16:
        img = np.rint(img.astype(np.float64) / 257.0).astype(np.uint8)
    return img


def main() -> None:
    rng = np.random.default_rng(0)
    img8 = rng.integers(0, 256, size=(37, 53)).astype(np.int64)
    img16 = rng.integers(0, 65536, size=(37, 53)).astype(np.int64)
    img100 = rng.integers(0, 101, size=(37, 53)).astype(np.int64)
    img1000 = rng.integers(0, 1001, size=(37, 53)).astype(np.int64)
    cases = {
        "P5 8-bit maxval 255 (map_saver)": _p5(img8, 255, b"# CREATOR: map_saver.cpp 0.050 m/pix\n"),
        "P5 8-bit maxval 100": _p5(img100, 100),
        "P5 16-bit maxval 65535": _p5(img16, 65535),
        "P5 16-bit maxval 1000": _p5(img1000, 1000),
        "P5 comment between width and height": (
            b"P5\n53 # width\n# a line of its own\n37\n255\n" + img8.astype(np.uint8).tobytes()),
        "P2 ASCII maxval 255": _p2(img8, 255),
        "P2 ASCII maxval 100": _p2(img100, 100),
    }
    print(f"OpenCV {cv2.__version__}")
    print(f"{'PGM':40s} {'same pixels':>12s} {'max |diff|':>11s}")
    with tempfile.TemporaryDirectory() as tmp:
        for name, data in cases.items():
            path = Path(tmp) / "map.pgm"
            path.write_bytes(data)
            ours = read_image(path)
            theirs = _opencv(path)
            if theirs is None:
                print(f"{name:40s} {'unread':>12s} {'-':>11s}")
                continue
            same = theirs.shape == ours.shape and np.array_equal(theirs, ours)
            diff = (int(np.abs(theirs.astype(int) - ours.astype(int)).max())
                    if theirs.shape == ours.shape else -1)
            print(f"{name:40s} {same!s:>12s} {diff:>11d}")
        big = Path(tmp) / "big.pgm"
        big.write_bytes(_p5(rng.integers(0, 256, size=(2000, 2000)), 255))
        n = 20
        t_ours = min(timeit.repeat(lambda: read_image(big), number=n, repeat=3)) / n
        t_cv = min(timeit.repeat(lambda: _opencv(big), number=n, repeat=3)) / n
        print(f"2000 x 2000 P5: read_image {t_ours * 1e3:.2f} ms, cv2.imread {t_cv * 1e3:.2f} ms")


if __name__ == "__main__":
    main()
