"""The empirical MDP: counts, T = n(s,a,s')/n(s,a), entropy, coverage (thesis 3.2.5,
Fig. 4.8).

Thesis eq. 1.13: ``T(s, a, s') = n(s, a, s') / n(s, a)``. A pair (s, a) never tried
has no estimate; the rule here makes it a **self-loop** (``T[s, a, s] = 1``) and flags
it ``visited[s, a] = False``, so every row of T is a distribution and a planner sees
an untried action as "nothing happens" (agents that want optimism, e.g. R-max, use
``visited``). Eq. 1.14, ``R(s, a) = sum_i r_i / n(s, a)``, is computed per goal with
the reward of the physics task, r = 1 when s' lies in the goal area
(:meth:`CountModel.rewards`; 0 for unvisited pairs).

**Unvisited pairs for planners**: the self-loop keeps T a distribution, but a
planner must not read "never tried" as "a free stay". The rule stored in the model's
metadata (``meta_json``: ``{"unvisited": "mask" | "self-loop", "action_set": {...}}``)
says what consumers do with ``visited == False``: ``mask`` (the default) means training
and replay only choose among visited actions of a state (``valid = visited``; a state with
no visited action keeps all of them); ``self-loop`` is the old rule, the self-loop taken
at face value. T itself is the same under both rules (so old results stay bit-identical).

**Action sets**: the model records its :class:`~simlab.base.actions.ActionSet` (number of
actions, direction numbering, speed of an 8-action set), from the dataset or from the
``--n-actions/--convention/--speed`` of a count table; files without it are simlab's 16
primitives.

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
has no ``T``/``counts`` but ``indptr``, ``indices``, ``probabilities``, ``counts_data``
and ``shape`` (3,) ``(S, A, S)``, and ``meta_json["storage"] = "sparse-csr"``; read it
with :func:`simlab.data.mdp.load_sparse_mdp` (:func:`simlab.data.mdp.load_mdp` densifies
it when it is small and otherwise names the sparse loader). The dense path is unchanged.
"""

from __future__ import annotations

import itertools
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from simlab.base import validation
from simlab.base.actions import SIMLAB16, ActionSet, ActionSetOptions
from simlab.base.errors import ConfigError
from simlab.base.io import atomic_write, atomic_write_json, ensure_new, output_transaction
from simlab.base.options import command, option
from simlab.data.schema import N_ACTIONS
from simlab.physics.inputs import load_arena_config, load_discretizer

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


# --------------------------------------------------------------------------------------
# Pure functions
# --------------------------------------------------------------------------------------


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

    What :func:`estimate` computes before writing ``mdp.npz``; not the validated
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
    """Whether :func:`estimate` takes the sparse path (module docstring)."""
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


# --------------------------------------------------------------------------------------
# The command
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class EstimateResult:
    """What :func:`estimate` produced: the model, the output paths and the summary."""

    mdp: CountModel | SparseCountModel
    npz: Path
    summary_path: Path
    plot: Path | None
    summary: dict[str, Any] = field(repr=False)


def output_paths(out: str | os.PathLike[str]) -> tuple[Path, Path, Path]:
    """``(mdp.npz, mdp.json summary, mdp_entropy.png plot)`` for ``out = mdp.npz``."""
    out = Path(out)
    if out.suffix != ".npz":
        raise ConfigError("the model file must end in .npz", path=out, fix="e.g. --out mdp.npz")
    return out, out.with_suffix(".json"), out.with_name(f"{out.stem}_entropy.png")


def _inside(path: Path, directory: Path) -> bool:
    try:
        path.resolve().relative_to(directory.resolve())
    except ValueError:
        return False
    return True


def _finite(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


def _floats(values: NDArray[np.float64]) -> list[float | None]:
    """JSON-safe floats: NaN (an action never tried) becomes null."""
    return [_finite(v) for v in values]


@dataclass(frozen=True, kw_only=True)
class EstimateConfig(ActionSetOptions):
    """Options of ``simlab estimate`` / :func:`estimate`. The action-set group
    (:class:`~simlab.base.actions.ActionSetOptions`) and ``action_set`` (an
    :class:`~simlab.base.actions.ActionSet`, from Python) describe a count table only; a dataset
    records its own (decision: the group is refused for a dataset, as the CLI always did)."""

    COMMAND = "estimate"
    ARGUMENTS = ("dataset", "out")

    dataset: Path | None = option(None, "dataset directory written by `simlab collect`",
                                  positional=True)
    out: Path = option(help="model file mdp.npz (summary .json and _entropy.png beside it)")
    counts: Path | None = option(
        None, "instead of a dataset: CSV/JSON table with s, a, s_next, count")
    arena: Any | None = option(
        None, "arena whose goals define goal_masks (default: the dataset's)")
    states: Any | None = option(
        None, "states file: S and centres for --counts; checked against a dataset")
    n_states: int | None = option(None, "number of states for --counts without --states")
    unvisited: str = option("mask", "unvisited (s, a): mask = planners never choose them; "
                            "self-loop = the old rule, a free stay")
    plot: bool = option(True, "the entropy bar plot (--no-plot skips it)")
    overwrite: bool = option(False, "replace existing outputs")
    storage: str = option("auto", "model storage: auto = sparse CSR when S*A*S > 2e7 cells, "
                          "else dense; dense; sparse", choices=STORAGES)
    action_set: Any | None = option(None, "ActionSet of a count table (Python only)", cli=False)

    def validate(self) -> None:
        if (self.dataset is None) == (self.counts is None):
            raise ConfigError("give either a dataset directory or --counts FILE (exactly one)",
                              key="source")
        check_unvisited_rule(self.unvisited)
        use_sparse(1, 1, self.storage)  # an unknown storage names its field here
        if self.action_set is not None and not isinstance(self.action_set, ActionSet):
            raise ConfigError(f"expected an ActionSet, got {self.action_set!r}",
                              key="action_set")
        if self.action_set_given and (self.dataset is not None or self.action_set is not None):
            raise ConfigError("--n-actions/--convention/--speed describe a --counts table; a "
                              "dataset records its own action set", key="n_actions",
                              fix="drop them, or re-import the data with the right convention")
        if self.n_actions is not None or self.convention != "simlab":
            self.make_action_set(N_ACTIONS)  # a bad convention names its field here
        if self.n_states is not None:
            validation.whole(self.n_states, "n_states", minimum=1)
        output_paths(self.out)

    def table_action_set(self) -> ActionSet:
        """The action set of a count table: ``action_set``, else the group's fields."""
        return self.action_set if self.action_set is not None else self.make_action_set(N_ACTIONS)


@dataclass
class _Source:
    """What the dataset or the count table gives the model (arrays as loaded)."""

    counts: NDArray[np.int64] | None
    action_set: ActionSet | None
    summary: dict[str, Any]
    triples: tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]] | None = None
    shape: tuple[int, int] | None = None
    states_hash: str | None = None
    centres: NDArray[np.float64] | None = None
    goals: Any = None
    bounds: list[float] | None = None
    blocked_by_action: NDArray[np.float64] | None = None


@command(EstimateConfig)
def estimate(cfg: EstimateConfig) -> EstimateResult:
    """Estimate the empirical MDP of a dataset directory or an external count table.

    Takes an :class:`EstimateConfig` or its fields (``estimate(dataset, out, plot=False)``):

    * ``dataset``: a directory written by ``simlab collect`` (validated: checksums,
      schema, discretizer). Its manifest supplies S, the centres and the goals.
    * ``out``: the model file ``*.npz``; the JSON summary and the entropy plot go beside
      it (``mdp.json``, ``mdp_entropy.png``). Must not lie inside ``dataset``.
    * ``counts``: instead of ``dataset``, a CSV/JSON count table (:mod:`simlab.data.counts`).
    * ``arena``: arena name/path/``ArenaConfig`` whose goals define ``goal_masks``
      (default for a dataset: the goals recorded in its manifest).
    * ``states``: states file or discretizer: S and the centres for a count table; for a
      dataset, its hash must equal the manifest's (else DataError).
    * ``n_states``: S for a count table without ``states`` (default: largest index + 1).
    * ``n_actions``/``convention``/``speed`` or ``action_set``: what the action indices of
      a count table mean (default simlab's 16 primitives). A dataset carries its own
      (``TransitionDataset.action_set``, SIMLAB16 for datasets without one).
    * ``plot``: write the mean-entropy-per-action bar plot (thesis Fig. 4.8).
    * ``overwrite``: replace existing output files.
    * ``unvisited``: rule for unvisited (s, a), ``mask`` (default) or ``self-loop``,
      stored in the model's metadata (module docstring).
    * ``storage``: ``auto`` (sparse when ``S * A * S`` > :data:`SPARSE_CELLS`), ``dense``
      or ``sparse`` (module docstring, "Sparse path"); the sparse path's ``mdp`` is a
      :class:`SparseCountModel` and its npz holds the CSR arrays instead of ``counts``/``T``.

    Returns:
        :class:`EstimateResult`. The (dense) npz holds ``counts`` (S, A, S) int64, ``T`` (S, A, S),
        ``visited`` (S, A) bool, ``entropy`` (S, A) bits, ``mean_entropy`` (A,) bits and,
        when the centres are known, ``centres`` (S, 2) m; with goals also
        ``goal_names`` (G,) unicode, ``goal_masks`` (G, S) bool and ``R`` (G, S, A);
        with a known arena ``bounds`` (4,) ``x_min, y_min, x_max, y_max`` m; and
        ``meta_json`` (JSON: ``action_set``, ``unvisited``).
    """
    npz_path, summary_path, plot_path = output_paths(cfg.out)
    if cfg.dataset is not None and _inside(npz_path, Path(cfg.dataset)):
        raise ConfigError(
            "the model must not be written inside the dataset directory (Parquet readers "
            "of the directory would choke on it)", path=npz_path,
            fix="choose --out outside the dataset, e.g. beside it",
        )
    for p in (npz_path, summary_path, *((plot_path,) if cfg.plot else ())):
        ensure_new(p, overwrite=cfg.overwrite)
    disc = None if cfg.states is None else load_discretizer(cfg.states)
    arena_cfg = None if cfg.arena is None else load_arena_config(cfg.arena)
    if disc is not None and arena_cfg is not None:  # the goals are found through the centres
        from simlab.base.statecheck import check_centres_in_arena

        check_centres_in_arena(disc.centres, arena_cfg, source=str(cfg.states)
                               if isinstance(cfg.states, str | os.PathLike) else None)
    src = _from_dataset(cfg, disc, arena_cfg) if cfg.dataset is not None else \
        _from_counts(cfg, disc, arena_cfg)
    mdp = _count_model(src, cfg.storage)
    arrays, goal_info = _model_arrays(mdp, src, cfg.unvisited)
    summary = _summary(mdp, src, cfg.unvisited, goal_info)
    summary["files"] = {"npz": str(npz_path), "summary": str(summary_path),
                        "plot": str(plot_path) if cfg.plot else None}
    _write_outputs(cfg, mdp, arrays, summary, (npz_path, summary_path, plot_path))
    return EstimateResult(mdp=mdp, npz=npz_path, summary_path=summary_path,
                          plot=plot_path if cfg.plot else None, summary=summary)


def _from_dataset(cfg: EstimateConfig, disc: Any, arena_cfg: Any) -> _Source:
    """Counts, action set, centres, goals and blocked fractions of a dataset directory."""
    from simlab.data.dataset import open_dataset
    from simlab.data.goals import goals_from_manifest

    dataset = cfg.dataset
    ds = open_dataset(dataset, validate=True,
                      expected_discretizer=None if disc is None else disc.content_hash())
    S, A = ds.n_states, ds.n_actions
    names = getattr(ds, "action_names", None)
    action_set = None if names is not None else (getattr(ds, "action_set", None) or SIMLAB16)
    if action_set is None:  # named non-primitive actions (e.g. the social task's 22)
        if cfg.action_set is not None:
            raise ConfigError("the dataset's actions are not motion primitives",
                              path=dataset, key="action_set", fix="leave action_set out")
    elif cfg.action_set is not None and cfg.action_set != action_set:
        raise ConfigError(
            f"the dataset records {action_set.describe()}, not {cfg.action_set.describe()}",
            path=dataset, key="action_set",
            fix="leave --n-actions/--convention/--speed out for a dataset")
    if action_set is not None and action_set.n_actions != A:
        raise ConfigError(f"the dataset has {A} actions but records "
                          f"{action_set.describe()}", path=dataset, key="action_set")
    ds.warn_if_incomplete("the model")
    a_col = ds.column("a")
    triples = (ds.column("s"), a_col, ds.column("s_next"))
    arena = ds.manifest["arena"]
    bounds = None if arena_cfg is None else [float(v) for v in arena_cfg.bounds]
    if bounds is None and arena.get("bounds") is not None:
        bounds = [float(v) for v in arena["bounds"]]
    tries = np.bincount(a_col, minlength=A)
    hits = np.bincount(a_col, weights=ds.column("blocked").astype(np.float64), minlength=A)
    parts = ds.manifest["parts"]
    source = {
        "dataset": str(Path(dataset)),
        "arena": arena["name"],
        "simulator": ds.manifest.get("simulator"),
        "pose_source": ds.manifest["pose_source"],
        "discretizer_hash": ds.discretizer_hash,
        "seed": ds.manifest["seed"],
        "workers": ds.manifest["workers"],
        "complete": ds.manifest.get("complete"),
        "simulated_hours": float(
            sum(max((e["t_end"] for e in parts if e["worker"] == w), default=0.0)
                for w in range(int(ds.manifest["workers"])))) / 3600.0,
    }
    return _Source(
        counts=None if use_sparse(S, A, cfg.storage) else count_transitions(*triples, S, A),
        triples=triples, shape=(S, A),
        action_set=action_set, summary={"source": source},
        states_hash=ds.discretizer_hash, centres=ds.centres,
        goals=arena_cfg if arena_cfg is not None else goals_from_manifest(
            arena.get("goals", [])),
        bounds=bounds,
        blocked_by_action=np.divide(hits, tries, out=np.full(A, np.nan), where=tries > 0))


def _count_model(src: _Source, storage: str) -> CountModel | SparseCountModel:
    """The dense model of the counts, or the sparse one (:func:`use_sparse`)."""
    if src.counts is None:  # a dataset on the sparse path: its triples only
        S, A = src.shape  # type: ignore[misc]
        return sparse_count_model(*src.triples, S, A)  # type: ignore[misc]
    S, A = src.counts.shape[:2]
    if use_sparse(S, A, storage):
        return sparse_from_dense_counts(src.counts)
    return empirical_mdp(src.counts)


def _from_counts(cfg: EstimateConfig, disc: Any, arena_cfg: Any) -> _Source:
    """Counts and centres of an external count table (its action set as given)."""
    from simlab.data.counts import load_counts

    n_states = cfg.n_states
    if disc is not None and n_states is not None and int(n_states) != disc.n_states:
        raise ConfigError(
            f"--n-states {n_states} disagrees with the states file ({disc.n_states} states)",
            key="n_states",
        )
    action_set = cfg.table_action_set()
    table = load_counts(cfg.counts, n_states=disc.n_states if disc is not None else n_states,
                        n_actions=action_set.n_actions)  # type: ignore[arg-type]
    source = {
        "counts": str(Path(cfg.counts)),  # type: ignore[arg-type]
        "format": table.format,
        "rows": table.rows,
        "duplicate_rows_summed": table.duplicates,
        # the file's own top-level fields (ISIR: actioncount, timecount), as given
        "file_metadata": dict(table.metadata),
        "n_states_from": "states file" if disc is not None else (
            "--n-states" if n_states is not None else "largest index + 1"),
    }
    return _Source(
        counts=table.counts, action_set=action_set, summary={"source": source},
        states_hash=None if disc is None else disc.content_hash(),
        centres=None if disc is None else np.asarray(disc.centres, dtype=np.float64),
        goals=arena_cfg,
        bounds=None if arena_cfg is None else [float(v) for v in arena_cfg.bounds])


def _action_set_json(src: _Source) -> dict[str, Any] | None:
    """The action set record; None for a dataset of named non-primitive actions."""
    return None if src.action_set is None else src.action_set.to_json()


def _model_arrays(mdp: CountModel | SparseCountModel, src: _Source, unvisited: str
                  ) -> tuple[dict[str, Any], dict[str, list[int]] | None]:
    """The arrays of ``mdp.npz`` and the goal states (None without centres or goals)."""
    from simlab.data.goals import goal_state_masks

    # the states fingerprint: train and replay check it against their states file
    meta = {"action_set": _action_set_json(src), "unvisited": unvisited}
    if src.states_hash is not None:
        meta["states_hash"] = src.states_hash
    if isinstance(mdp, SparseCountModel):
        meta["storage"] = "sparse-csr"
        arrays: dict[str, Any] = {
            "shape": np.array([mdp.n_states, mdp.n_actions, mdp.n_states], dtype=np.int64),
            "indptr": mdp.indptr, "indices": mdp.indices,
            "probabilities": mdp.probabilities, "counts_data": mdp.counts}
    else:
        arrays = {"counts": mdp.counts, "T": mdp.T}
    arrays.update({
        "visited": mdp.visited,
        "entropy": mdp.entropy,
        "mean_entropy": mdp.mean_entropy,
        "meta_json": np.array(json.dumps(meta)),
    })
    goal_info = None
    if src.bounds is not None:
        arrays["bounds"] = np.asarray(src.bounds, dtype=np.float64)
    if src.centres is not None:
        arrays["centres"] = np.asarray(src.centres, dtype=np.float64)
        if src.goals is not None:
            names, masks = goal_state_masks(src.goals, src.centres)
            arrays["goal_names"] = names
            arrays["goal_masks"] = masks
            arrays["R"] = mdp.rewards(masks)
            goal_info = {str(n): [int(s) for s in np.flatnonzero(m)]
                         for n, m in zip(names, masks, strict=True)}
    return arrays, goal_info


def _summary(mdp: CountModel | SparseCountModel, src: _Source, unvisited: str,
             goal_info: dict[str, list[int]] | None) -> dict[str, Any]:
    """The JSON summary beside the model (without its ``files`` entry)."""
    n_masked = int((~valid_actions(mdp.visited)).sum()) if unvisited == "mask" else 0
    summary = dict(src.summary)
    summary.update({
        "n_states": mdp.n_states,
        "n_actions": mdp.n_actions,
        "transitions": int(mdp.counts.sum()),
        **({"storage": "sparse-csr", "stored_entries": mdp.nnz}
           if isinstance(mdp, SparseCountModel) else {}),
        "coverage": coverage_report(mdp),
        "entropy_bits": {
            "per_action": _floats(mdp.mean_entropy),
            "slow_mean": _finite(mdp.slow_mean_entropy) if mdp.n_actions == 16 else None,
            "fast_mean": _finite(mdp.fast_mean_entropy) if mdp.n_actions == 16 else None,
            "overall_mean_visited": float(mdp.entropy[mdp.visited].mean())
            if mdp.visited.any() else None,
        },
        "action_set": _action_set_json(src),
        "unvisited": unvisited,
        "unvisited_rule": (
            "T[s, a, s] = 1, flagged visited[s, a] = False; "
            + ("planners choose only visited actions (mask)" if unvisited == "mask"
               else "planners may choose them as a free stay (self-loop)")),
        "masked_pairs": n_masked,
        "states_without_data": int((~mdp.visited.any(axis=1)).sum()),
    })
    if src.blocked_by_action is not None:
        summary["blocked_fraction_per_action"] = _floats(src.blocked_by_action)
    if goal_info is not None:
        summary["goal_states"] = goal_info
    return summary


def _write_outputs(cfg: EstimateConfig, mdp: CountModel | SparseCountModel, arrays: dict[str, Any],
                   summary: dict[str, Any], paths: tuple[Path, Path, Path]) -> None:
    """Write the model, the plot and the summary: all of them, or none."""
    npz_path, summary_path, plot_path = paths
    finals = (npz_path, summary_path, *((plot_path,) if cfg.plot else ()))
    with output_transaction(npz_path.parent, finals, overwrite=cfg.overwrite,
                            what="model output") as txn:
        with atomic_write(txn.path(npz_path), "wb") as fh:
            np.savez_compressed(fh, **arrays)
        if cfg.plot:
            from simlab.data.plots import plot_entropy_per_action

            title = None
            if mdp.n_actions == 16:
                title = (f"Mean entropy per action — slow {mdp.slow_mean_entropy:.2f} bits, "
                         f"fast {mdp.fast_mean_entropy:.2f} bits "
                         f"({summary['coverage']['fraction_visited']:.0%} of (s, a) visited)")
            means = ({"slow_mean": mdp.slow_mean_entropy, "fast_mean": mdp.fast_mean_entropy}
                     if mdp.n_actions == 16 else {})  # NaN without data, and no warning
            plot_entropy_per_action(mdp.mean_entropy, txn.path(plot_path), title=title,
                                    **means)
        atomic_write_json(txn.path(summary_path), summary)
