"""Speed of the discretize layer: ``state_of`` (poses/s) and occupancy updates (scans/s).

Each figure is compared with a baseline measured in the same run:

* ``Discretizer.state_of`` (cKDTree over the 41 centres of the table) against a
  brute-force numpy nearest-centre search (all pose-centre distances, argmin), in
  chunks of 100,000 poses;
* ``OccupancyGrid.integrate`` (numba kernel) against the same traversal run
  interpreted, beam by beam, in Python (``backend="python"``).

Scans are the exact ranges from random poses in the 1.5 m table to its walls plus
0.01 m Gaussian noise: 360 beams, as the LDS-01. Usage::

    python benchmarks/discretize_speed.py [--repeats 3] [--poses 1000000]

Prints the best time of each repeat and the spread (best..worst), since the machine
is shared.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np


def _table_scans(rng: np.random.Generator, n: int, half: float = 0.75):
    angles = np.arange(360) * (2 * math.pi / 360)
    scans = []
    for _ in range(n):
        x, y = rng.uniform(-half + 0.12, half - 0.12, size=2)
        yaw = rng.uniform(-math.pi, math.pi)
        theta = yaw + angles
        c, s = np.cos(theta), np.sin(theta)
        with np.errstate(divide="ignore"):
            tx = np.where(c > 0, (half - x) / c, np.where(c < 0, (-half - x) / c, np.inf))
            ty = np.where(s > 0, (half - y) / s, np.where(s < 0, (-half - y) / s, np.inf))
        ranges = np.minimum(tx, ty) + rng.normal(0.0, 0.01, size=360)
        scans.append((ranges, (x, y, yaw)))
    return angles, scans


def _timed(fn, repeats: int) -> list[float]:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return times


def _brute_force(centres: np.ndarray, xy: np.ndarray, chunk: int = 100_000) -> np.ndarray:
    out = np.empty(len(xy), dtype=np.int64)
    for start in range(0, len(xy), chunk):
        p = xy[start : start + chunk]
        d2 = ((p[:, None, :] - centres[None, :, :]) ** 2).sum(axis=2)
        out[start : start + chunk] = np.argmin(d2, axis=1)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--poses", type=int, default=1_000_000)
    parser.add_argument("--scans", type=int, default=500, help="scans for the numba kernel")
    parser.add_argument("--python-scans", type=int, default=10, help="scans for the baseline")
    args = parser.parse_args()

    from discretize.gridmap import OccupancyMap
    from discretize.occupancy import OccupancyGrid
    from discretize.voronoi import Discretizer

    rng = np.random.default_rng(0)

    # ---------------------------------------------------------------- state_of
    n = 200
    occ = np.full((n, n), 100, dtype=np.int8)
    occ[25:175, 25:175] = 0
    table = OccupancyMap(occ, 0.01, (-1.0, -1.0, 0.0))
    disc = Discretizer.from_map(table, 41)
    xy = rng.uniform(-0.75, 0.75, size=(args.poses, 2))
    ours = disc.state_of(xy)
    assert np.array_equal(ours, _brute_force(disc.centres, xy)), "state_of disagrees with brute force"
    t_tree = _timed(lambda: disc.state_of(xy), args.repeats)
    t_brute = _timed(lambda: _brute_force(disc.centres, xy), args.repeats)
    rate_tree = args.poses / min(t_tree)
    rate_brute = args.poses / min(t_brute)
    print(f"state_of, {disc.n_states} centres, {args.poses:,} poses")
    print(f"  cKDTree     : {rate_tree:12,.0f} poses/s  (best {min(t_tree):.3f} s, worst {max(t_tree):.3f} s)")
    print(f"  brute force : {rate_brute:12,.0f} poses/s  (best {min(t_brute):.3f} s, worst {max(t_brute):.3f} s)")
    print(f"  ratio       : {rate_tree / rate_brute:.1f}x")

    # --------------------------------------------------------------- occupancy
    angles, scans = _table_scans(rng, args.scans)

    def run(backend: str, count: int) -> OccupancyGrid:
        grid = OccupancyGrid.covering((-0.75, -0.75, 0.75, 0.75), 0.01, 0.25)
        for ranges, pose in scans[:count]:
            grid.integrate(ranges, angles, pose, 0.12, 3.5, backend=backend)
        return grid

    run("numba", 1)  # compile / load the cache outside the timing
    k = min(args.python_scans, args.scans)
    a, b = run("numba", k), run("python", k)
    assert np.array_equal(a.log_odds, b.log_odds), "backends disagree"
    t_numba = _timed(lambda: run("numba", args.scans), args.repeats)
    t_py = _timed(lambda: run("python", k), args.repeats)
    rate_numba = args.scans / min(t_numba)
    rate_py = k / min(t_py)
    print(f"occupancy update, 360 beams, 0.01 m cells ({args.scans} / {k} scans)")
    print(f"  numba kernel     : {rate_numba:10,.0f} scans/s  ({1e6 / rate_numba:.0f} us/scan; "
          f"best {min(t_numba):.3f} s, worst {max(t_numba):.3f} s)")
    print(f"  python per beam  : {rate_py:10,.1f} scans/s  ({1e3 / rate_py:.1f} ms/scan; "
          f"best {min(t_py):.3f} s, worst {max(t_py):.3f} s)")
    print(f"  ratio            : {rate_numba / rate_py:.0f}x")


if __name__ == "__main__":
    main()
