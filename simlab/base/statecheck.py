"""States that belong together: centres against the arena, fingerprints where files meet.

A states file made for another arena, whose state count happens to match, was accepted
by ``collect`` (31 of 41 centres off the table) and ``replay`` (19.8 goals/h instead of
~160). Two checks stop it:

* :func:`check_centres_in_arena`: the centres must lie on the arena's floor, outside its
  obstacles and walls (:meth:`simlab.physics.arena.ArenaConfig.occupied`).
  Decision: a Voronoi centre is placed in eroded free space, so every centre of a matching
  states file is free; map-made states can put a centre or two on a mapping artefact, so
  up to :data:`MAX_BAD_FRACTION` of the centres only warn; more are refused.
* :func:`put_down`: the one rule of every command and env that sets the robot down: where
  it fits, the pose asked for, else the nearest free place (of the same state, for a walk
  that starts "at a state": :func:`start_in_state`, :func:`start_positions`; a centre in or
  against an obstacle, which the check above lets through). :func:`placed_pose` applies
  it to a pose.
* :func:`check_states_hash`: datasets (manifest ``discretizer.hash``), MDPs and Q-tables
  (``states_hash`` in their metadata) record the states fingerprint,
  :meth:`discretize.voronoi.Discretizer.content_hash`; wherever two of them meet, the
  fingerprints must agree (files without one, from older versions, are not checked).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from simlab.base.errors import ConfigError, warn

__all__ = ["MAX_BAD_FRACTION", "check_centres_in_arena", "check_states_hash",
           "npz_states_hash", "placed_pose", "put_down", "start_in_state", "start_positions"]

#: Largest fraction of centres off the floor or in obstacles that only warns.
MAX_BAD_FRACTION = 0.10


def check_centres_in_arena(centres: Any, arena: Any, *, source: str | None = None) -> int:
    """Refuse centres ``(S, 2)`` (m) that do not fit ``arena`` (an ``ArenaConfig``).

    Returns the number of centres off the floor or inside an obstacle/wall (0 when all
    fit; a few, up to :data:`MAX_BAD_FRACTION`, give a warning). Raises
    :class:`ConfigError` naming the states file and the first bad centres otherwise.
    """
    xy = np.asarray(centres, dtype=np.float64).reshape(-1, 2)
    if len(xy) == 0:
        return 0
    bad = np.flatnonzero(arena.occupied(xy))
    if bad.size == 0:
        return 0
    listed = ", ".join(f"{int(i)} ({xy[i, 0]:.2f}, {xy[i, 1]:.2f})" for i in bad[:4])
    text = (f"{bad.size} of {len(xy)} state centres lie off the floor or inside an obstacle "
            f"of arena {getattr(arena, 'name', '?')!r}: {listed}"
            + (" ..." if bad.size > 4 else ""))
    if bad.size > MAX_BAD_FRACTION * len(xy):
        raise ConfigError(text, path=source, key="centres",
                          fix="use the states made for this arena (simlab discretize)")
    warn(f"{source or 'states'}: {text}")
    return int(bad.size)


#: Spacing (m) of the positions :func:`put_down` tries and of the points of the robot's
#: footprint it checks.
START_GRID = 0.01
#: Radius (m) :func:`put_down` searches first: beyond a cell's size, within a few steps.
NEAR_SEARCH = 0.5


def _fits(xy: np.ndarray, footprint: tuple[float, float, float, float], arena: Any,
          yaw: float = 0.0) -> np.ndarray:
    """(k,) bool: the robot facing ``yaw`` (rad) at each position ``xy`` (k, 2) has its
    footprint rectangle ``(x_min, x_max, y_min, y_max)`` (m, robot frame) clear of walls,
    obstacles and the floor's edge (sampled every :data:`START_GRID`, edges included)."""
    x0, x1, y0, y1 = footprint
    gx = np.linspace(x0, x1, max(2, int(np.ceil((x1 - x0) / START_GRID)) + 1))
    gy = np.linspace(y0, y1, max(2, int(np.ceil((y1 - y0) / START_GRID)) + 1))
    body = np.stack(np.meshgrid(gx, gy), axis=-1).reshape(-1, 2)
    if yaw:
        c, s = np.cos(yaw), np.sin(yaw)
        body = body @ np.array([[c, s], [-s, c]])
    return ~arena.occupied(xy[:, None, :] + body[None, :, :]).any(axis=1)


def put_down(xy: Any, arena: Any, footprint: tuple[float, float, float, float], *,
             yaw: float = 0.0, region: Callable[[np.ndarray], np.ndarray] | None = None
             ) -> tuple[float, float] | None:
    """Where the robot asked to stand at ``xy`` (m) facing ``yaw`` (rad) is put down: at
    ``xy`` when its ``footprint`` fits there, else at the position nearest to ``xy`` where it
    fits (a :data:`START_GRID` lattice of the floor), among those ``region`` accepts
    (``(k, 2) -> (k,) bool``; None: the whole floor); None when it fits nowhere.

    Decision, the one rule of every command and env that sets the robot down (collect's
    walks, online's restarts, replay's start, the envs' resets): a pose inside an obstacle
    (a state centre of map-made states, or of the same floor without its obstacles, a pose
    given by hand) is not where a robot can stand. Placed there, the engine ejects it and
    the first transition records an impossible jump. The nearest free place keeps what was
    asked (the same state, the same spot of the floor) as closely as the robot allows."""
    target = np.asarray(xy, dtype=np.float64).reshape(2)
    if _fits(target[None, :], footprint, arena, yaw)[0]:
        return float(target[0]), float(target[1])
    x0, y0, x1, y1 = arena.bounds
    # within NEAR_SEARCH first (a restart's search, not the whole floor of a large map),
    # then the rest: whatever fits within the disc is nearer than anything outside it
    for radius in (NEAR_SEARCH, math.inf):
        lo = np.maximum((x0, y0), target - radius) if radius < math.inf else (x0, y0)
        hi = np.minimum((x1, y1), target + radius) if radius < math.inf else (x1, y1)
        gx = x0 + START_GRID * np.arange(np.ceil((lo[0] - x0) / START_GRID - 1e-9),
                                         np.floor((hi[0] - x0) / START_GRID + 1e-9) + 1)
        gy = y0 + START_GRID * np.arange(np.ceil((lo[1] - y0) / START_GRID - 1e-9),
                                         np.floor((hi[1] - y0) / START_GRID + 1e-9) + 1)
        grid = np.stack(np.meshgrid(gx, gy), axis=-1).reshape(-1, 2)
        dist = np.linalg.norm(grid - target, axis=1)
        keep = dist <= radius
        if region is not None:
            keep &= np.asarray(region(grid), dtype=bool)
        grid, dist = grid[keep], dist[keep]
        grid = grid[np.argsort(dist, kind="stable")]
        for chunk in range(0, len(grid), 256):  # nearest first; most fit within a chunk
            cand = grid[chunk:chunk + 256]
            ok = np.flatnonzero(_fits(cand, footprint, arena, yaw))
            if ok.size:
                return float(cand[ok[0], 0]), float(cand[ok[0], 1])
    return None


def start_in_state(state: int, disc: Any, arena: Any,
                   footprint: tuple[float, float, float, float], yaw: float = 0.0
                   ) -> tuple[float, float] | None:
    """Where a walk "from state ``state``" starts (x, y in m, the robot facing ``yaw``):
    :func:`put_down` at the state's centre, kept inside the state's Voronoi cell (one walk
    from each state keeps its meaning); None when the robot fits nowhere in the cell."""
    centre = np.asarray(disc.centres, dtype=np.float64)[int(state)]
    return put_down(centre, arena, footprint, yaw=yaw,
                    region=lambda xy: np.asarray(disc.state_of(xy)) == int(state))


def start_positions(states: Sequence[int], disc: Any, arena: Any,
                    footprint: tuple[float, float, float, float], *,
                    source: str | os.PathLike[str] | None = None
                    ) -> list[tuple[float, float]]:
    """Where each walk from a state of ``states`` starts, facing +x
    (:func:`start_in_state`): a state whose centre does not fit the robot is warned of once,
    naming where it starts instead; a state where it fits nowhere is a
    :class:`ConfigError` naming it and ``--start-states``."""
    centres = np.asarray(disc.centres, dtype=np.float64)
    out = []
    for s in states:
        xy = start_in_state(int(s), disc, arena, footprint)
        cx, cy = centres[int(s)]
        if xy is None:
            raise ConfigError(f"start state {s}: the robot fits nowhere in its cell (centre "
                              f"({cx:.2f}, {cy:.2f}) m)", path=source, key="start_states",
                              fix=f"leave state {s} out of --start-states")
        if xy != (float(cx), float(cy)):
            warn(f"start state {s}: the robot does not fit at its centre ({cx:.2f}, "
                 f"{cy:.2f}) m (an obstacle); its walk starts at ({xy[0]:.2f}, "
                 f"{xy[1]:.2f}) m, the nearest place of the state where it fits")
        out.append(xy)
    return out


def placed_pose(pose: Any, arena: Any, footprint: tuple[float, float, float, float], *,
                what: str = "the start pose") -> np.ndarray:
    """``pose`` (x, y, yaw) moved by :func:`put_down` to where the robot fits (warned), at
    its heading; :class:`ConfigError` naming ``what`` when it fits nowhere on the floor."""
    out = np.asarray(pose, dtype=np.float64).reshape(3).copy()
    xy = put_down(out[:2], arena, footprint, yaw=float(out[2]))
    if xy is None:
        raise ConfigError(f"{what} ({out[0]:.2f}, {out[1]:.2f}) m: the robot fits nowhere "
                          "on the floor", key="pose", fix="give a pose in free space")
    if xy != (float(out[0]), float(out[1])):
        warn(f"{what} ({out[0]:.2f}, {out[1]:.2f}) m: the robot does not fit there (an "
             f"obstacle, a wall or the floor's edge); it is put down at ({xy[0]:.2f}, "
             f"{xy[1]:.2f}) m, the nearest place where it fits")
        out[:2] = xy
    return out


def check_states_hash(found: str | None, expected: str | None, *, what: str,
                      path: str | os.PathLike[str] | None = None,
                      against: str = "the states file") -> None:
    """Raise :class:`ConfigError` when two states fingerprints are known and differ."""
    if found is None or expected is None or str(found) == str(expected):
        return
    raise ConfigError(
        f"{what} was made with other states (fingerprint {str(found)[:12]}...) than "
        f"{against} ({str(expected)[:12]}...)", path=path, key="states_hash",
        fix="use the states file the data were collected with")


def npz_states_hash(path: str | os.PathLike[str]) -> str | None:
    """The ``states_hash`` in an npz file's ``meta_json`` (None if absent or unreadable)."""
    try:
        with np.load(path, allow_pickle=False) as z:
            if "meta_json" not in z.files:
                return None
            meta = json.loads(str(z["meta_json"]))
    except (OSError, ValueError):
        return None
    value = meta.get("states_hash") if isinstance(meta, dict) else None
    return None if value is None else str(value)
