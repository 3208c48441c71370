"""The count model of the empirical MDP: counts, T = n(s,a,s')/n(s,a), entropy, coverage
(thesis 3.2.5, Fig. 4.8), dense or on the observed triples only (sparse).

Thesis eq. 1.13: ``T(s, a, s') = n(s, a, s') / n(s, a)``. A pair (s, a) never tried
has no estimate; the rule here makes it a **self-loop** (``T[s, a, s] = 1``) and flags
it ``visited[s, a] = False``, so every row of T is a distribution and a planner sees
an untried action as "nothing happens" (agents that want optimism, e.g. R-max, use
``visited``). Eq. 1.14, ``R(s, a) = sum_i r_i / n(s, a)``, is computed per goal with
the reward of the physics task, r = 1 when s' lies in the goal area
(:meth:`CountModel.rewards`; 0 for unvisited pairs).

Entropy (thesis Fig. 4.8): ``H(s, a) = -sum_s' T log2 T`` in bits, 0 for unvisited
pairs; the mean per action is taken over the visited pairs of that action (NaN if it
has none), and the slow / fast means are the means of the 8 per-action values of
actions 0-7 / 8-15. These are plug-in estimates: with few visits per pair they are
biased low (no Miller-Madow correction), which is why coverage is reported with them.

**Sparse path**: a dense ``(S, A, S)`` table costs ``8 S A S`` bytes per array
(the social task's 2560 x 22 x 2560 peaked at 7.1 GB). When ``S * A * S`` exceeds
:data:`SPARSE_CELLS` (or with ``storage="sparse"``) the counts are built from the logged
triples only (:func:`sparse_count_model`, a :class:`SparseCountModel`: one CSR structure
over the ``S * A`` rows, ``indptr`` (S A + 1,), ``indices`` (nnz,) s', ``counts`` (nnz,)
and ``probabilities`` (nnz,)), and memory grows with the distinct observed triples, never
with ``S * A * S``. The rules are the dense ones: an unvisited row holds the one entry
``(s, 1.0)`` with count 0 (the self-loop), ``visited``, entropy, coverage, ``R`` and the
summary are the same figures (to float rounding of the entropy sums). Its ``mdp.npz``
(:func:`simlab.data.estimate.estimate`) has no ``T``/``counts`` but ``indptr``, ``indices``,
``probabilities``, ``counts_data`` and ``shape`` (3,) ``(S, A, S)``, and ``meta_json["storage"] = "sparse-csr"``; read it
with :func:`simlab.data.mdp.load_sparse_mdp` (:func:`simlab.data.mdp.load_mdp` densifies
it when it is small and otherwise names the sparse loader). The dense path is unchanged.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from simlab.base.errors import ConfigError
from simlab.data.schema import N_ACTIONS

__all__ = ["HISTOGRAM_EDGES", "SPARSE_CELLS", "STORAGES", "UNVISITED_RULES", "CountModel",
           "SparseCountModel", "check_unvisited_rule", "count_transitions", "coverage_report",
           "empirical_mdp", "entropy_bits", "mean_entropy_per_action", "sparse_count_model",
           "sparse_from_dense_counts", "transition_matrix", "use_sparse", "valid_actions"]


#: Lower edges of the n(s, a) histogram bins of the coverage report: [0], [1], [2, 5), ...
HISTOGRAM_EDGES = (0, 1, 2, 5, 10, 20, 50, 100)

#: ``S * A * S`` above which ``storage="auto"`` takes the sparse path (module docstring):
#: 2e7 cells is 160 MB per dense float64 table, three of which the dense path holds.
SPARSE_CELLS = 20_000_000

#: Storage choices of :class:`EstimateConfig`: the first is the default.
STORAGES = ("auto", "dense", "sparse")

#: Rules for unvisited (s, a) pairs (see the module docstring); the first is the default.
UNVISITED_RULES = ("mask", "self-loop")


def check_unvisited_rule(rule: str, *, key: str = "unvisited") -> str:
    """``rule`` if it is one of :data:`UNVISITED_RULES`, else :class:`ConfigError`."""
    if rule not in UNVISITED_RULES:
        raise ConfigError(f"unknown rule {rule!r}", key=key,
                          fix="use 'mask' (default) or 'self-loop'")
    return rule


def valid_actions(visited: ArrayLike) -> NDArray[np.bool_]:
    """``(S, A)`` bool actions a planner may choose under the ``mask`` rule.

    ``visited``, except that a state with no visited action keeps all of them (nothing is
    known there, and every state needs at least one action).
    """
    v = np.array(visited, dtype=bool)
    v[~v.any(axis=1)] = True
    return v


def count_transitions(
    s: ArrayLike, a: ArrayLike, s_next: ArrayLike, n_states: int, n_actions: int = N_ACTIONS
) -> NDArray[np.int64]:
    """Counts n(s, a, s') ``(S, A, S)`` int64 from logged index arrays ``(N,)``."""
    s, a, s_next = (np.asarray(v, dtype=np.int64).ravel() for v in (s, a, s_next))
    if not (len(s) == len(a) == len(s_next)):
        raise ValueError(f"s, a, s_next lengths differ: {len(s)}, {len(a)}, {len(s_next)}")
    for name, v, upper in (("s", s, n_states), ("a", a, n_actions), ("s_next", s_next, n_states)):
        if v.size and (v.min() < 0 or v.max() >= upper):
            raise ValueError(f"{name}: indices must lie in 0..{upper - 1}")
    from simlab.base.guards import array_bytes, check_memory

    # counts, T and the bincount buffer: three (S, A, S) 8-byte tables
    check_memory(array_bytes((n_states, n_actions, n_states), 24), key="n_states",
                 what=f"a {n_states} x {n_actions} x {n_states} count table",
                 fix="use fewer states (a coarser discretizer)")
    flat = (s * n_actions + a) * n_states + s_next
    return np.bincount(flat, minlength=n_states * n_actions * n_states).reshape(
        n_states, n_actions, n_states
    ).astype(np.int64)


def transition_matrix(counts: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """``(T (S, A, S), visited (S, A))`` from counts with the self-loop rule for unvisited."""
    counts = np.asarray(counts)
    if counts.ndim != 3 or counts.shape[0] != counts.shape[2]:
        raise ValueError(f"counts: expected shape (S, A, S), got {counts.shape}")
    if np.any(counts < 0):
        raise ValueError("counts: negative entries")
    n_sa = counts.sum(axis=2)
    visited = n_sa > 0
    T = np.zeros(counts.shape, dtype=np.float64)
    np.divide(counts, n_sa[..., None], out=T, where=visited[..., None])
    unvisited_s, unvisited_a = np.nonzero(~visited)
    T[unvisited_s, unvisited_a, unvisited_s] = 1.0
    return T, visited


def entropy_bits(T: ArrayLike) -> NDArray[np.float64]:
    """Shannon entropy ``-sum_s' p log2 p`` (bits) of each distribution on the last axis."""
    p = np.asarray(T, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = np.where(p > 0, -p * np.log2(np.where(p > 0, p, 1.0)), 0.0)
    return terms.sum(axis=-1) + 0.0  # + 0.0 turns -0.0 into 0.0


def mean_entropy_per_action(entropy: ArrayLike, visited: ArrayLike) -> NDArray[np.float64]:
    """Mean entropy ``(A,)`` over the visited states of each action (NaN if none)."""
    h = np.asarray(entropy, dtype=np.float64)
    v = np.asarray(visited, dtype=bool)
    n = v.sum(axis=0)
    total = np.where(v, h, 0.0).sum(axis=0)
    out = np.full(h.shape[1], np.nan)
    np.divide(total, n, out=out, where=n > 0)
    return out


def _nanmean(values: NDArray[np.float64]) -> float:
    finite = values[np.isfinite(values)]
    return float(finite.mean()) if finite.size else float("nan")


class _ModelFigures:
    """The figures both count models derive from their ``entropy`` and ``visited``
    ``(S, A)`` arrays."""

    entropy: NDArray[np.float64]
    visited: NDArray[np.bool_]

    @property
    def mean_entropy(self) -> NDArray[np.float64]:
        """Mean entropy per action ``(A,)`` in bits over visited pairs (NaN if none)."""
        return mean_entropy_per_action(self.entropy, self.visited)

    @property
    def slow_mean_entropy(self) -> float:
        """Mean of the per-action mean entropies of the slow actions 0-7 (bits)."""
        return _nanmean(self.mean_entropy[:8])

    @property
    def fast_mean_entropy(self) -> float:
        """Mean of the per-action mean entropies of the fast actions 8-15 (bits)."""
        return _nanmean(self.mean_entropy[8:16])

    @property
    def coverage(self) -> float:
        """Fraction of (s, a) pairs visited at least once."""
        return float(self.visited.mean())


@dataclass(frozen=True)
class CountModel(_ModelFigures):
    """Counts and the model estimated from them (arrays are read-only views of the inputs).

    What :func:`simlab.data.estimate.estimate` computes before writing ``mdp.npz``; not the validated
    :class:`simlab.data.mdp.EmpiricalMDP` that training and replay load from that file.

    Attributes:
        counts: n(s, a, s') ``(S, A, S)`` int64.
        T: transition probabilities ``(S, A, S)``; rows sum to 1 (self-loop if unvisited).
        visited: ``(S, A)`` bool, n(s, a) > 0.
        entropy: ``(S, A)`` Shannon entropy of ``T[s, a]`` in bits (0 if unvisited).
    """

    counts: NDArray[np.int64]
    T: NDArray[np.float64]
    visited: NDArray[np.bool_]
    entropy: NDArray[np.float64]

    @property
    def n_states(self) -> int:
        return int(self.counts.shape[0])

    @property
    def n_actions(self) -> int:
        return int(self.counts.shape[1])

    @property
    def n_sa(self) -> NDArray[np.int64]:
        """Visits n(s, a) ``(S, A)``."""
        return self.counts.sum(axis=2)

    def rewards(self, goal_masks: ArrayLike) -> NDArray[np.float64]:
        """Eq. 1.14 per goal: ``R[g, s, a]`` = mean over logged (s, a) of 1[s' in goal g].

        ``goal_masks`` is ``(G, S)`` bool; returns ``(G, S, A)``, 0 for unvisited pairs.
        """
        m = np.asarray(goal_masks, dtype=np.float64)
        hits = np.einsum("sat,gt->gsa", self.counts.astype(np.float64), m)
        n = self.n_sa.astype(np.float64)
        out = np.zeros_like(hits)
        np.divide(hits, n[None], out=out, where=n[None] > 0)
        return out


def empirical_mdp(counts: ArrayLike) -> CountModel:
    """Estimate T, visited and entropy from counts ``(S, A, S)`` (see the module docstring)."""
    c = np.asarray(counts)
    if not np.issubdtype(c.dtype, np.integer):
        if not np.all(np.isfinite(c)) or not np.all(c == np.round(c)):
            raise ValueError("counts: expected whole numbers")
    c = c.astype(np.int64)
    T, visited = transition_matrix(c)
    return CountModel(counts=c, T=T, visited=visited, entropy=entropy_bits(T))


@dataclass(frozen=True)
class SparseCountModel(_ModelFigures):
    """The count model of :class:`CountModel` on the observed triples only (CSR rows).

    Row ``r = s * A + a`` holds the entries ``indptr[r]:indptr[r + 1]`` of ``indices``
    (s', increasing), ``counts`` n(s, a, s') int64 and ``probabilities`` T(s, a, s')
    float64; an unvisited row holds the single self-loop ``(s, 1.0)`` with count 0, so
    every row is a distribution (the dense rule). ``visited`` and ``entropy`` are
    ``(S, A)`` as in :class:`CountModel`; the properties are the same figures.
    """

    n_states: int
    n_actions: int
    indptr: NDArray[np.int64]
    indices: NDArray[np.int64]
    counts: NDArray[np.int64]
    probabilities: NDArray[np.float64]
    visited: NDArray[np.bool_]
    entropy: NDArray[np.float64]

    @property
    def nnz(self) -> int:
        """Stored entries (observed triples plus one self-loop per unvisited pair)."""
        return int(self.indices.size)

    @property
    def n_sa(self) -> NDArray[np.int64]:
        """Visits n(s, a) ``(S, A)``."""
        return np.add.reduceat(self.counts, self.indptr[:-1]).reshape(
            self.n_states, self.n_actions).astype(np.int64)

    @property
    def transitions(self) -> int:
        return int(self.counts.sum())

    def rows(self) -> NDArray[np.int64]:
        """Row ``s * A + a`` of every stored entry ``(nnz,)``."""
        return np.repeat(np.arange(self.n_states * self.n_actions, dtype=np.int64),
                         np.diff(self.indptr))

    def matrix(self) -> Any:
        """``scipy.sparse.csr_matrix`` ``(S * A, S)`` of the probabilities."""
        from scipy.sparse import csr_matrix

        return csr_matrix((self.probabilities, self.indices, self.indptr),
                          shape=(self.n_states * self.n_actions, self.n_states))

    def dense_T(self) -> NDArray[np.float64]:
        """The dense ``(S, A, S)`` T (for small models and tests only)."""
        return self.matrix().toarray().reshape(self.n_states, self.n_actions, self.n_states)

    def rewards(self, goal_masks: ArrayLike) -> NDArray[np.float64]:
        """Eq. 1.14 per goal, as :meth:`CountModel.rewards`: ``(G, S, A)``."""
        m = np.asarray(goal_masks, dtype=np.float64)
        hits = np.zeros((m.shape[0], self.n_states * self.n_actions))
        for g in range(m.shape[0]):
            hits[g] = np.bincount(self.rows(), weights=self.counts * m[g, self.indices],
                                  minlength=self.n_states * self.n_actions)
        hits = hits.reshape(m.shape[0], self.n_states, self.n_actions)
        n = self.n_sa.astype(np.float64)
        out = np.zeros_like(hits)
        np.divide(hits, n[None], out=out, where=n[None] > 0)
        return out


def sparse_count_model(s: ArrayLike, a: ArrayLike, s_next: ArrayLike, n_states: int,
                       n_actions: int = N_ACTIONS) -> SparseCountModel:
    """:class:`SparseCountModel` from logged index arrays ``(N,)`` (the sparse
    :func:`count_transitions` + :func:`empirical_mdp`); memory O(N + S A)."""
    s, a, s_next = (np.asarray(v, dtype=np.int64).ravel() for v in (s, a, s_next))
    if not (len(s) == len(a) == len(s_next)):
        raise ValueError(f"s, a, s_next lengths differ: {len(s)}, {len(a)}, {len(s_next)}")
    for name, v, upper in (("s", s, n_states), ("a", a, n_actions), ("s_next", s_next, n_states)):
        if v.size and (v.min() < 0 or v.max() >= upper):
            raise ValueError(f"{name}: indices must lie in 0..{upper - 1}")
    triples, n = np.unique((s * n_actions + a) * n_states + s_next, return_counts=True)
    return _sparse_from_triples(triples // n_states, triples % n_states, n.astype(np.int64),
                                n_states, n_actions)


def sparse_from_dense_counts(counts: ArrayLike) -> SparseCountModel:
    """:class:`SparseCountModel` of a dense ``(S, A, S)`` count table."""
    c = np.asarray(counts)
    if c.ndim != 3 or c.shape[0] != c.shape[2]:
        raise ValueError(f"counts: expected shape (S, A, S), got {c.shape}")
    if np.any(c < 0):
        raise ValueError("counts: negative entries")
    S, A = c.shape[:2]
    flat = np.flatnonzero(c.reshape(-1))
    return _sparse_from_triples(flat // S, flat % S, c.reshape(-1)[flat].astype(np.int64), S, A)


def _sparse_from_triples(row: NDArray[np.int64], col: NDArray[np.int64],
                         n: NDArray[np.int64], n_states: int, n_actions: int
                         ) -> SparseCountModel:
    """CSR from sorted (row, col) entries with counts ``n`` > 0, self-loops added."""
    n_rows = n_states * n_actions
    visited_rows = np.zeros(n_rows, dtype=bool)
    visited_rows[row] = True
    loops = np.flatnonzero(~visited_rows)
    rows = np.concatenate([row, loops])
    cols = np.concatenate([col, loops // n_actions])
    cnt = np.concatenate([n, np.zeros(loops.size, dtype=np.int64)])
    order = np.lexsort((cols, rows))
    rows, cols, cnt = rows[order], cols[order], cnt[order]
    indptr = np.zeros(n_rows + 1, dtype=np.int64)
    np.cumsum(np.bincount(rows, minlength=n_rows), out=indptr[1:])
    n_sa = np.add.reduceat(cnt, indptr[:-1])
    denom = np.repeat(n_sa, np.diff(indptr)).astype(np.float64)
    p = np.ones(cnt.size)
    np.divide(cnt, denom, out=p, where=denom > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = np.where(p > 0, -p * np.log2(np.where(p > 0, p, 1.0)), 0.0)
    entropy = np.add.reduceat(terms, indptr[:-1]) + 0.0
    return SparseCountModel(
        n_states=n_states, n_actions=n_actions, indptr=indptr, indices=cols, counts=cnt,
        probabilities=p, visited=visited_rows.reshape(n_states, n_actions),
        entropy=entropy.reshape(n_states, n_actions))


def use_sparse(n_states: int, n_actions: int, storage: str = "auto") -> bool:
    """Whether :func:`simlab.data.estimate.estimate` takes the sparse path (module
    docstring)."""
    if storage not in STORAGES:
        raise ConfigError(f"unknown storage {storage!r}", key="storage",
                          fix="use auto, dense or sparse")
    if storage == "auto":
        return n_states * n_actions * n_states > SPARSE_CELLS
    return storage == "sparse"


def coverage_report(mdp: CountModel | SparseCountModel, *, max_listed: int | None = None) -> dict[str, Any]:
    """Coverage: visited pairs, unvisited (s, a) list, n(s, a) histogram and quantiles."""
    n_sa = mdp.n_sa
    edges = list(HISTOGRAM_EDGES)
    hist = np.histogram(n_sa, bins=[*edges, np.inf])[0]
    labels = [f"{lo}" if hi - lo == 1 else f"{lo}-{hi - 1}" for lo, hi in itertools.pairwise(edges)]
    labels.append(f">={edges[-1]}")
    unvisited = np.argwhere(~mdp.visited).tolist()
    listed = unvisited if max_listed is None else unvisited[:max_listed]
    return {
        "pairs": int(n_sa.size),
        "visited_pairs": int(mdp.visited.sum()),
        "fraction_visited": mdp.coverage,
        "unvisited": listed,
        "n_unvisited": len(unvisited),
        "n_sa_histogram": dict(zip(labels, (int(v) for v in hist), strict=True)),
        "n_sa_min": int(n_sa.min()),
        "n_sa_median": float(np.median(n_sa)),
        "n_sa_max": int(n_sa.max()),
        "states_never_left": [int(s) for s in np.flatnonzero(n_sa.sum(axis=1) == 0)],
    }
