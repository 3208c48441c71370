"""States that belong together: centres against the arena, fingerprints where files meet.

A states file made for another arena, whose state count happens to match, was accepted
by ``collect`` (31 of 41 centres off the table) and ``replay`` (19.8 goals/h instead of
~160). Two checks stop it:

* :func:`check_centres_in_arena`: the centres must lie on the arena's floor, outside its
  obstacles and walls (:meth:`simlab.physics.arena.ArenaConfig.occupied`).
  Decision: a Voronoi centre is placed in eroded free space, so every centre of a matching
  states file is free; map-made states can put a centre or two on a mapping artefact, so
  up to :data:`MAX_BAD_FRACTION` of the centres only warn; more are refused.
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
           "npz_states_hash"]

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
