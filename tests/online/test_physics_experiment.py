"""The physics experiment's pieces: the MDP of the arena from a random walk, the map-built lab."""

from __future__ import annotations

import numpy as np

from simlab.online.experiments import lab_map_arena, lattice_states, random_walk_mdp
from simlab.physics.arena import load_arena


def test_the_mdp_is_estimated_from_a_random_walk_of_the_arena(tmp_path) -> None:
    m = random_walk_mdp("table", 5, 120, 0, tmp_path)
    assert (m.n_states, m.n_actions) == (25, 16)
    np.testing.assert_allclose(np.asarray(m.T).sum(axis=2), 1.0)
    # every count is a transition of the walk (a dataset of simlab collect), no other
    assert int(np.asarray(m.counts).sum()) == 120
    assert (tmp_path / "walk" / "_manifest.json").is_file()
    # the walk starts from every state's centre: each state has a counted transition
    assert np.all(np.asarray(m.counts).sum(axis=(1, 2)) > 0)


def test_the_map_built_lab_has_two_gaps_and_states_on_its_floor(tmp_path) -> None:
    arena = load_arena(lab_map_arena(tmp_path))
    disc = lattice_states(arena, 5)
    assert disc.n_states == 25
    # the wall at x 1.15-1.25 m between y 0.5 and 1.5 m: occupied in the middle, free in
    # both gaps (where the experiment's box goes: top gap, y 1.5-2.0 m)
    res, origin = 0.01, (arena.bounds[0], arena.bounds[1])
    occ = arena.rasterize(res, origin, (int(2.4 / res), int(3.4 / res)))

    def occupied(x: float, y: float) -> bool:
        return bool(occ[int((y - origin[1]) / res), int((x - origin[0]) / res)])

    assert occupied(1.2, 1.0) and not occupied(1.2, 1.75) and not occupied(1.2, 0.25)
    assert not any(occupied(x, y) for x, y in disc.centres)
