"""Reset rows: a state whose recorded transitions are an experiment's episode reset, not moves.

A real robot's transition model is often recorded during a learning experiment, whose
protocol puts the robot back at a start after each reward. The published ISIR navigation
experiment (Dromnelle et al. 2022) records that reset as the goal's own transitions: in the
13-hour model every action of the goal state "leads" to a start state several metres away.
Those rows are not moves of the robot: compared with a twin they make a perfect simulator
look wrong, and scored as moves they teleport every policy that drives through the goal
state back to a start.

**Recognised** (:func:`detect_reset_states`) from the state centres: a state with recorded
transitions of which every one ends farther than :data:`RESET_JUMP_CELLS` cells (the median
distance between neighbouring centres) from it, and none stays. A robot that drives until its
state changes ends in a neighbour, one cell and a bit away; a jump of several cells in one
decision is not a move. Without centres nothing is recognised.

**Kept out** (``calibrate``, ``transfer``): the real rows of a reset state leave the
distance, its floors and the real signature (the twin's rows of that state are then
compared with nothing), and in the transfer the real rows are replaced by the twin's own
rows of that state, so that no policy is charged for them either way; a one-line warning
says so, and ``--reset-states none`` keeps them (a list of ids names them by hand).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from simlab.base import validation
from simlab.base.errors import ConfigError

#: A state whose every recorded outcome lies farther than this many cells is a reset.
RESET_JUMP_CELLS = 2.5


def detect_reset_states(counts: ArrayLike, centres: ArrayLike | None) -> tuple[int, ...]:
    """The states of ``counts`` (S, A, S) whose rows are a reset (module docstring), given
    the state ``centres`` (S, 2) in metres; ``()`` without centres."""
    from simlab.calibration.signature import cell_size

    n = np.asarray(counts)
    if centres is None:
        return ()
    c = np.asarray(centres, dtype=np.float64)
    cell = cell_size(c)
    if not math.isfinite(cell) or cell <= 0:
        return ()
    out = []
    for s in range(n.shape[0]):
        row = n[s].sum(axis=0)
        targets = np.flatnonzero(row)
        if targets.size == 0 or row[s] > 0:
            continue
        if float(np.linalg.norm(c[targets] - c[s], axis=1).min()) > RESET_JUMP_CELLS * cell:
            out.append(s)
    return tuple(out)


def resolve_reset_states(option: Any, counts: ArrayLike, centres: ArrayLike | None,
                         key: str = "reset_states") -> tuple[int, ...]:
    """The reset states an option names: ``"auto"`` (:func:`detect_reset_states`),
    ``"none"`` (or None), or state ids (a list or ``"18,34"``), checked against S."""
    S = int(np.shape(counts)[0])
    if option is None or (isinstance(option, str) and option.strip().lower() == "none"):
        return ()
    if isinstance(option, str) and option.strip().lower() == "auto":
        return detect_reset_states(counts, centres)
    ids = validation.state_ids(option, key)
    bad = [s for s in ids or () if not 0 <= s < S]
    if bad:
        raise ConfigError(f"state {bad[0]} is not one of the {S} states", key=key,
                          fix=f"auto, none, or ids in 0..{S - 1}")
    return tuple(sorted(set(ids or ())))


def reset_warning(states: tuple[int, ...], counts: ArrayLike, centres: ArrayLike | None,
                  where: str) -> str:
    """One line naming the reset states, where their transitions land and what is done.

    A state named by hand whose rows do not look like a reset (:func:`detect_reset_states`:
    some transition stays or lands within :data:`RESET_JUMP_CELLS` cells) is said to be
    left out *as asked*, with what its rows look like, not called a reset."""
    n = np.asarray(counts)
    looks = set(detect_reset_states(n, centres)) if centres is not None else set(states)
    resets, moves = [], []
    for s in states:
        targets = np.flatnonzero(n[s].sum(axis=0))
        jump = ""
        if centres is not None and targets.size:
            d = np.linalg.norm(np.asarray(centres)[targets] - np.asarray(centres)[s], axis=1)
            verb = "jump" if s in looks else "end"
            jump = f" {verb} {d.min():.1f}-{d.max():.1f} m away"
        text = (f"state {s}'s {int(n[s].sum())} transitions{jump} (to "
                f"{', '.join(map(str, targets.tolist()))})")
        (resets if s in looks else moves).append(text)
    lines = []
    if resets:
        lines.append(f"{'; '.join(resets)}: an episode reset, not a move; left out of "
                     f"{where} (--reset-states none keeps them)")
    if moves:
        lines.append(f"{'; '.join(moves)}: named by --reset-states, though they look like "
                     f"moves (a reset's every transition jumps over {RESET_JUMP_CELLS:g} "
                     f"cells and none stays); left out of {where} as asked")
    return "; ".join(lines)


def without_rows(counts: ArrayLike, states: tuple[int, ...]) -> NDArray[np.int64]:
    """A copy of ``counts`` (S, A, S) with the rows of ``states`` emptied."""
    out = np.array(counts, dtype=np.int64, copy=True)
    if states:
        out[list(states)] = 0
    return out
