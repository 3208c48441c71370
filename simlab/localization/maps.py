"""Maps to localize on: the arena's own raster, loading a map file, and checking that a
map belongs to the arena it is used in.

A map made in another arena (or shifted, or of another size) would make the particle
filter converge to nonsense without any error, so :func:`check_map_matches_arena`
compares the two before anything runs:

1. **provenance** — ``simlab map`` writes ``exploration.json`` beside ``map.yaml`` with
   the arena's name and file hash; a different name is an error at once;
2. **content** — the map's occupied cells must lie on the arena's walls and obstacles
   (*precision*: the fraction of occupied map cells bordering free ones - the surfaces a
   LIDAR maps - within ``tolerance`` of an occupied cell of the arena raster) and the arena's wall and obstacle surfaces that the map
   observed must be mapped as occupied (*recall*: the fraction of surface cells of the
   raster, among those the map knows, within ``tolerance`` of an occupied map cell).
   Both must reach ``min_score``. A map made without an obstacle fails the recall, a map
   with an obstacle the arena lacks (or shifted walls) fails the precision.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage

from discretize.gridmap import FREE, OCCUPIED, OccupancyMap
from simlab.base.errors import ConfigError


def arena_map(arena: Any, resolution: float = 0.01, margin: float = 0.1) -> OccupancyMap:
    """The arena's exact geometry as an occupancy map: walls, outside and obstacles occupied.

    ``margin`` (m) of occupied cells beyond the inner area on each side; origin yaw 0.
    """
    x0, y0, x1, y1 = arena.bounds
    w = math.ceil((x1 - x0 + 2 * margin) / resolution)
    h = math.ceil((y1 - y0 + 2 * margin) / resolution)
    origin = (x0 - margin, y0 - margin)
    occupied = arena.rasterize(resolution, origin, (h, w))
    occ = np.where(occupied, OCCUPIED, FREE).astype(np.int8)
    return OccupancyMap(occ, resolution, (origin[0], origin[1], 0.0))


@dataclass(frozen=True)
class MapCheck:
    """How well a map agrees with an arena's geometry (fractions in [0, 1], NaN if no cell).

    ``provenance_arena`` is the arena named by the map's ``exploration.json`` (None if
    there is none).
    """

    precision: float
    recall: float
    n_occupied: int
    n_surface_known: int
    provenance_arena: str | None
    tolerance: float

    def as_dict(self) -> dict[str, Any]:
        return {
            "precision": None if math.isnan(self.precision) else self.precision,
            "recall": None if math.isnan(self.recall) else self.recall,
            "n_occupied": self.n_occupied,
            "n_surface_known": self.n_surface_known,
            "provenance_arena": self.provenance_arena,
            "tolerance_m": self.tolerance,
        }


def map_provenance(map_yaml: str | os.PathLike[str]) -> dict[str, Any] | None:
    """The ``exploration.json`` written beside a map by ``simlab map`` (None if absent)."""
    meta = Path(map_yaml).with_name("exploration.json")
    if not meta.is_file():
        return None
    try:
        doc = json.loads(meta.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError):
        return None
    return doc if isinstance(doc, dict) else None


def map_agreement(grid: OccupancyMap, arena: Any, tolerance: float = 0.03) -> MapCheck:
    """Precision and recall of ``grid`` against ``arena``'s geometry (see the module doc)."""
    truth = np.asarray(arena.occupied(grid.pixel_centres()), dtype=bool).reshape(grid.shape)
    ring = np.ones((3, 3), dtype=bool)
    # Occupied map cells next to free ones: the surfaces a LIDAR sees (a raster map's solid
    # walls and outside would otherwise drown the obstacles in the count).
    mapped = (grid.occupancy >= 65) & ndimage.binary_dilation(grid.occupancy == 0, ring)
    known = grid.occupancy >= 0
    k = max(1, round(tolerance / grid.resolution))
    box = np.ones((2 * k + 1, 2 * k + 1), dtype=bool)
    near_truth = ndimage.binary_dilation(truth, box)
    near_mapped = ndimage.binary_dilation(mapped, box)
    surface = truth & ndimage.binary_dilation(~truth, ring)
    # A surface cell counts when the map knows something about its neighbourhood.
    surface_known = surface & ndimage.binary_dilation(known, box)
    n_occ = int(mapped.sum())
    n_surf = int(surface_known.sum())
    precision = float((mapped & near_truth).sum() / n_occ) if n_occ else float("nan")
    recall = float((surface_known & near_mapped).sum() / n_surf) if n_surf else float("nan")
    return MapCheck(precision, recall, n_occ, n_surf, None, tolerance)


def check_map_matches_arena(grid: OccupancyMap, arena: Any,
                            path: str | os.PathLike[str] | None = None, *,
                            tolerance: float = 0.03, min_score: float = 0.9) -> MapCheck:
    """Raise :class:`ConfigError` naming ``path`` if the map was not made in ``arena``."""
    prov = map_provenance(path) if path is not None else None
    prov_arena = None if prov is None else prov.get("arena")
    if prov_arena is not None and prov_arena != arena.name:
        raise ConfigError(
            f"this map was made in the arena {prov_arena!r} (exploration.json), "
            f"not in {arena.name!r}",
            path=path, key="map",
            fix=f"make a map of {arena.name!r} with `simlab map --arena {arena.name}`",
        )
    check = map_agreement(grid, arena, tolerance)
    check = MapCheck(check.precision, check.recall, check.n_occupied, check.n_surface_known,
                     prov_arena, tolerance)
    if check.n_occupied == 0:
        raise ConfigError("the map has no occupied cell", path=path, key="map",
                          fix="use a map with walls (simlab map)")
    bad = []
    if not check.precision >= min_score:
        bad.append(f"only {check.precision:.0%} of its occupied cells lie on the arena's "
                   "walls and obstacles")
    if not math.isnan(check.recall) and not check.recall >= min_score:
        bad.append(f"only {check.recall:.0%} of the arena's wall and obstacle surfaces it "
                   "observed are occupied in it")
    if bad:
        raise ConfigError(
            f"the map does not match the arena {arena.name!r}: " + "; ".join(bad),
            path=path, key="map",
            fix=f"use a map made in {arena.name!r} (simlab map --arena {arena.name})",
        )
    return check


def load_map_for_arena(map_path: str | os.PathLike[str] | None, arena: Any,
                       resolution: float = 0.01) -> tuple[OccupancyMap, MapCheck | None]:
    """The map file ``map_path`` checked against ``arena``, or the arena's raster if None."""
    if map_path is None:
        return arena_map(arena, resolution), None
    from discretize.mapio import read_map

    grid = read_map(map_path)
    return grid, check_map_matches_arena(grid, arena, map_path)
