"""A synthetic 38-state, 8-action count model in the ISIR ``transitionActions`` format.

The published navigation model of Dromnelle et al. (2022, sec. 4.1) is not part of
simlab; this stand-in has its *signature*: 38 states in two rooms joined by two doors and an open bottom row, the
published state ids at the places the protocol uses them (start states 0 and 32, goal 18,
new goal 34, passages 20 <-> 21 and 6 <-> 7 on the shortest routes from the starts to 18,
with a longer detour left open when both close), 8 actions counter-clockwise from east
(the ISIR convention ``ccw-east``: 0 E, 1 NE, 2 N, ..., 7 SE), stochastic outcomes
(an intended move succeeds with probability ``p_move``, else the robot slips to a
neighbouring heading or stays), and whole visit counts per (s, a) as a 13-hour log would
give. It exercises exactly the path a real file takes (``load_counts`` ->
``empirical_mdp``).

Layout (x right, y down; ``#`` a wall), cells numbered by :data:`ROLE` then row-major::

    y=0  # . . . # . . . #
    y=1  . . . . . . . . .       doors of the wall x = 4 at y = 1 (6 <-> 7) and y = 3
    y=2  . . # . # . # . .       (20 <-> 21); the bottom row stays open
    y=3  . . . . . . . . .
    y=4  . . . . . . . . #
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["LAYOUT", "ROLE", "corridor_counts", "corridor_positions", "isir_document"]

LAYOUT = (
    "#...#...#",
    ".........",
    "..#.#.#..",
    ".........",
    "........#",
)

#: State id -> (x, y) cell of the protocol's states: starts 0 and 32 (left wall), goal 18
#: (right room), new goal 34 (bottom, between the rooms), passages 6 <-> 7 and 20 <-> 21 (the
#: doors of the wall x = 4 at y = 1 and y = 3; the bottom row y = 4 stays open, the detour).
ROLE = {0: (0, 1), 32: (0, 4), 18: (7, 2), 34: (5, 4), 6: (3, 1), 7: (4, 1), 20: (3, 3),
        21: (4, 3)}

#: ccw-east headings: action k moves by (dx, dy) with y down (k = 2 is north, up).
_MOVES = ((1, 0), (1, -1), (0, -1), (-1, -1), (-1, 0), (-1, 1), (0, 1), (1, 1))


def corridor_positions() -> np.ndarray:
    """(38, 2) int cell (x, y) of each state id."""
    cells = [(x, y) for y, row in enumerate(LAYOUT) for x, c in enumerate(row) if c == "."]
    rest = iter(c for c in cells if c not in ROLE.values())
    pos = [ROLE[i] if i in ROLE else next(rest) for i in range(len(cells))]
    return np.array(pos, dtype=np.int64)


def _target(pos: dict[tuple[int, int], int], s_xy: tuple[int, int], k: int) -> tuple[int, int]:
    dx, dy = _MOVES[k % 8]
    x, y = s_xy[0] + dx, s_xy[1] + dy
    # a diagonal move needs both L-shaped paths free (no corner cutting through a wall)
    if dx and dy and ((s_xy[0] + dx, s_xy[1]) not in pos or (s_xy[0], s_xy[1] + dy) not in pos):
        return s_xy
    return (x, y) if (x, y) in pos else s_xy


def corridor_counts(rng: np.random.Generator, *, visits: tuple[int, int] = (8, 40),
                    p_move: float = 0.7, p_slip: float = 0.1) -> np.ndarray:
    """(38, 8, 38) int64 counts n(s, a, s'): per pair a visit count uniform in ``visits``
    and outcomes drawn from: the intended cell ``p_move``, each neighbouring heading
    ``p_slip``, staying the rest (a move into a wall stays)."""
    xy = corridor_positions()
    pos = {tuple(int(v) for v in p): i for i, p in enumerate(xy)}
    S = len(xy)
    counts = np.zeros((S, 8, S), dtype=np.int64)
    for s in range(S):
        here = (int(xy[s, 0]), int(xy[s, 1]))
        for a in range(8):
            p = np.zeros(S)
            p[pos[_target(pos, here, a)]] += p_move
            p[pos[_target(pos, here, a + 1)]] += p_slip
            p[pos[_target(pos, here, a - 1)]] += p_slip
            p[s] += 1.0 - p_move - 2 * p_slip
            counts[s, a] = rng.multinomial(int(rng.integers(visits[0], visits[1] + 1)), p)
    return counts


def isir_document(counts: np.ndarray, **metadata: Any) -> dict[str, Any]:
    """The ISIR ``transitionActions`` JSON document of ``counts`` (S, A, S) (``prob``
    holds counts, as in the published files); ``metadata`` keys are added at top level."""
    entries = []
    for s in range(counts.shape[0]):
        tr = [{"action": int(a), "state": int(s2), "prob": int(counts[s, a, s2])}
              for a, s2 in zip(*np.nonzero(counts[s]), strict=True)]
        entries.append({"state": int(s), "transitions": tr})
    return {"transitionActions": entries, **metadata}
