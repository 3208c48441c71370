"""The empirical MDP: a validated transition matrix with its goal areas (thesis 4.5).

A data type shared by training, replay and the ``simlab/EmpiricalMDP-v0`` env, built by
``simlab estimate`` and read from its ``mdp.npz``.

The npz arrays (see :func:`load_mdp`): ``T`` (S, A, S) float64, rows summing to 1
(required); ``counts`` (S, A, S) int64, ``visited`` (S, A) bool, ``entropy``
(S, A) float64 bits (optional, kept for reports); ``centres`` (S, 2) float64
metres, ``goal_names`` (G,) unicode, ``goal_masks`` (G, S) bool (needed to pick a
goal by name); ``bounds`` (4,) ``x_min, y_min, x_max, y_max`` metres (optional, for plots; the
convention of :attr:`simlab.physics.arena.ArenaConfig.bounds`); ``meta_json`` (optional):
``action_set`` (absent: simlab's 16 primitives; for another number of actions unknown, None,
which training accepts and heat-map arrows and replay refuse)
and ``unvisited`` (``mask``, the default also for files without it, or ``self-loop``).

Sparse files (``simlab estimate`` on a large MDP, ``meta_json["storage"] == "sparse-csr"``,
:mod:`simlab.data.count_model`): no ``T``, but the CSR arrays ``shape`` (3,) ``(S, A, S)``,
``indptr`` (S A + 1,), ``indices`` (nnz,) s', ``probabilities`` (nnz,) and ``counts_data``
(nnz,). The sibling loader :func:`load_sparse_mdp` reads them into a
:class:`SparseEmpiricalMDP` (validated the same way: rows are distributions); decision:
:func:`load_mdp` densifies a sparse file when ``S * A * S`` is at most
:data:`simlab.data.count_model.SPARSE_CELLS` (so every existing consumer reads it), and
otherwise raises a :class:`ConfigError` naming :func:`load_sparse_mdp`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base.actions import ActionSet, action_set_from_metadata
from simlab.base.errors import ConfigError, DataError
from simlab.data.goals import GoalMasks

__all__ = ["EmpiricalMDP", "SparseEmpiricalMDP", "load_mdp", "load_sparse_mdp",
           "mdp_from_arrays"]

#: Arrays of a sparse ``mdp.npz`` (module docstring).
SPARSE_ARRAYS = ("shape", "indptr", "indices", "probabilities")

_ROW_ATOL = 1e-6


@dataclass(frozen=True, eq=False)
class EmpiricalMDP:
    """A validated empirical MDP and its goal areas (arrays are read-only)."""

    T: np.ndarray
    """(S, A, S) float64 transition probabilities, rows sum to 1."""
    goal_names: tuple[str, ...] = ()
    """Names of the goal areas (G,)."""
    goal_masks: np.ndarray | None = None
    """(G, S) bool, ``goal_masks[g, s]``: state s lies in goal g."""
    centres: np.ndarray | None = None
    """(S, 2) float64 metres, the Voronoi centres."""
    bounds: tuple[float, float, float, float] | None = None
    """``(x_min, y_min, x_max, y_max)`` metres of the arena, if known."""
    counts: np.ndarray | None = None
    """(S, A, S) int64 transition counts, if known."""
    visited: np.ndarray | None = None
    """(S, A) bool, pairs observed at least once, if known."""
    entropy: np.ndarray | None = None
    """(S, A) float64 entropy of T(s, a, .) in bits, if known."""
    source: str | None = None
    """File the MDP was read from (for messages)."""
    action_set: ActionSet | None = None
    """What each action index means (None only for MDPs built from bare arrays)."""
    unvisited: str = "mask"
    """Rule for unvisited (s, a): ``mask`` (planners never choose them) or ``self-loop``."""
    cdf: np.ndarray = field(init=False, repr=False)
    """(S, A, S) cumulative sums of T along s' (for sampling)."""

    def __post_init__(self) -> None:
        cdf = np.cumsum(self.T, axis=2)
        cdf.setflags(write=False)
        object.__setattr__(self, "cdf", cdf)

    @property
    def n_states(self) -> int:
        return int(self.T.shape[0])

    @property
    def n_actions(self) -> int:
        return int(self.T.shape[1])

    @property
    def valid(self) -> np.ndarray | None:
        """(S, A) bool actions a planner may choose, or None when all are allowed.

        Under the ``mask`` rule the visited pairs (a state with no visited action keeps
        all of them); None under ``self-loop``, without ``visited``/``counts``, or when
        every pair was visited (so fully covered data trains exactly as before).
        """
        from simlab.data.count_model import valid_actions

        if self.unvisited != "mask":
            return None
        visited = self.visited
        if visited is None and self.counts is not None:
            visited = self.counts.sum(axis=2) > 0
        if visited is None:
            return None
        v = valid_actions(visited)
        return None if v.all() else v

    def goal_index(self, goal: str | int) -> int:
        """Index of a goal given by name or index; :class:`ConfigError` lists the valid ones."""
        if self.goal_masks is None or not self.goal_names:
            raise ConfigError(
                "has no goal areas (arrays goal_names and goal_masks)",
                path=self.source,
                key="goal",
                fix="re-run simlab estimate with an arena that defines goals, or pass goal_mask=",
            )
        if isinstance(goal, int | np.integer) and not isinstance(goal, bool):
            if 0 <= int(goal) < len(self.goal_names):
                return int(goal)
        elif isinstance(goal, str) and goal in self.goal_names:
            return self.goal_names.index(goal)
        raise ConfigError(
            f"unknown goal {goal!r}; valid goals: {', '.join(self.goal_names)}",
            path=self.source,
            key="goal",
        )

    def goal_mask(self, goal: str | int) -> np.ndarray:
        """(S,) bool mask of a goal."""
        return self.goal_masks[self.goal_index(goal)].copy()

    def goal_reward(self, goal: str | int | np.ndarray) -> np.ndarray:
        """(S,) float64 reward on arrival: 1.0 inside the goal, 0.0 elsewhere."""
        mask = goal if isinstance(goal, np.ndarray) else self.goal_mask(goal)
        return np.asarray(mask, dtype=np.float64)


def _readonly(a: np.ndarray | None) -> np.ndarray | None:
    if a is None:
        return None
    a = np.array(a)
    a.setflags(write=False)
    return a


def mdp_from_arrays(
    T: np.ndarray,
    *,
    goals: GoalMasks | None = None,
    centres: np.ndarray | None = None,
    bounds: Any = None,
    counts: np.ndarray | None = None,
    visited: np.ndarray | None = None,
    entropy: np.ndarray | None = None,
    source: str | os.PathLike[str] | None = None,
    action_set: ActionSet | None = None,
    unvisited: str = "mask",
) -> EmpiricalMDP:
    """Validate arrays and build an :class:`EmpiricalMDP`.

    ``goals`` names the goal areas and their states (``names`` (G,), ``masks`` (G, S) bool,
    the record :func:`simlab.data.goals.goal_state_masks` returns; None: no goals).
    ``action_set`` must have A actions (default: simlab's 16 primitives when A is 16, else
    None); ``unvisited`` is ``mask`` or ``self-loop`` (see :attr:`EmpiricalMDP.valid`).

    Raises :class:`ConfigError` naming ``source`` and the array: T not
    (S, A, S), negative or non-finite entries, rows not summing to 1, goal
    arrays or centres of the wrong shape.
    """
    from simlab.agents.planning import validate_mdp
    from simlab.data.count_model import check_unvisited_rule

    path = None if source is None else str(source)
    T = np.asarray(T)
    validate_mdp(T, atol=_ROW_ATOL, path=path, p_name="T")
    T = T.astype(np.float64)
    S, A = T.shape[:2]
    names, goal_masks = _checked_goals(goals, S, path)
    centres = _checked_centres(centres, S, path)
    bounds_t = None if bounds is None else _checked_bounds(bounds, path)
    for name, arr, shape in (("counts", counts, (S, A, S)), ("visited", visited, (S, A)),
                             ("entropy", entropy, (S, A))):  # fmt: skip
        if arr is not None and np.shape(arr) != shape:
            raise ConfigError(f"expected shape {shape}, got {np.shape(arr)}", path=path, key=name)
    if counts is not None:
        counts = _check_counts(np.asarray(counts), path, "counts")
    check_unvisited_rule(unvisited)
    return EmpiricalMDP(
        T=_readonly(T),
        goal_names=names,
        goal_masks=_readonly(goal_masks),
        centres=_readonly(centres),
        bounds=bounds_t,
        counts=_readonly(counts),
        visited=_readonly(visited),
        entropy=_readonly(entropy),
        source=path,
        action_set=_checked_action_set(action_set, A, path),
        unvisited=unvisited,
    )


def _checked_goals(goals: GoalMasks | None, S: int, path: str | None
                   ) -> tuple[tuple[str, ...], np.ndarray | None]:
    """``(names (G,), masks (G, S) bool)``: both or neither given, one mask row of S
    states per name, names unique."""
    goal_names, goal_masks = (None, None) if goals is None else goals
    if goal_names is None and goal_masks is None:
        return (), None
    if goal_names is None or goal_masks is None:
        missing = "goal_masks" if goal_masks is None else "goal_names"
        raise ConfigError("goal_names and goal_masks come together", path=path, key=missing)
    names = tuple(str(n) for n in np.asarray(goal_names).ravel())
    goal_masks = np.asarray(goal_masks)
    if goal_masks.shape != (len(names), S):
        raise ConfigError(f"expected shape (G, S) = ({len(names)}, {S}), got {goal_masks.shape}",
                          path=path, key="goal_masks")
    if len(set(names)) != len(names):
        raise ConfigError(f"duplicate goal names in {list(names)}", path=path, key="goal_names")
    return names, goal_masks.astype(bool)


def _goal_pair(names: Any, masks: np.ndarray | None) -> GoalMasks | None:
    """The goals of a file's ``goal_names`` and ``goal_masks`` (None when it has neither;
    one without the other is refused by :func:`mdp_from_arrays`, naming the missing one)."""
    if names is None and masks is None:
        return None
    return GoalMasks(names, masks)  # type: ignore[arg-type]


def _checked_centres(centres: np.ndarray | None, S: int, path: str | None
                     ) -> np.ndarray | None:
    """``centres`` as (S, 2) float64 metres (None stays None)."""
    if centres is None:
        return None
    centres = np.asarray(centres, dtype=np.float64)
    if centres.shape != (S, 2):
        raise ConfigError(f"expected shape (S, 2) = ({S}, 2), got {centres.shape}", path=path,
                          key="centres")
    return centres


def _checked_bounds(bounds: Any, path: str | None) -> tuple[float, float, float, float]:
    """``(x_min, y_min, x_max, y_max)`` metres, each min below its max."""
    b = np.asarray(bounds, dtype=np.float64).ravel()
    if b.shape != (4,) or not (b[0] < b[2] and b[1] < b[3]):
        raise ConfigError(f"expected (x_min, y_min, x_max, y_max) with min < max, got "
                          f"{b.tolist()}", path=path, key="bounds")
    return (float(b[0]), float(b[1]), float(b[2]), float(b[3]))


def _checked_action_set(action_set: ActionSet | None, A: int, path: str | None
                        ) -> ActionSet | None:
    """The action set of an MDP with ``A`` actions: the given one (refused when its size is
    not A), simlab's 16 primitives when A is 16, else None."""
    if action_set is None and A == 16:
        action_set = action_set_from_metadata(None, A, where=path or "mdp")
    if action_set is not None and action_set.n_actions != A:
        raise ConfigError(f"action_set says {action_set.n_actions} actions, T has {A}",
                          path=path, key="action_set")
    return action_set


def _check_counts(counts: np.ndarray, path: str | None, key: str) -> np.ndarray:
    """``counts`` as int64 when every entry is a finite whole number >= 0 (ConfigError
    naming the file, the array and the first bad entry otherwise: a NaN count would
    otherwise surface as numpy's cast error deep in training)."""
    if counts.dtype.kind not in "biuf":
        raise ConfigError(f"expected numbers, got dtype {counts.dtype}", path=path, key=key,
                          fix="re-estimate the MDP with simlab estimate")
    if counts.dtype.kind == "f":
        bad = ~np.isfinite(counts) | (counts != np.round(counts))
    else:
        bad = np.zeros(counts.shape, dtype=bool)
    bad |= counts < 0
    if np.any(bad):
        where = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ConfigError(f"{int(bad.sum())} entr(ies) are not whole numbers >= 0 (first at "
                          f"{list(where)}: {counts[where]!r})", path=path, key=key,
                          fix="re-estimate the MDP with simlab estimate")
    return counts.astype(np.int64, copy=False)


def load_mdp(path: str | os.PathLike[str]) -> EmpiricalMDP:
    """Read and validate an ``mdp.npz`` (no pickle). Only ``T`` is required.

    Errors name the file and the array (missing ``T``, rows not summing to 1,
    shapes that disagree).
    """
    from simlab.agents.storage import load_npz

    try:
        arrays, meta = load_npz(path)
    except DataError as exc:
        raise DataError(f"{path}: not an mdp.npz written by simlab estimate "
                        f"({str(exc).removeprefix(f'{path}: ')})") from exc
    path = Path(path)
    if meta.get("storage") == "sparse-csr" and "T" not in arrays:
        return _densified(load_sparse_mdp(path))
    if "T" not in arrays:
        load_npz(path, ("T",))  # the missing-array message
    T = arrays["T"]
    n_actions = int(T.shape[1]) if T.ndim == 3 else 16
    return mdp_from_arrays(
        T,
        goals=_goal_pair(arrays.get("goal_names"), arrays.get("goal_masks")),
        centres=arrays.get("centres"),
        bounds=arrays.get("bounds"),
        counts=arrays.get("counts"),
        visited=arrays.get("visited"),
        entropy=arrays.get("entropy"),
        source=path,
        action_set=(action_set_from_metadata(meta, n_actions, where=str(path))
                    if meta.get("action_set") is not None or n_actions == 16 else None),
        unvisited=str(meta.get("unvisited", "mask")),
    )


@dataclass(frozen=True, eq=False)
class SparseEmpiricalMDP:
    """A validated sparse empirical MDP (:func:`load_sparse_mdp`; arrays read-only).

    ``P`` is a ``scipy.sparse.csr_matrix`` ``(S * A, S)``: row ``s * A + a`` is
    ``T(s, a, .)``. ``counts`` (nnz,) int64 are aligned with ``P.data`` (0 for the
    self-loop of an unvisited pair); the other fields are :class:`EmpiricalMDP`'s.
    """

    P: Any
    n_states: int
    n_actions: int
    counts: np.ndarray | None = None
    visited: np.ndarray | None = None
    entropy: np.ndarray | None = None
    goal_names: tuple[str, ...] = ()
    goal_masks: np.ndarray | None = None
    centres: np.ndarray | None = None
    bounds: np.ndarray | None = None
    source: str | None = None
    unvisited: str = "mask"
    meta: dict[str, Any] = field(default_factory=dict, repr=False)

    @property
    def valid(self) -> np.ndarray | None:
        """As :attr:`EmpiricalMDP.valid`: (S, A) bool planner-choosable actions, or None."""
        from simlab.data.count_model import valid_actions

        if self.unvisited != "mask" or self.visited is None:
            return None
        v = valid_actions(self.visited)
        return None if v.all() else v

    def dense_T(self) -> np.ndarray:
        """The dense ``(S, A, S)`` T (small models only)."""
        return self.P.toarray().reshape(self.n_states, self.n_actions, self.n_states)


def load_sparse_mdp(path: str | os.PathLike[str]) -> SparseEmpiricalMDP:
    """Read and validate a sparse ``mdp.npz`` (no pickle; module docstring).

    Errors name the file and the array: missing CSR arrays, ``indptr`` not of length
    ``S * A + 1`` or not non-decreasing from 0 to nnz, ``indices`` outside ``0..S-1``,
    negative or non-finite probabilities, rows not summing to 1, shapes that disagree.
    """
    from scipy.sparse import csr_matrix

    from simlab.agents.storage import load_npz
    from simlab.data.count_model import check_unvisited_rule

    arrays, meta = load_npz(path, SPARSE_ARRAYS)
    where = str(path)
    shape = np.asarray(arrays["shape"]).ravel()
    if shape.shape != (3,) or shape[0] != shape[2] or np.any(shape < 1):
        raise ConfigError(f"expected (S, A, S) with S, A >= 1, got {shape.tolist()}",
                          path=where, key="shape")
    S, A = int(shape[0]), int(shape[1])
    indptr = np.asarray(arrays["indptr"], dtype=np.int64)
    indices = np.asarray(arrays["indices"], dtype=np.int64)
    prob = np.asarray(arrays["probabilities"], dtype=np.float64)
    if indptr.shape != (S * A + 1,) or indptr[0] != 0 or np.any(np.diff(indptr) < 0) \
            or indptr[-1] != indices.size:
        raise ConfigError(f"expected {S * A + 1} non-decreasing offsets from 0 to "
                          f"{indices.size}", path=where, key="indptr")
    if prob.shape != indices.shape:
        raise ConfigError(f"expected shape {indices.shape}, got {prob.shape}", path=where,
                          key="probabilities")
    if indices.size and (indices.min() < 0 or indices.max() >= S):
        raise ConfigError(f"next states must lie in 0..{S - 1}", path=where, key="indices")
    if not np.all(np.isfinite(prob)) or np.any(prob < 0):
        raise ConfigError("negative or non-finite probability", path=where,
                          key="probabilities")
    P = csr_matrix((prob, indices, indptr), shape=(S * A, S))
    sums = np.asarray(P.sum(axis=1)).ravel()
    bad = np.abs(sums - 1.0) > _ROW_ATOL
    if np.any(bad):
        r = int(np.flatnonzero(bad)[0])
        raise ConfigError(f"row ({r // A}, {r % A}) sums to {sums[r]:.6g}, not 1 "
                          f"({int(bad.sum())} rows are not distributions)", path=where,
                          key="probabilities")
    counts = arrays.get("counts_data")
    for name, arr, want in (("counts_data", counts, indices.shape),
                            ("visited", arrays.get("visited"), (S, A)),
                            ("entropy", arrays.get("entropy"), (S, A)),
                            ("centres", arrays.get("centres"), (S, 2))):
        if arr is not None and np.shape(arr) != want:
            raise ConfigError(f"expected shape {want}, got {np.shape(arr)}", path=where,
                              key=name)
    if counts is not None:
        counts = _check_counts(np.asarray(counts), where, "counts_data")
    names = arrays.get("goal_names")
    masks = arrays.get("goal_masks")
    if masks is not None and names is not None and np.shape(masks) != (np.size(names), S):
        raise ConfigError(f"expected shape ({np.size(names)}, {S}), got {np.shape(masks)}",
                          path=where, key="goal_masks")
    unvisited = check_unvisited_rule(str(meta.get("unvisited", "mask")))
    return SparseEmpiricalMDP(
        P=P, n_states=S, n_actions=A, counts=_readonly(counts),
        visited=_readonly(None if arrays.get("visited") is None
                          else arrays["visited"].astype(bool)),
        entropy=_readonly(arrays.get("entropy")),
        goal_names=() if names is None else tuple(str(n) for n in np.ravel(names)),
        goal_masks=_readonly(None if masks is None else np.asarray(masks, dtype=bool)),
        centres=_readonly(arrays.get("centres")), bounds=_readonly(arrays.get("bounds")),
        source=where, unvisited=unvisited,
        meta=meta)


def _densified(m: SparseEmpiricalMDP) -> EmpiricalMDP:
    """:class:`EmpiricalMDP` of a small sparse file (module docstring, decision)."""
    from simlab.data.count_model import SPARSE_CELLS

    S, A = m.n_states, m.n_actions
    if S * A * S > SPARSE_CELLS:
        raise ConfigError(f"a sparse model of {S} x {A} x {S} cells is too large to load "
                          "densely", path=m.source, key="storage",
                          fix="read it with simlab.data.mdp.load_sparse_mdp")
    counts = None
    if m.counts is not None:
        from scipy.sparse import csr_matrix

        counts = csr_matrix((m.counts, m.P.indices, m.P.indptr), shape=m.P.shape
                            ).toarray().reshape(S, A, S).astype(np.int64)
    action_set = None
    if m.meta.get("action_set") is not None or A == 16:
        action_set = action_set_from_metadata(m.meta, A, where=str(m.source))
    return mdp_from_arrays(m.dense_T(), goals=_goal_pair(m.goal_names or None, m.goal_masks),
                           centres=m.centres, bounds=m.bounds,
                           counts=counts,
                           visited=m.visited, entropy=m.entropy, source=m.source,
                           action_set=action_set, unvisited=m.unvisited)
