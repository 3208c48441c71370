"""The greedy policy of a Q-table, with its valid-action mask.

A Q-table trained on an empirical MDP holds, for a pair ``(s, a)`` the robot never tried,
the agent's initial value, not an estimate: the agents start optimistic
(``r_max / (1 - gamma)``, 10.0 with the thesis's ``gamma = 0.9``, see
:mod:`simlab.agents.config`) so that every action is tried. After training these values
are still the largest of their row, so ``Q[s].argmax()`` picks an action about which
nothing is known. The greedy policy skips them: ``argmax`` over the valid actions
``valid[s]`` only (a state with no valid action keeps all of them), ties to the lowest
index (as :func:`simlab.agents.planning.greedy_policy`).

``simlab train`` saves that mask (``valid`` (S, A) bool) and the greedy policy
(``greedy`` (S,) int64) in every Q-table file; :func:`greedy` reads either.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from simlab.agents.npzfile import load_npz
from simlab.base.errors import ConfigError

__all__ = ["greedy", "masked_argmax", "qtable_mask"]


def masked_argmax(Q: ArrayLike, valid: ArrayLike | None = None) -> NDArray[np.int64]:
    """(S,) int64 ``argmax`` of each row of ``Q`` (S, A) over the ``valid`` (S, A) actions.

    ``valid`` None: every action. A row of ``valid`` without any True allows every action
    of that state (nothing is known there). Ties go to the lowest index.
    """
    q = np.asarray(Q, dtype=np.float64)
    if q.ndim != 2 or q.shape[1] == 0:
        raise ConfigError(f"expected an (S, A) array with A >= 1, got shape {q.shape}",
                          key="Q")
    if valid is None:
        return np.argmax(q, axis=1).astype(np.int64)
    v = np.asarray(valid)
    if v.dtype != bool or v.shape != q.shape:
        raise ConfigError(f"expected a {q.shape} bool mask, got {v.dtype} {v.shape}",
                          key="valid")
    v = v | ~v.any(axis=1, keepdims=True)
    return np.argmax(np.where(v, q, -np.inf), axis=1).astype(np.int64)


def qtable_mask(arrays: dict[str, np.ndarray], meta: dict[str, Any]) -> NDArray[np.bool_] | None:
    """The (S, A) bool mask the greedy policy of a saved Q-table obeys, or None.

    The file's ``valid`` array, except for tables trained under the ``self-loop`` rule
    (metadata ``unvisited = "self-loop"``), where an untried pair is a modelled stay and
    may be chosen.
    """
    if meta.get("unvisited") == "self-loop":
        return None
    v = arrays.get("valid")
    return None if v is None else np.asarray(v, dtype=bool)


def greedy(
    qtable: str | os.PathLike[str] | ArrayLike, valid: ArrayLike | None = None
) -> NDArray[np.int64]:
    """The greedy policy (S,) int64 of a Q-table, untried actions masked.

    ``qtable`` is a Q-table file (``simlab train``'s ``q_<goal>.npz``, or any file of
    :func:`simlab.agents.save_q_table`): its saved ``greedy`` policy when present, else
    the masked argmax of its ``Q`` with its saved ``valid`` mask. Or an (S, A) array of
    Q-values, with the (S, A) bool ``valid`` mask (None: every action valid).

    Use it wherever a Q-table is turned into actions::

        policy = simlab.agents.greedy("q/table/q_NE.npz")
        obs, reward, terminated, truncated, info = env.step(int(policy[obs]))
    """
    if isinstance(qtable, str | os.PathLike):
        if valid is not None:
            raise ConfigError("a Q-table file carries its own mask", key="valid",
                              fix="pass the file alone, or its Q array with valid=")
        return _greedy_of_file(Path(qtable))
    return masked_argmax(qtable, valid)


def _greedy_of_file(path: Path) -> NDArray[np.int64]:
    arrays, meta = load_npz(path, ("Q",))
    Q = arrays["Q"]
    if Q.ndim != 2 or not np.issubdtype(Q.dtype, np.floating):
        raise ConfigError(f"expected a 2-D float array, got {Q.dtype} {Q.shape}",
                          path=path, key="Q")
    if "greedy" in arrays:
        pi = arrays["greedy"]
        if (pi.shape != (Q.shape[0],) or not np.issubdtype(pi.dtype, np.integer)
                or (pi.size and (pi.min() < 0 or pi.max() >= Q.shape[1]))):
            raise ConfigError(f"expected ({Q.shape[0]},) action indices in 0..{Q.shape[1] - 1}, "
                              f"got {pi.dtype} {pi.shape}", path=path, key="greedy",
                              fix="rewrite the file with simlab.agents.save_q_table")
        return pi.astype(np.int64)
    mask = qtable_mask(arrays, meta)
    try:
        return masked_argmax(Q, mask)
    except ConfigError as exc:
        raise ConfigError(exc.problem, path=path, key=exc.key) from None
