"""Occupancy maps, the ROS map_server format and Voronoi state discretization.

This package knows nothing of PyBullet (the exploration run that feeds it scans is
:mod:`simlab.orchestration.mapping`). Modules:

* :mod:`discretize.gridmap` — :class:`OccupancyMap`, the map object (map_server
  orientation, world/pixel conversions, content hash);
* :mod:`discretize.mapio` — read/write ``map.yaml`` + PGM/PNG images;
* :mod:`discretize.occupancy` — log-odds grid updated from range scans;
* :mod:`discretize.voronoi` — :class:`Discretizer`: centres, numbering, ``state_of``;
* :mod:`discretize.plot` — the thesis Fig. 3.5 style figure.
"""

from __future__ import annotations

from discretize.gridmap import FREE, OCCUPIED, UNKNOWN, OccupancyMap
from discretize.mapio import read_map, write_map

__all__ = ["FREE", "OCCUPIED", "UNKNOWN", "OccupancyMap", "read_map", "write_map"]
