"""The models a transfer is scored on and planned on: a count model or ``mdp.npz``
(:class:`TransferModel`), ``simlab train`` Q-tables (:class:`QTableTwin`), the action
columns that match a twin to the real robot, and the readers of those files."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from simlab.base.actions import ActionSet
from simlab.base.errors import ConfigError
from simlab.calibration.transfer.steps import allowed_mask


@dataclass(frozen=True, eq=False)
class TransferModel:
    """A transition model to plan on or to score on: the real robot's or a twin's.

    ``T`` (S, A, S) float64 rows summing to 1; ``allowed`` (S, A) bool the pairs with data
    (the real robot tried them); ``visits`` (S,) int64 decisions taken in each state, if
    known; ``centres`` (S, 2) metres, if known; ``action_set`` what action ``a`` means
    (None: unknown, then the other side must have the same number of actions).
    """

    T: NDArray[np.float64]
    allowed: NDArray[np.bool_]
    name: str = "model"
    action_set: ActionSet | None = None
    visits: NDArray[np.int64] | None = None
    centres: NDArray[np.float64] | None = None
    goals: dict[str, NDArray[np.bool_]] = field(default_factory=dict)
    counts: NDArray[np.int64] | None = None
    """(S, A, S) the counts T was estimated from, if known (the sampling floor needs them)."""

    def __post_init__(self) -> None:
        from simlab.agents.planning import validate_mdp

        validate_mdp(self.T, path=self.name, p_name="T")
        S, A = self.T.shape[:2]
        object.__setattr__(self, "allowed", allowed_mask(self.allowed, S, A))
        if self.visits is not None and np.shape(self.visits) != (S,):
            raise ConfigError(f"expected shape ({S},), got {np.shape(self.visits)}",
                              path=self.name, key="visits")
        if self.centres is not None and np.shape(self.centres) != (S, 2):
            raise ConfigError(f"expected shape ({S}, 2), got {np.shape(self.centres)}",
                              path=self.name, key="centres")
        if self.counts is not None and np.shape(self.counts) != (S, A, S):
            raise ConfigError(f"expected shape ({S}, {A}, {S}), got {np.shape(self.counts)}",
                              path=self.name, key="counts")
        if self.action_set is not None and self.action_set.n_actions != A:
            raise ConfigError(f"action_set has {self.action_set.n_actions} actions, T has {A}",
                              path=self.name, key="action_set")

    @property
    def n_states(self) -> int:
        return int(self.T.shape[0])

    @property
    def n_actions(self) -> int:
        return int(self.T.shape[1])

    def with_rows(self, states: tuple[int, ...], T_rows: NDArray[np.float64],
                  count_rows: NDArray[np.int64] | None) -> TransferModel:
        """A copy whose rows of ``states`` are ``T_rows`` (k, A, S) (tried where they hold
        an outcome other than the row's own self-loop for untried pairs), with their counts
        ``count_rows`` (k, A, S) when known (else the counts are dropped if they were kept)."""
        T, allowed = self.T.copy(), self.allowed.copy()
        idx = list(states)
        T[idx] = T_rows
        allowed[idx] = count_rows.sum(axis=2) > 0 if count_rows is not None else True
        counts = None
        if self.counts is not None and count_rows is not None:
            counts = self.counts.copy()
            counts[idx] = count_rows
        visits = None if counts is None else counts.sum(axis=(1, 2)).astype(np.int64)
        return TransferModel(T=T, allowed=allowed, name=self.name, action_set=self.action_set,
                             visits=visits if visits is not None else self.visits,
                             centres=self.centres, goals=self.goals, counts=counts)

    @classmethod
    def from_counts(cls, counts: ArrayLike, *, name: str = "counts",
                    action_set: ActionSet | None = None,
                    centres: ArrayLike | None = None) -> TransferModel:
        """From counts n(s, a, s') (S, A, S): T the frequencies, an untried pair a stay."""
        from simlab.data.count_model import transition_matrix

        c = np.asarray(counts)
        T, visited = transition_matrix(c)
        return cls(T=T, allowed=visited, name=name, action_set=action_set,
                   visits=c.sum(axis=(1, 2)).astype(np.int64), counts=c.astype(np.int64),
                   centres=None if centres is None else np.asarray(centres, dtype=np.float64))

    @classmethod
    def from_mdp(cls, mdp: Any, *, name: str | None = None) -> TransferModel:
        """From a :class:`simlab.data.mdp.EmpiricalMDP` (``load_mdp``): its counts when
        stored (visits, tried pairs), else its ``visited`` mask, else every pair allowed."""
        T = np.asarray(mdp.T, dtype=np.float64)
        S, A = T.shape[:2]
        name = name or str(mdp.source or "mdp")
        visits = None
        if mdp.counts is not None:
            check_counts_agree(T, np.asarray(mdp.counts), name)
            allowed = np.asarray(mdp.counts).sum(axis=2) > 0
            visits = np.asarray(mdp.counts).sum(axis=(1, 2)).astype(np.int64)
        elif mdp.visited is not None:
            allowed = np.asarray(mdp.visited, dtype=bool)
        else:
            allowed = np.ones((S, A), dtype=bool)
        goals = {}
        if mdp.goal_masks is not None:
            goals = {str(n): np.asarray(m, dtype=bool)
                     for n, m in zip(mdp.goal_names, mdp.goal_masks, strict=True)}
        return cls(T=T, allowed=allowed, name=name,
                   action_set=mdp.action_set, visits=visits,
                   counts=None if mdp.counts is None else np.asarray(mdp.counts, np.int64),
                   centres=None if mdp.centres is None else np.asarray(mdp.centres),
                   goals=goals)


#: Largest difference between ``T`` and its counts normalised that is still agreement (the
#: row-sum tolerance of an mdp.npz, :mod:`simlab.data.mdp`).
COUNTS_ATOL = 1e-6


def check_counts_agree(T: ArrayLike, counts: ArrayLike, name: str) -> None:
    """Refuse a model whose ``T`` (S, A, S) is not its ``counts`` (S, A, S) normalised on
    the tried pairs (``n(s, a) > 0``; an untried pair's row is a rule, not data).

    A transfer scores on ``T`` and draws its floor from the counts (parametric bootstrap,
    :func:`~simlab.calibration.transfer.score.transfer_floor`): a file whose two arrays
    disagree (``T`` edited or smoothed, counts from another run) would judge the twins
    against one model and the floor against another. :class:`ConfigError` naming the file,
    both fields and the first pair that disagrees."""
    T = np.asarray(T, dtype=np.float64)
    c = np.asarray(counts, dtype=np.float64)
    n = c.sum(axis=2)
    tried = n > 0
    freq = np.divide(c, n[..., None], out=np.zeros_like(c), where=tried[..., None])
    gap = np.where(tried[..., None], np.abs(T - freq), 0.0).max(axis=2)
    bad = gap > COUNTS_ATOL
    if not bad.any():
        return
    s, a = (int(i) for i in np.argwhere(bad)[0])
    sp = int(np.argmax(np.abs(T[s, a] - freq[s, a])))
    raise ConfigError(
        f"T and counts disagree on {int(bad.sum())} of {int(tried.sum())} tried (s, a) "
        f"pairs, e.g. ({s}, {a}): T = {T[s, a, sp]:.6g} but counts give "
        f"{int(c[s, a, sp])}/{int(n[s, a])} = {freq[s, a, sp]:.6g} at s' = {sp}; the transfer "
        f"would score on T and draw its floor from the counts", path=name, key="T, counts",
        fix="re-estimate the mdp.npz with simlab estimate (T is the counts normalised), "
            "or give the count file itself instead")


@dataclass(frozen=True, eq=False)
class QTable:
    """One Q-table of ``simlab train``: ``Q`` (S, A), its goal (S,) bool, the ``valid``
    (S, A) bool mask (None: all) and the stored ``greedy`` (S,) policy (None: not stored),
    in the twin's action numbering."""

    Q: NDArray[np.float64]
    goal: NDArray[np.bool_]
    valid: NDArray[np.bool_] | None = None
    greedy: NDArray[np.int64] | None = None
    name: str = ""


@dataclass(frozen=True, eq=False)
class QTableTwin:
    """A twin given by the Q-tables it trained (one per goal) rather than by its model."""

    tables: tuple[QTable, ...]
    name: str = "q-tables"
    action_set: ActionSet | None = None

    @property
    def n_states(self) -> int:
        return int(self.tables[0].Q.shape[0])

    @property
    def n_actions(self) -> int:
        return int(self.tables[0].Q.shape[1])

    def table_for(self, goal: NDArray[np.bool_]) -> QTable | None:
        """The table trained for exactly this goal set (None if none)."""
        for t in self.tables:
            if np.array_equal(t.goal, goal):
                return t
        return None


def twin_columns(twin: ActionSet | None, real: ActionSet | None, *, n_twin: int,
                 n_real: int, where: str = "twin") -> NDArray[np.int64]:
    """(A_real,) the twin's action (column) doing each real action.

    Both sets known: through the primitives (:meth:`ActionSet.primitives`), so simlab's 16
    primitives read on an 8-action robot give the 8 columns of its speed and direction
    numbering. One unknown: the identity when the counts agree. Anything else is a
    :class:`ConfigError` naming ``where``.
    """
    if twin is None or real is None:
        if n_twin != n_real:
            raise ConfigError(f"{n_twin} actions against the real model's {n_real}, and the "
                              "action set of one side is unknown", path=where,
                              key="action_set",
                              fix="give both sides an action set (estimate --n-actions "
                                  "--convention)")
        return np.arange(n_real, dtype=np.int64)
    cols = [twin.from_primitive(p) for p in real.primitives()]
    missing = [a for a, c in enumerate(cols) if c is None]
    if missing:
        a = missing[0]
        raise ConfigError(f"has {twin.describe()}, none of which does real action {a} "
                          f"({real.direction(a).name}, {'fast' if real.speed_index(a) else 'slow'})"
                          f" of {real.describe()}", path=where, key="action_set",
                          fix="score it on a model of the same action set; a real count file takes "
                              "--n-actions and --convention")
    return np.array(cols, dtype=np.int64)


def policy_from_q(table: QTable, columns: NDArray[np.int64],
                  restrict: NDArray[np.bool_] | None = None) -> NDArray[np.int64]:
    """(S,) real-numbered greedy policy of a Q-table through the twin ``columns``.

    The stored ``greedy`` action when it is one of the real actions and valid; else the
    argmax of ``Q`` over the valid real columns (ties to the lowest real index; a state
    with no valid real column considers all of them). ``restrict`` (S, A_real) bool narrows
    the valid actions further where it leaves any (the real robot's tried pairs, rule
    ``untried="mask"`` of :func:`transfer_report`).
    """
    Q = table.Q[:, columns]
    S, A = Q.shape
    valid = np.ones((S, A), dtype=bool) if table.valid is None else table.valid[:, columns]
    valid = valid | ~valid.any(axis=1, keepdims=True)
    if restrict is not None:
        narrowed = valid & restrict
        valid = np.where(narrowed.any(axis=1, keepdims=True), narrowed, valid)
    pi = np.argmax(np.where(valid, Q, -np.inf), axis=1).astype(np.int64)
    if table.greedy is not None:
        inverse = {int(c): a for a, c in enumerate(columns)}
        for s, g in enumerate(table.greedy):
            a = inverse.get(int(g))
            if a is not None and valid[s, a]:
                pi[s] = a
    return pi


def load_qtable_twin(path: str | os.PathLike[str]) -> QTableTwin:
    """A twin from a ``simlab train`` output directory (every ``q_*.npz``) or one Q-table
    file: ``Q``, ``goal_mask`` (required: the goal it was trained for), ``valid`` and
    ``greedy`` when stored, the action set of its metadata."""
    from simlab.agents.storage import load_npz
    from simlab.base.actions import action_set_from_metadata

    path = Path(path)
    files = sorted(path.glob("q_*.npz")) if path.is_dir() else [path]
    if not files:
        raise ConfigError("no Q-table (q_*.npz) in this directory", path=path, key="sim",
                          fix="give the --out directory of simlab train, or an mdp.npz")
    tables, asets = [], []
    for f in files:
        arrays, meta = load_npz(f, ("Q",))
        Q = arrays["Q"]
        if Q.ndim != 2 or not np.issubdtype(Q.dtype, np.floating):
            raise ConfigError(f"expected a 2-D float array, got {Q.dtype} {Q.shape}", path=f,
                              key="Q")
        S, A = Q.shape
        if "goal_mask" not in arrays or np.shape(arrays["goal_mask"]) != (S,):
            raise ConfigError("no goal_mask (S,) array: the goal it was trained for is "
                              "unknown", path=f, key="goal_mask",
                              fix="use a Q-table written by simlab train")
        # under the self-loop rule an untried pair was a modelled stay, choosable in training
        valid = None if meta.get("unvisited") == "self-loop" else arrays.get("valid")
        if valid is not None and valid.shape != (S, A):
            raise ConfigError(f"expected shape ({S}, {A}), got {valid.shape}", path=f,
                              key="valid")
        greedy = arrays.get("greedy")
        if greedy is not None and (greedy.shape != (S,) or not np.issubdtype(greedy.dtype,
                                                                             np.integer)
                                   or (S and (greedy.min() < 0 or greedy.max() >= A))):
            raise ConfigError(f"expected ({S},) actions in 0..{A - 1}", path=f, key="greedy")
        aset = None
        if meta.get("action_set") is not None or A == 16:
            aset = action_set_from_metadata(meta, A, where=str(f))
        tables.append(QTable(Q=Q.astype(np.float64),
                             goal=np.asarray(arrays["goal_mask"], dtype=bool),
                             valid=None if valid is None else valid.astype(bool),
                             greedy=None if greedy is None else greedy.astype(np.int64),
                             name=str(meta.get("goal", f.stem.removeprefix("q_")))))
        asets.append(aset)
        if Q.shape != tables[0].Q.shape or aset != asets[0]:
            raise ConfigError(f"Q-table {f.name} has another shape or action set than "
                              f"{files[0].name}", path=path, key="sim")
    return QTableTwin(tables=tuple(tables), name=str(path), action_set=asets[0])


def load_twin(path: str | os.PathLike[str]) -> TransferModel | QTableTwin:
    """A twin from a path: a ``simlab train`` directory or Q-table file
    (:func:`load_qtable_twin`), or an ``mdp.npz`` of ``simlab estimate``."""
    from simlab.agents.storage import load_npz
    from simlab.data.mdp import load_mdp

    path = Path(path)
    if path.is_dir():
        return load_qtable_twin(path)
    arrays, _meta = load_npz(path)
    if "Q" in arrays and "T" not in arrays:
        return load_qtable_twin(path)
    return TransferModel.from_mdp(load_mdp(path), name=str(path))
