"""Wall boxes of an arena built from a realistic ~10 x 4 m lab map at 5 cm.

The map is synthetic but GMapping-like: outer walls 0.10 m thick with ragged (+-1 pixel)
faces, a partition with a door, furniture, single-pixel speckles in the free space, and
unknown pixels around. Prints the occupied pixel count, the merged box count, the
precision/recall of the boxes rasterised back onto the map, and load / world-build times.

    PYTHONPATH=$PWD python benchmarks/map_arena_boxes.py
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from discretize.gridmap import OccupancyMap
from discretize.mapio import write_map
from simlab.physics.arena import load_arena
from simlab.physics.world import World

RES = 0.05


def lab_map(seed: int = 0, speckles: float = 0.003) -> OccupancyMap:
    rng = np.random.default_rng(seed)
    h, w = int(5.0 / RES), int(11.0 / RES)
    occ = np.full((h, w), -1, np.int8)

    def fill(x0: float, y0: float, x1: float, y1: float, v: int) -> None:
        xs = (np.arange(w) + 0.5) * RES
        ys = (h - 1 - np.arange(h) + 0.5) * RES
        occ[np.ix_((ys >= y0) & (ys < y1), (xs >= x0) & (xs < x1))] = v

    fill(0.4, 0.4, 10.6, 4.6, 100)
    fill(0.5, 0.5, 10.5, 4.5, 0)
    fill(6.0, 0.5, 6.1, 2.5, 100)      # partition, door 2.5..3.5
    fill(6.0, 3.5, 6.1, 4.5, 100)
    for x0, y0, x1, y1 in [(2.0, 3.8, 4.0, 4.5), (0.5, 1.5, 0.9, 3.0), (8.0, 1.0, 8.6, 1.6),
                           (4.5, 0.5, 5.5, 0.9), (9.0, 3.9, 10.5, 4.5), (3.0, 2.0, 3.2, 2.2)]:
        fill(x0, y0, x1, y1, 100)      # desks, shelves, a cabinet, a chair leg
    # ragged wall faces: free pixels next to a wall flip to occupied at random, and back
    wall = occ == 100
    near = np.zeros_like(wall)
    near[1:, :] |= wall[:-1, :]
    near[:-1, :] |= wall[1:, :]
    near[:, 1:] |= wall[:, :-1]
    near[:, :-1] |= wall[:, 1:]
    occ[(occ == 0) & near & (rng.random(occ.shape) < 0.3)] = 100
    occ[(occ == 0) & (rng.random(occ.shape) < speckles)] = 100
    fill(1.0, 1.0, 1.4, 1.4, 0)        # start area
    fill(4.9, 1.9, 5.1, 2.1, 0)        # goal centre
    return OccupancyMap(occ, RES, (-1.0, -0.5, 0.0))


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        grid = lab_map()
        write_map(Path(tmp) / "lab.yaml", grid)
        toml = Path(tmp) / "lab.toml"
        toml.write_text('name = "lab"\n[map]\nyaml = "lab.yaml"\n[walls]\nheight = 0.25\n'
                        'thickness = 0.05\n[start]\npose = [0.2, 0.7, 90.0]\n[[goals]]\n'
                        'name = "g"\ncenter = [4.0, 1.5]\nradius = 0.3\n')
        t0 = time.perf_counter()
        arena = load_arena(toml)
        t_load = time.perf_counter() - t0
        occupied = grid.occupancy >= 65
        h, w = grid.occupancy.shape
        gx, gy = np.meshgrid(grid.origin[0] + (np.arange(w) + 0.5) * RES,
                             grid.origin[1] + (h - 1 - np.arange(h) + 0.5) * RES)
        built = np.zeros((h, w), bool)
        for x0, y0, x1, y1 in arena.map_walls.boxes:
            built |= (gx > x0) & (gx < x1) & (gy > y0) & (gy < y1)
        tp = (built & occupied).sum()
        t0 = time.perf_counter()
        with World(arena) as world:
            t_world = time.perf_counter() - t0
            t0 = time.perf_counter()
            for _ in range(20):
                world.reset()
            t_reset = (time.perf_counter() - t0) / 20
        x0, y0, x1, y1 = arena.bounds
        print(f"map {w} x {h} px at {RES} m ({(x1 - x0):.2f} x {(y1 - y0):.2f} m known), "
              f"{int(occupied.sum())} occupied px -> {len(arena.map_walls.boxes)} boxes; "
              f"precision {tp / built.sum():.4f}, recall {tp / occupied.sum():.4f}; "
              f"load {t_load * 1e3:.0f} ms, first World {t_world * 1e3:.0f} ms, "
              f"reset {t_reset * 1e3:.1f} ms")


if __name__ == "__main__":
    main()
