"""The occupancy map object shared by mapping, map files and the discretizer.

Conventions (those of the ROS ``map_server``, so real-robot maps load unchanged):

* ``occupancy`` is an ``(H, W)`` int8 array: ``-1`` unknown, ``0`` free, ``100``
  occupied (values ``1..99`` appear only in maps read in ``scale``/``raw`` mode).
* Row 0 is the **top** of the image (largest y), column 0 the left (smallest x).
* ``origin = (x, y, yaw)`` is the world pose (metres, radians) of the lower-left
  corner of the lower-left pixel; the map is rotated by ``yaw`` about that point.
  Maps from GMapping and from :mod:`simlab.orchestration.mapping` have ``yaw = 0``.
* Pixel ``(row, col)`` covers, in the map's own (unrotated) frame,
  ``x in [col*res, (col+1)*res)`` and ``y in [(H-1-row)*res, (H-row)*res)``
  measured from the origin.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

#: Occupancy values of a trinary map.
UNKNOWN = -1
FREE = 0
OCCUPIED = 100


@dataclass(frozen=True, eq=False)
class OccupancyMap:
    """A 2-D occupancy grid in map_server orientation.

    Attributes:
        occupancy: ``(H, W)`` int8, ``-1`` unknown, ``0`` free, ``100`` occupied
            (``1..99`` = intermediate occupancy in percent). Stored read-only.
        resolution: side of one pixel in metres (> 0).
        origin: ``(x, y, yaw)`` world pose of the lower-left image corner
            (metres, radians).
    """

    occupancy: np.ndarray
    resolution: float
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        occ = np.asarray(self.occupancy)
        if occ.ndim != 2 or occ.shape[0] < 1 or occ.shape[1] < 1:
            raise ValueError(f"occupancy: expected a non-empty (H, W) array, got shape {occ.shape}")
        if not np.issubdtype(occ.dtype, np.integer):
            raise ValueError(f"occupancy: expected integers, got dtype {occ.dtype}")
        if occ.size and (occ.min() < -1 or occ.max() > 100):
            raise ValueError("occupancy: values must lie in -1..100")
        occ = np.array(occ, dtype=np.int8, copy=True)
        occ.setflags(write=False)
        object.__setattr__(self, "occupancy", occ)
        res = float(self.resolution)
        if not np.isfinite(res) or res <= 0:
            raise ValueError(f"resolution: expected a finite number > 0, got {self.resolution!r}")
        object.__setattr__(self, "resolution", res)
        origin = tuple(float(v) for v in self.origin)
        if len(origin) != 3 or not all(np.isfinite(origin)):
            raise ValueError(f"origin: expected three finite numbers (x, y, yaw), got {self.origin!r}")
        object.__setattr__(self, "origin", origin)

    # ------------------------------------------------------------------ shape
    @property
    def shape(self) -> tuple[int, int]:
        """``(H, W)`` in pixels."""
        return self.occupancy.shape  # type: ignore[return-value]

    @property
    def height(self) -> int:
        return self.occupancy.shape[0]

    @property
    def width(self) -> int:
        return self.occupancy.shape[1]

    # ------------------------------------------------------------------ masks
    def free_mask(self) -> np.ndarray:
        """``(H, W)`` bool, True where the map is free (occupancy 0)."""
        return self.occupancy == FREE

    def occupied_mask(self, threshold: int = 65) -> np.ndarray:
        """``(H, W)`` bool, True where occupancy >= ``threshold`` percent."""
        return self.occupancy >= threshold

    def unknown_mask(self) -> np.ndarray:
        """``(H, W)`` bool, True where the map is unknown (occupancy -1)."""
        return self.occupancy == UNKNOWN

    # ------------------------------------------------------------ coordinates
    def _rotation(self) -> tuple[float, float]:
        yaw = self.origin[2]
        return float(np.cos(yaw)), float(np.sin(yaw))

    def world_to_pixel_float(self, xy: np.ndarray) -> np.ndarray:
        """Continuous image coordinates ``(..., 2)`` as ``(row, col)`` of world points.

        ``xy`` is ``(..., 2)`` in metres. The centre of pixel ``(r, c)`` maps to
        ``(r + 0.5, c + 0.5)``; ``floor`` gives the pixel containing the point.
        """
        xy = np.asarray(xy, dtype=np.float64)
        c, s = self._rotation()
        dx = xy[..., 0] - self.origin[0]
        dy = xy[..., 1] - self.origin[1]
        # Inverse rotation into the map's own frame.
        mx = c * dx + s * dy
        my = -s * dx + c * dy
        col = mx / self.resolution
        row = self.height - my / self.resolution
        return np.stack([row, col], axis=-1)

    def world_to_pixel(self, xy: np.ndarray) -> np.ndarray:
        """Integer ``(row, col)`` (int64, ``(..., 2)``) of the pixel containing each point.

        Points outside the image get indices outside ``[0, H) x [0, W)``; check
        with :meth:`in_bounds`.
        """
        return np.floor(self.world_to_pixel_float(xy)).astype(np.int64)

    def pixel_to_world(self, rc: np.ndarray) -> np.ndarray:
        """World coordinates ``(..., 2)`` (metres) of the centres of pixels ``rc`` (row, col)."""
        rc = np.asarray(rc, dtype=np.float64)
        mx = (rc[..., 1] + 0.5) * self.resolution
        my = (self.height - rc[..., 0] - 0.5) * self.resolution
        c, s = self._rotation()
        x = self.origin[0] + c * mx - s * my
        y = self.origin[1] + s * mx + c * my
        return np.stack([x, y], axis=-1)

    def in_bounds(self, rc: np.ndarray) -> np.ndarray:
        """Bool ``(...)``: which integer pixel indices ``(..., 2)`` lie inside the image."""
        rc = np.asarray(rc)
        return (
            (rc[..., 0] >= 0) & (rc[..., 0] < self.height) & (rc[..., 1] >= 0) & (rc[..., 1] < self.width)
        )

    def pixel_centres(self, mask: np.ndarray | None = None) -> np.ndarray:
        """World coordinates ``(K, 2)`` of the centres of the pixels where ``mask`` is True.

        Pixels come in row-major order (top row first). ``mask=None`` means all pixels.
        """
        if mask is None:
            mask = np.ones(self.shape, dtype=bool)
        rows, cols = np.nonzero(mask)
        return self.pixel_to_world(np.stack([rows, cols], axis=-1))

    def extent(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the image in metres (for ``imshow``; yaw 0 only)."""
        x0, y0, _ = self.origin
        return (x0, x0 + self.width * self.resolution, y0, y0 + self.height * self.resolution)

    # --------------------------------------------------------------- identity
    def content_hash(self) -> str:
        """SHA-256 (hex) of the map's content: shape, resolution, origin and occupancy.

        Independent of the file encoding (PGM/PNG, ``negate``, thresholds): two files
        that read to the same occupancy have the same hash.
        """
        h = hashlib.sha256()
        h.update(b"simlab-occupancy-map-v1\0")
        h.update(np.asarray(self.shape, dtype="<i8").tobytes())
        h.update(np.asarray([self.resolution, *self.origin], dtype="<f8").tobytes())
        h.update(np.ascontiguousarray(self.occupancy, dtype=np.int8).tobytes())
        return h.hexdigest()

    def same_as(self, other: OccupancyMap) -> bool:
        """True if both maps have identical occupancy, resolution and origin."""
        return (
            self.shape == other.shape
            and self.resolution == other.resolution
            and self.origin == other.origin
            and bool(np.array_equal(self.occupancy, other.occupancy))
        )
