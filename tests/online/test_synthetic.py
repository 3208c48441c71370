"""The synthetic ISIR-style model: the protocol's states where the protocol needs them."""

from __future__ import annotations

import numpy as np

from simlab.online.synthetic import ROLE, corridor_counts, corridor_positions, route_length

DOORS = ((6, 7), (20, 21))


def test_the_doors_are_the_short_routes_and_closing_them_forces_a_detour() -> None:
    # hand-counted on the layout: 0 -> 1 -> 2 -> 6 -> 7 -> (4, 2) -> 18 is 6 moves; round
    # the bottom corridor from 0: 3 down the left side, 6 along, 3 up the right, 3 more
    assert route_length(0, 18) == 6 and route_length(32, 18) == 6
    assert route_length(0, 18, DOORS) == 15 and route_length(32, 18, DOORS) == 13
    # either door alone still gives a short route: only closing both forces the detour
    assert route_length(0, 18, DOORS[:1]) == 6 and route_length(0, 18, DOORS[1:]) == 6
    assert route_length(32, 34) == 6  # the new goal: down the corridor, not through a door


def test_states_cells_and_counts() -> None:
    xy = corridor_positions()
    assert xy.shape == (38, 2) and len({tuple(p) for p in xy}) == 38
    for s, cell in ROLE.items():
        assert tuple(xy[s]) == cell
    counts = corridor_counts(np.random.default_rng(0))
    assert counts.shape == (38, 8, 38) and np.all(counts.sum(axis=2) >= 8)
    # the door cell 7 = (3, 1) is reached only from itself and its two sides: no diagonal
    # cuts past the wall's corners
    sources = np.nonzero(counts[:, :, 7].sum(axis=1))[0]
    assert {tuple(int(v) for v in xy[s]) for s in sources} == {(2, 1), (3, 1), (4, 1)}
