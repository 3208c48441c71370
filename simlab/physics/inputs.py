"""Turn command-line style inputs (names, paths) into arena and discretizer objects.

Below every command that takes an arena or a states file (physics drive, map arenas,
collection, estimation, replay, calibration); it needs only the arena loader and the
Voronoi discretizer, both at or below the physics layer.
"""

from __future__ import annotations

import os
from typing import Any

from simlab.base.errors import ConfigError


def load_arena_config(arena: Any) -> Any:
    """An ``ArenaConfig`` from a built-in name or ``.toml`` path; objects pass through."""
    if isinstance(arena, str | os.PathLike):
        from simlab.physics.arena import load_arena

        return load_arena(arena)
    return arena


def load_discretizer(states: Any) -> Any:
    """A discretizer from a states file (``simlab discretize`` JSON); objects pass through.

    An object must provide ``state_of(xy (N, 2)) -> (N,)``, ``n_states``, ``centres``
    ``(S, 2)`` and ``content_hash()``.
    """
    if states is None:
        raise ConfigError(
            "a states file is needed to turn poses into Markov states", key="states",
            fix="make one with `simlab discretize` and pass --states states/<arena>.json",
        )
    if isinstance(states, str | os.PathLike):
        from discretize.voronoi import Discretizer

        return Discretizer.load(states)
    for attr in ("state_of", "n_states", "centres", "content_hash"):
        if not hasattr(states, attr):
            raise ConfigError(f"the discretizer object has no {attr!r}", key="states")
    return states
