"""A synthetic 38-state, 8-action count model in the ISIR ``transitionActions`` format.

The published navigation model of Dromnelle et al. (2022, sec. 4.1) is not part of
simlab; this stand-in has its *signature*: 38 states in two rooms joined by two doors,
with a long corridor round the bottom as the only other way between them; the published
state ids at the places the protocol uses them (start states 0 and 32 in the left room,
goal 18 in the right room, new goal 34 on the bottom corridor, passages 6 <-> 7 and
20 <-> 21 the two doors); 8 actions counter-clockwise from east (the ISIR convention
``ccw-east``: 0 E, 1 NE, 2 N, ..., 7 SE); stochastic outcomes (an intended move succeeds
with probability ``p_move``, else the robot slips to a neighbouring heading or stays);
whole visit counts per (s, a) as a 13-hour log would give. It exercises exactly the path
a real file takes (``load_counts`` -> ``empirical_mdp``).

Decision (the doors matter as in the lab): in the published lab the two passages are the
short routes from the start states to the goal, and closing them forces a detour. Here
the doors are the only openings of the wall between the rooms (no diagonal cuts past a
wall corner), so the shortest intended-move route from a start to 18 is 6 moves through a
door and 15 (from 0) or 13 (from 32) round the bottom corridor once both doors close
(checked by ``tests/online/test_synthetic.py``). The new goal 34 lies on that corridor,
away from the old route, so a goal change asks for new directions, not a shortcut.

Layout (x right, y down; ``#`` a wall), cells numbered by :data:`ROLE` then row-major::

    y=0  . . . # . . .
    y=1  . . 6 7 . . .      0 = (0, 1); door 6 <-> 7 at y = 1
    y=2  . . . # . . 18
    y=3  . . 20 21 . . .    32 = (0, 3); door 20 <-> 21 at y = 3
    y=4  . # # # # # .
    y=5  . # # # # # .      the corridor round the bottom (the detour)
    y=6  . . . 34 . . .
    y=7  # # # . # # #      a nook under 34
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["LAYOUT", "ROLE", "corridor_counts", "corridor_positions", "isir_document",
           "route_length"]

LAYOUT = (
    "...#...",
    ".......",
    "...#...",
    ".......",
    ".#####.",
    ".#####.",
    ".......",
    "###.###",
)

#: State id -> (x, y) cell of the protocol's states: starts 0 and 32 (left room), goal 18
#: (right room), new goal 34 (bottom corridor), passages 6 <-> 7 and 20 <-> 21 (the doors
#: of the wall x = 3 at y = 1 and y = 3).
ROLE = {0: (0, 1), 32: (0, 3), 18: (6, 2), 34: (3, 6), 6: (2, 1), 7: (3, 1), 20: (2, 3),
        21: (3, 3)}

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


def route_length(start: int, goal: int, closed: tuple[tuple[int, int], ...] = ()) -> int:
    """Fewest intended moves from state ``start`` to state ``goal`` with the passages
    ``closed`` (pairs of state ids) removed; -1 when unreachable."""
    xy = corridor_positions()
    pos = {tuple(int(v) for v in p): i for i, p in enumerate(xy)}
    shut = {frozenset(p) for p in closed}
    dist = {start: 0}
    frontier = [start]
    while frontier:
        nxt = []
        for s in frontier:
            here = (int(xy[s, 0]), int(xy[s, 1]))
            for k in range(8):
                s2 = pos[_target(pos, here, k)]
                if s2 not in dist and frozenset((s, s2)) not in shut:
                    dist[s2] = dist[s] + 1
                    nxt.append(s2)
        frontier = nxt
    return dist.get(goal, -1)


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
