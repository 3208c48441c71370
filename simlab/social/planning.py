"""A small grid path planner for GO_TO_HUMAN's drive (thesis 2.1.3).

The grid's GO_TO_HUMAN places the robot in front of the human; in physics the robot must
drive there with its 8-direction primitives around the arena's obstacles and the human.
:func:`plan_path` runs Dijkstra on an 8-connected grid of ``step`` m over the table, whose
free nodes keep ``clearance`` m from walls and obstacles (analytic, from the arena
description: :func:`simlab.social.human.is_free`) and from extra discs (the human); a
diagonal step is refused if either orthogonal neighbour is blocked (no corner cutting).
The path's moves are the 8 primitive directions, so the primitives follow it exactly up to
their own heading error. Waypoints are the path's turning points.

The arena's part of the free grid is the same on every call of a run, so it is computed
once per (arena geometry, clearance, step) and kept (:func:`_static_free`); the discs,
which move, are applied on top of it with numpy on each call.
"""

from __future__ import annotations

import functools
import heapq
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.physics.arena import ArenaConfig
from simlab.social.human import is_free

_MOVES = ((1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1))


@dataclass(frozen=True)
class _StaticGrid:
    """The cache key of :func:`_static_free`: the arena's geometry as :func:`is_free` reads
    it (centre, size, obstacles, map wall boxes; plain floats, so always hashable), the
    clearance and the step. ``arena`` rides along for the computation but is left out of
    the key (an ArenaConfig holds a map's wall array and need not be hashable)."""

    geometry: tuple[Any, ...]
    clearance: float
    step: float
    arena: ArenaConfig = field(compare=False, hash=False, repr=False)


def _geometry(arena: ArenaConfig) -> tuple[Any, ...]:
    obstacles = tuple((ob.kind, float(ob.x), float(ob.y), tuple(float(v) for v in ob.size),
                       float(ob.yaw), float(ob.radius)) for ob in arena.obstacles)
    walls = None if arena.map_walls is None else tuple(
        tuple(float(v) for v in box) for box in arena.map_walls.boxes)
    return (tuple(float(v) for v in arena.center), tuple(float(v) for v in arena.size),
            obstacles, walls)


@functools.lru_cache(maxsize=16)
def _static_free(key: _StaticGrid
                 ) -> tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64]]:
    """The arena's free nodes (no discs) and node coordinates, read-only: the same for
    every GO_TO_HUMAN of a run, so computed once (one :func:`is_free` per node) and
    kept, keyed by value: an equal arena loaded again hits the entry, a changed one
    cannot."""
    arena, clearance, step = key.arena, key.clearance, key.step
    cx, cy = arena.center
    nx, ny = (max(1, math.floor(arena.size[k] / step)) for k in (0, 1))
    xs = cx - arena.size[0] / 2 + (np.arange(nx) + 0.5) * arena.size[0] / nx
    ys = cy - arena.size[1] / 2 + (np.arange(ny) + 0.5) * arena.size[1] / ny
    free = np.zeros((nx, ny), dtype=bool)
    for i, x in enumerate(xs):
        for j, y in enumerate(ys):
            free[i, j] = is_free(arena, (x, y), clearance)
    for a in (free, xs, ys):
        a.setflags(write=False)
    return free, xs, ys


def _outside_disc(xs: NDArray[np.float64], ys: NDArray[np.float64],
                  centre: NDArray[np.float64], radius: float, clearance: float
                  ) -> NDArray[np.bool_]:
    """Nodes (nx, ny) farther than ``radius + clearance`` (m) from ``centre``.

    ``np.hypot`` (libm) and ``math.hypot`` (Python's own) may round differently in the
    last bit, so the nodes within a relative 1e-9 of the bound are decided by
    ``math.hypot``, as the node-by-node grid always did: the same booleans, ties included."""
    bound = radius + clearance
    d = np.hypot(xs[:, None] - centre[0], ys[None, :] - centre[1])
    out = d > bound
    for i, j in np.argwhere(np.abs(d - bound) <= 1e-9 * max(1.0, abs(bound))):
        out[i, j] = math.hypot(xs[i] - centre[0], ys[j] - centre[1]) > bound
    return out


def free_grid(arena: ArenaConfig, clearance: float, step: float,
              discs: Sequence[tuple[NDArray[np.float64], float]] = ()
              ) -> tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64]]:
    """Free nodes (nx, ny) bool and the node coordinates xs (nx,), ys (ny,) in m (fresh
    arrays: the caller may write them). A node is free when a disc of ``clearance`` m
    there is (:func:`is_free`) and it is more than ``radius + clearance`` from every disc
    ``(centre (2,), radius)``. The arena part is cached (:func:`_static_free`)."""
    key = _StaticGrid(_geometry(arena), float(clearance), float(step), arena)
    static, xs, ys = _static_free(key)
    free = static.copy()
    for centre, r in discs:
        free &= _outside_disc(xs, ys, centre, r, clearance)
    return free, xs.copy(), ys.copy()


def _nearest_free(free: NDArray[np.bool_], xs: NDArray[np.float64], ys: NDArray[np.float64],
                  xy: NDArray[np.float64]) -> tuple[int, int] | None:
    idx = np.argwhere(free)
    if idx.size == 0:
        return None
    d = (xs[idx[:, 0]] - xy[0]) ** 2 + (ys[idx[:, 1]] - xy[1]) ** 2
    i, j = idx[int(np.argmin(d))]
    return int(i), int(j)


def plan_path(arena: ArenaConfig, start: NDArray[np.float64], goal: NDArray[np.float64],
              clearance: float, step: float = 0.05,
              discs: Sequence[tuple[NDArray[np.float64], float]] = ()
              ) -> list[NDArray[np.float64]] | None:
    """Waypoints (each (2,), m) from ``start`` to the free node nearest ``goal`` (the
    last waypoint is ``goal`` itself when it is free), or None if no path exists.

    ``discs``: extra round obstacles ``(centre (2,), radius)``.
    """
    free, xs, ys = free_grid(arena, clearance, step, discs)
    s = _nearest_free(free, xs, ys, start)
    g = _nearest_free(free, xs, ys, goal)
    if s is None or g is None:
        return None
    dist = {s: 0.0}
    prev: dict[tuple[int, int], tuple[int, int]] = {}
    heap = [(0.0, s)]
    nx, ny = free.shape
    while heap:
        d, node = heapq.heappop(heap)
        if node == g:
            break
        if d > dist.get(node, math.inf):
            continue
        i, j = node
        for di, dj in _MOVES:
            a, b = i + di, j + dj
            if not (0 <= a < nx and 0 <= b < ny and free[a, b]):
                continue
            if di and dj and not (free[i + di, j] and free[i, j + dj]):
                continue
            nd = d + (math.sqrt(2.0) if di and dj else 1.0)
            if nd < dist.get((a, b), math.inf):
                dist[(a, b)] = nd
                prev[(a, b)] = node
                heapq.heappush(heap, (nd, (a, b)))
    if g not in dist:
        return None
    nodes = [g]
    while nodes[-1] != s:
        nodes.append(prev[nodes[-1]])
    nodes.reverse()
    points = [np.array([xs[i], ys[j]]) for i, j in nodes]
    # keep the turning points (and the first node when the start is off the grid)
    way = [points[k] for k in range(1, len(points) - 1)
           if tuple(np.subtract(nodes[k + 1], nodes[k])) != tuple(np.subtract(nodes[k],
                                                                              nodes[k - 1]))]
    way.insert(0, points[0])
    goal = np.asarray(goal, dtype=float)
    gi, gj = g
    last = goal if math.hypot(goal[0] - xs[gi], goal[1] - ys[gj]) < step else points[-1]
    way.append(last)
    return way


def segment_free(arena: ArenaConfig, a: NDArray[np.float64], b: NDArray[np.float64],
                 clearance: float, spacing: float = 0.01) -> bool:
    """Whether a disc of radius ``clearance`` (m) moved along the segment ``a`` -> ``b``
    ((2,) m) stays free (:func:`~simlab.social.human.is_free`), sampled every ``spacing``
    m, both ends included. Analytic, from the arena description (no ray test), as the
    planner's free grid."""
    a, b = np.asarray(a, dtype=float)[:2], np.asarray(b, dtype=float)[:2]
    n = max(1, math.ceil(math.hypot(*(b - a)) / spacing))
    return all(is_free(arena, a + (b - a) * (k / n), clearance) for k in range(n + 1))


def first_leg_bearing(arena: ArenaConfig, start: NDArray[np.float64],
                      goal: NDArray[np.float64], clearance: float, step: float = 0.05
                      ) -> float | None:
    """Direction (rad) of the first leg of :func:`plan_path` from ``start`` to ``goal``:
    from its first waypoint (the free node nearest ``start``) to its second (the first
    turning point, or the goal), so one of the planner's 8 moves; None without a path
    (or when start and goal share a node)."""
    path = plan_path(arena, np.asarray(start, dtype=float), np.asarray(goal, dtype=float),
                     clearance, step)
    if path is None or len(path) < 2:
        return None
    d = path[1] - path[0]
    if math.hypot(d[0], d[1]) < 1e-9:
        return None
    return math.atan2(d[1], d[0])
