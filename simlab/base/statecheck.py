"""States that belong together: centres against the arena, fingerprints where files meet.

A states file made for another arena, whose state count happens to match, was accepted
by ``collect`` (31 of 41 centres off the table) and ``replay`` (19.8 goals/h instead of
~160). Two checks stop it:

* :func:`check_centres_in_arena`: the centres must lie on the arena's floor, outside its
  obstacles and walls (:meth:`simlab.physics.arena.ArenaConfig.occupied`).
  Decision: a Voronoi centre is placed in eroded free space, so every centre of a matching
  states file is free; map-made states can put a centre or two on a mapping artefact, so
  up to :data:`MAX_BAD_FRACTION` of the centres only warn; more are refused.
* :func:`start_in_state`: a walk that starts "at a state" starts where the robot fits: the
  state's centre, or (a centre in or against an obstacle, which the two checks above let
  through) the free position of the state's cell nearest to it.
* :func:`check_states_hash`: datasets (manifest ``discretizer.hash``), MDPs and Q-tables
  (``states_hash`` in their metadata) record the states fingerprint,
  :meth:`discretize.voronoi.Discretizer.content_hash`; wherever two of them meet, the
  fingerprints must agree (files without one, from older versions, are not checked).
"""

from __future__ import annotations

import json
import os
from typing import Any

import numpy as np

from simlab.base.errors import ConfigError, warn

__all__ = ["MAX_BAD_FRACTION", "check_centres_in_arena", "check_states_hash",
           "npz_states_hash", "start_in_state"]

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


#: Spacing (m) of the positions :func:`start_in_state` tries and of the points of the
#: robot's footprint it checks.
START_GRID = 0.01


def _fits(xy: np.ndarray, footprint: tuple[float, float, float, float], arena: Any
          ) -> np.ndarray:
    """(k,) bool: the robot facing +x at each position ``xy`` (k, 2) has its footprint
    rectangle ``(x_min, x_max, y_min, y_max)`` (m, robot frame) clear of walls, obstacles
    and the floor's edge (sampled every :data:`START_GRID`, edges included)."""
    x0, x1, y0, y1 = footprint
    gx = np.linspace(x0, x1, max(2, int(np.ceil((x1 - x0) / START_GRID)) + 1))
    gy = np.linspace(y0, y1, max(2, int(np.ceil((y1 - y0) / START_GRID)) + 1))
    body = np.stack(np.meshgrid(gx, gy), axis=-1).reshape(-1, 2)
    return ~arena.occupied(xy[:, None, :] + body[None, :, :]).any(axis=1)


def start_in_state(state: int, disc: Any, arena: Any,
                   footprint: tuple[float, float, float, float]) -> tuple[float, float] | None:
    """Where a walk "from state ``state``" starts (x, y in m, the robot facing +x): the
    state's centre when the robot's ``footprint`` fits there, else the position of the
    state's Voronoi cell nearest to the centre where it fits (a :data:`START_GRID` lattice),
    None when it fits nowhere in the cell.

    Decision: a centre inside an obstacle (map-made states, or states of the same floor
    without the obstacles) is not where a robot can stand: placed there, the engine ejects
    it and the walk's first transition records an impossible jump. The nearest free place
    of the same state keeps the walk's meaning (one walk from each state)."""
    centre = np.asarray(disc.centres, dtype=np.float64)[int(state)]
    if _fits(centre[None, :], footprint, arena)[0]:
        return float(centre[0]), float(centre[1])
    x0, y0, x1, y1 = arena.bounds
    gx = np.arange(x0, x1 + START_GRID / 2, START_GRID)
    gy = np.arange(y0, y1 + START_GRID / 2, START_GRID)
    grid = np.stack(np.meshgrid(gx, gy), axis=-1).reshape(-1, 2)
    grid = grid[np.asarray(disc.state_of(grid)) == int(state)]
    grid = grid[np.argsort(np.linalg.norm(grid - centre, axis=1), kind="stable")]
    for chunk in range(0, len(grid), 256):  # nearest first; most cells fit within a chunk
        cand = grid[chunk:chunk + 256]
        ok = np.flatnonzero(_fits(cand, footprint, arena))
        if ok.size:
            return float(cand[ok[0], 0]), float(cand[ok[0], 1])
    return None


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
