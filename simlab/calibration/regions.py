"""The signature of a count table per region of the lab: open space, corridor, near a wall.

One distance over the whole lab says how far a twin is, not where. A robot's moves differ most
with what lies ahead of it: in the ISIR lab the robot stays in its cell in 11 % of its moves
with over a metre of free floor ahead and in 55 % with a wall within 0.6 m, and what it does
at a wall (stay, slide to a side, back off) is where a twin is hardest to get right. So each
real ``(s, a)`` pair is put in a **region** by the free floor along the action's heading from
the state's centre (:func:`pair_regions`), measured in the arena (walls, map walls,
obstacles: :meth:`~simlab.physics.arena.ArenaConfig.occupied`):

* ``wall``: an obstacle within one cell (the median distance between neighbouring centres)
  ahead: the move ends at or against it;
* ``corridor``: free ahead, but obstacles within one cell on both sides of the heading;
* ``open``: the rest.

:func:`region_signature` gives, per region, the real transitions, the share that stay in
their state, end ahead (within 67.5 degrees of the heading, seen from the state's centre),
to a side (up to 112.5 degrees) or behind, the mean next-state entropy and the
visit-weighted TV distance of a twin on that region's pairs, so a report can show them side by
side.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

REGIONS = ("open", "corridor", "wall")

#: Bounds of the outcome classes (rad from the action's heading): ahead, side, behind.
_AHEAD, _SIDE = math.radians(67.5), math.radians(112.5)


def free_distance(arena: Any, xy: ArrayLike, headings: ArrayLike, reach: float,
                  step: float = 0.02) -> NDArray[np.float64]:
    """(n,) free floor (m) from points ``xy`` (n, 2) along ``headings`` (n,) rad, up to
    ``reach`` (m), sampled every ``step`` m (``reach`` when nothing is met)."""
    p = np.asarray(xy, dtype=np.float64)
    h = np.asarray(headings, dtype=np.float64)
    d = np.arange(step, reach + step / 2, step)
    pts = p[:, None, :] + d[None, :, None] * np.stack([np.cos(h), np.sin(h)], axis=1)[:, None]
    hit = np.asarray(arena.occupied(pts), dtype=bool)
    first = np.where(hit.any(axis=1), hit.argmax(axis=1), d.size)
    return np.where(first < d.size, d[np.minimum(first, d.size - 1)] - step, reach)


def pair_regions(arena: Any, centres: ArrayLike, headings: ArrayLike,
                 cell: float) -> NDArray[np.int64]:
    """(S, A) region index (:data:`REGIONS`) of each state and action heading (rad, (A,)),
    with ``cell`` the cell size (m)."""
    c = np.asarray(centres, dtype=np.float64)
    h = np.asarray(headings, dtype=np.float64)
    S, A = len(c), len(h)
    xy = np.repeat(c, A, axis=0)
    hh = np.tile(h, S)
    reach = 1.5 * cell
    ahead = free_distance(arena, xy, hh, reach).reshape(S, A)
    left = free_distance(arena, xy, hh + math.pi / 2, reach).reshape(S, A)
    right = free_distance(arena, xy, hh - math.pi / 2, reach).reshape(S, A)
    out = np.zeros((S, A), dtype=np.int64)
    out[(left < cell) & (right < cell)] = REGIONS.index("corridor")
    out[ahead < cell] = REGIONS.index("wall")
    return out


def outcome_classes(centres: NDArray[np.float64], headings: NDArray[np.float64]
                     ) -> NDArray[np.int64]:
    """(S, A, S) class of each outcome: 0 stay, 1 ahead, 2 side, 3 behind."""
    S = len(centres)
    v = centres[None, :, :] - centres[:, None, :]                  # (S, S', 2)
    bearing = np.arctan2(v[..., 1], v[..., 0])                      # (S, S')
    off = np.abs((bearing[:, None, :] - headings[None, :, None] + math.pi)
                 % (2 * math.pi) - math.pi)                         # (S, A, S')
    cls = np.where(off <= _AHEAD, 1, np.where(off <= _SIDE, 2, 3))
    cls[np.arange(S), :, np.arange(S)] = 0
    return cls.astype(np.int64)


def region_signature(counts: ArrayLike, regions: NDArray[np.int64], centres: ArrayLike,
                     headings: ArrayLike, tv_per_pair: ArrayLike | None = None,
                     weights: ArrayLike | None = None) -> list[dict[str, Any]]:
    """Per region of :data:`REGIONS`: ``pairs`` and ``transitions`` of ``counts`` (S, A, S)
    there, the shares of its transitions that ``stay``, end ``ahead``, to a ``side`` or
    ``behind``, the visit-weighted mean next-state ``entropy`` (bits), and with
    ``tv_per_pair`` (S, A) the mean ``tv`` weighted by ``weights`` (S, A) (the real visits;
    NaN pairs, untried by the twin, count as 1)."""
    n = np.asarray(counts, dtype=np.float64)
    cls = outcome_classes(np.asarray(centres, dtype=np.float64),
                           np.asarray(headings, dtype=np.float64))
    n_sa = n.sum(axis=2)
    p = n / np.maximum(n_sa, 1.0)[..., None]
    with np.errstate(divide="ignore", invalid="ignore"):
        h = -np.where(p > 0, p * np.log2(np.where(p > 0, p, 1.0)), 0.0).sum(axis=2)
    out = []
    for k, name in enumerate(REGIONS):
        m = regions == k
        total = float(n_sa[m].sum())
        row: dict[str, Any] = {"region": name, "pairs": int((m & (n_sa > 0)).sum()),
                               "transitions": int(total)}
        for j, label in enumerate(("stay", "ahead", "side", "behind")):
            row[label] = float((n[m] * (cls[m] == j)).sum() / total) if total else None
        row["entropy"] = float((h[m] * n_sa[m]).sum() / total) if total else None
        if tv_per_pair is not None:
            w = np.asarray(weights, dtype=np.float64)[m]
            tv = np.nan_to_num(np.asarray(tv_per_pair, dtype=np.float64)[m], nan=1.0)
            row["tv"] = float((w * tv).sum() / w.sum()) if w.sum() > 0 else None
        out.append(row)
    return out
