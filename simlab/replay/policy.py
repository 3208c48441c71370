"""The replay's action choice: greedy over the valid actions, blocked retries, the loop
watchdog (see :mod:`simlab.replay.replay` for the decisions)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["escape_action", "greedy_action", "recurs"]


def greedy_action(q: NDArray[np.float64], rng: np.random.Generator,
                  excluded: NDArray[np.bool_] | None = None, tie_tolerance: float = 1e-9, *,
                  valid: NDArray[np.bool_] | None = None) -> int:
    """``argmax_a q[a]`` over the ``valid`` actions (None: all; a state with none valid keeps
    all) not ``excluded`` (ignored when it would exclude every valid action), ties (within
    ``tie_tolerance * max(1, |max|)``, the rule of
    :func:`simlab.replay.prediction.greedy_ties`) broken uniformly with ``rng``."""
    q = np.asarray(q, dtype=np.float64)
    if valid is not None and valid.any() and not valid.all():
        q = np.where(valid, q, -np.inf)
        if excluded is not None:
            excluded = excluded & valid
            if excluded.sum() == valid.sum():
                excluded = None
    if excluded is not None and excluded.any() and not excluded.all():
        q = np.where(excluded, -np.inf, q)
    best = float(q.max())
    ties = np.flatnonzero(q >= best - tie_tolerance * max(1.0, abs(best)))
    if ties.size == 1:
        return int(ties[0])
    return int(ties[rng.integers(0, ties.size)])


def escape_action(a: int, valid: NDArray[np.bool_] | None, n_actions: int,
                  rng: np.random.Generator) -> int:
    """A uniformly random action other than ``a`` (among the valid ones when there are
    others; without a mask the same draw as before the mask existed)."""
    if valid is None or valid.all():
        return int((a + 1 + rng.integers(0, n_actions - 1)) % n_actions)
    others = np.flatnonzero(valid & (np.arange(n_actions) != a))
    if others.size == 0:
        return a
    return int(others[rng.integers(0, others.size)])


def recurs(history: list[tuple[float, float, int]], pose: NDArray[np.float64], action: int,
           radius: float) -> bool:
    """Whether ``action`` was already taken from within ``radius`` (m) of ``pose``."""
    r2 = radius * radius
    x, y = float(pose[0]), float(pose[1])
    return any(a == action and (hx - x) ** 2 + (hy - y) ** 2 <= r2 for hx, hy, a in history)
