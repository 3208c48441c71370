"""A synthetic stand-in for the table arena's empirical MDP (tests, demos, benchmarks).

:func:`synthetic_arena_mdp` places ``n_states`` Voronoi centres in a square arena
(Lloyd relaxation of random points), then *estimates* ``T`` the way the robot
does: for every state and each of the 16 motion primitives (8 directions x 2
speeds, index ``speed * 8 + direction``, directions UP, DOWN, LEFT, RIGHT,
UP_LEFT, UP_RIGHT, DOWN_LEFT, DOWN_RIGHT with UP = +y) it simulates noisy
displacements from random poses in the cell, clips them to the walls and counts
the cell reached. Fast moves travel further and are noisier, so their rows have
higher entropy, as in the thesis's Fig. 4.8. Nine goal areas (3 x 3 layout) are
the states whose centre is nearest to nine points.

It is a stand-in only: the real matrix comes from ``simlab estimate`` on a
physics dataset.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from simlab.data.goals import GoalMasks
from simlab.data.mdp import EmpiricalMDP, mdp_from_arrays

__all__ = ["DIRECTIONS", "synthetic_arena_mdp"]

_D = np.sqrt(0.5)
#: Unit vectors (x, y) of the 8 directions, in the thesis order; UP is +y.
DIRECTIONS = np.array(
    [[0, 1], [0, -1], [-1, 0], [1, 0], [-_D, _D], [_D, _D], [-_D, -_D], [_D, -_D]], dtype=float
)


def _spread_centres(rng: np.random.Generator, n_states: int, side: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """``(points (20 S, 2), centres (S, 2))`` in m: uniform points of the arena (0.1 m from
    its sides) and cell centres spread evenly among them (30 Lloyd relaxations), numbered
    row-major from the top-left as the discretizer numbers states."""
    margin = 0.1
    pts = rng.uniform(margin, side - margin, size=(20 * n_states, 2))
    centres = pts[rng.choice(len(pts), n_states, replace=False)].copy()
    for _ in range(30):  # Lloyd relaxation: evenly spread cells
        owner = cKDTree(centres).query(pts)[1]
        for k in range(n_states):
            sel = pts[owner == k]
            if len(sel):
                centres[k] = sel.mean(axis=0)
    row_h = side / max(1, round(np.sqrt(n_states)))
    order = np.lexsort((centres[:, 0], np.floor((side - centres[:, 1]) / row_h)))
    return pts, centres[order]


def _goal_masks(tree: cKDTree, n_states: int, side: float, goal_cells: int) -> np.ndarray:
    """(9, S) bool: goal ``g`` holds the ``goal_cells`` states nearest to its anchor, a 3 x 3
    grid at 20, 50 and 80 % of ``side`` (m), row-major from the top-left."""
    anchors = np.array(
        [
            [x, y]
            for y in (0.8 * side, 0.5 * side, 0.2 * side)
            for x in (0.2 * side, 0.5 * side, 0.8 * side)
        ]
    )
    masks = np.zeros((9, n_states), dtype=bool)
    for g, p in enumerate(anchors):
        masks[g, tree.query(p, k=goal_cells)[1]] = True
    return masks


def synthetic_arena_mdp(
    rng: np.random.Generator,
    *,
    n_states: int = 41,
    side: float = 1.5,
    steps: tuple[float, float] = (0.15, 0.30),
    noise: tuple[float, float] = (0.04, 0.08),
    samples_per_pair: int = 100,
    goal_cells: int = 3,
) -> EmpiricalMDP:
    """Build a seeded synthetic empirical MDP of a ``side`` x ``side`` metre arena.

    ``steps`` are the slow/fast displacement lengths (m) and ``noise`` the
    standard deviations (m) of their Gaussian endpoint noise; each (s, a) row is
    estimated from ``samples_per_pair`` simulated moves. Each of the 9 goals
    (``"g1"`` ... ``"g9"``, row-major from the top-left) holds the ``goal_cells``
    states nearest to its anchor point. Returns a validated :class:`EmpiricalMDP`
    with ``counts``, ``visited``, ``entropy``, ``centres`` (S, 2) m, goals and bounds.
    """
    pts, centres = _spread_centres(rng, n_states, side)
    tree = cKDTree(centres)
    owner = tree.query(pts)[1]

    S, A = n_states, 16
    counts = np.zeros((S, A, S), dtype=np.int64)
    for s in range(S):
        cell_pts = pts[owner == s]
        if len(cell_pts) == 0:
            cell_pts = centres[s : s + 1]
        starts = cell_pts[rng.integers(0, len(cell_pts), samples_per_pair)]
        for a in range(A):
            speed, direction = divmod(a, 8)
            end = starts + steps[speed] * DIRECTIONS[direction]
            end = end + rng.normal(0.0, noise[speed], size=end.shape)
            end = np.clip(end, 0.02, side - 0.02)
            np.add.at(counts[s, a], tree.query(end)[1], 1)
    T = counts / counts.sum(axis=2, keepdims=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        entropy = -np.where(T > 0, T * np.log2(T), 0.0).sum(axis=2)
    masks = _goal_masks(tree, S, side, goal_cells)
    return mdp_from_arrays(
        T,
        goals=GoalMasks(np.array([f"g{i + 1}" for i in range(9)]), masks),
        centres=centres,
        bounds=(0.0, 0.0, side, side),
        counts=counts,
        visited=counts.sum(axis=2) > 0,
        entropy=entropy,
        source="synthetic",
    )
