"""Does a policy trained in the twin reach the goal on the real robot? The transfer report.

A simulated twin of a real lab is worth what its policies do on the real robot. This module
scores a twin's policy on the **real** transition model by the expected number of decisions
to reach a goal from the start states, against the best any policy can do on that model:

* :func:`optimal_steps` — minimum expected number of decisions to the goal on a dense
  ``P[s, a, s']`` using allowed actions only: a stochastic shortest path with unit costs
  (Bertsekas & Tsitsiklis 1991, "An analysis of stochastic shortest path problems"), solved
  by policy iteration (exact linear solves, finitely many steps) started from a proper policy;
  ``inf`` where no policy reaches the goal with probability 1 (the almost-sure reachability
  fixed point, Baier & Katoen 2008, "Principles of Model Checking", sec. 10.6.1);
* :func:`policy_steps` — expected steps under a fixed deterministic policy: hitting times of
  the absorbing chain (Kemeny & Snell 1960, "Finite Markov Chains", ch. III), ``inf`` for the
  states from which the policy is not sure to arrive;
* :func:`twin_policy` / :func:`policy_from_q` — the twin's policy: the shortest-path policy
  of a twin model, or the greedy policy of a Q-table written by ``simlab train``;
* :func:`transfer_report` — per goal and per twin (one twin per seed): steps from the start
  states on the real model, the real optimum, their ratio, the share of starts that never
  arrive, per-state disagreement and excess steps; across twins mean, worst, best and spread;
* the report's markdown and figure (:func:`plot_transfer`), and ``simlab transfer``
  (:func:`transfer_command`).

Decisions:

* **Untried real pairs.** On a real count model the robot never tried some ``(s, a)``; no
  data says where it would go, so such a pair is not an action of the real optimum (the
  ``allowed`` mask), and a twin policy that chooses it is scored as **staying put** there
  (the self-loop ``simlab estimate`` also writes for an unvisited row): from any state whose
  walk reaches that state the policy never arrives, ``inf`` steps. The number of such states
  is reported per twin (``untried``). The rule ``untried="mask"`` instead chooses the twin's
  policy among the pairs the real robot tried (a twin that knows the real coverage).
* **Ties.** Among actions whose expected steps are equal within ``1e-9`` (relative), the
  lowest action index; a state with no way to the goal takes its lowest allowed action.
* **Action sets.** Twin and real model must hold the same primitives. A twin of simlab's 16
  primitives is read on an 8-action real set through the columns
  :meth:`simlab.base.actions.ActionSet.primitives` gives (the twin's action doing each real
  action); a real action the twin has no column for is an error.
* **Starts.** Default: every non-goal state the real robot left at least once. Start states
  from which even the real optimum cannot reach the goal are dropped (reported as
  ``unreachable_starts``): no policy can be scored there. Mean steps over the starts are
  uniform or weighted by the real visits of each start state (``weights``); a mean over
  starts of which one never arrives is ``inf`` ("never" in the reports).
* **A floor for the score.** The optimum of an estimated real model is biased low (its plan
  exploits lucky samples), so even a perfect twin scores above it; :func:`transfer_floor`
  estimates by how much at the real data's sample size, and the reports print it beside the
  twins' scores.
* **Goals** (command): ``--goal-states 18,34`` is one goal made of those states (named
  ``s18+34``, as ``simlab train --goal-states``); without it, the goals recorded in the real
  ``mdp.npz``, else those of the first twin (its Q-tables' goals, or its ``mdp.npz``'s);
  none of them is an error.
"""

from __future__ import annotations

import io
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from simlab.base import validation
from simlab.base.actions import ActionSet, ActionSetOptions
from simlab.base.errors import ConfigError
from simlab.base.options import command, option

__all__ = [
    "GoalTransfer",
    "QTable",
    "QTableTwin",
    "TransferConfig",
    "TransferFiles",
    "TransferFloor",
    "TransferModel",
    "TransferResult",
    "TwinScore",
    "load_twin",
    "optimal_steps",
    "plot_transfer",
    "policy_from_q",
    "policy_steps",
    "real_optimal_actions",
    "render_transfer_png",
    "transfer_command",
    "transfer_floor",
    "transfer_markdown",
    "transfer_report",
    "twin_columns",
    "twin_policy",
]

#: Relative tolerance of "equal expected steps" (ties, real-optimal actions).
TIE_RTOL = 1e-9

#: What a twin's choice of a pair the real robot never tried means (``untried`` option).
UNTRIED_RULES = {
    "stay": "the twin's policy as it is; an untried real (s, a) keeps the robot in place, "
            "so it never arrives from there",
    "mask": "the twin's policy chosen among the (s, a) the real robot tried",
}

#: Files of ``simlab transfer`` in its ``--out`` directory.
FILES = ("transfer.json", "transfer.md", "transfer.png")

#: ``kind`` of ``transfer.json``: ``--overwrite`` replaces only a file carrying it.
KIND = "simlab-transfer"


# --------------------------------------------------------------------------------------
# Pure solvers on dense arrays
# --------------------------------------------------------------------------------------


def _check_P(P: ArrayLike) -> NDArray[np.float64]:
    from simlab.agents.planning import validate_mdp

    P = np.asarray(P, dtype=np.float64)
    validate_mdp(P)
    return P


def goal_mask(goal: ArrayLike, n_states: int, *, key: str = "goal_states") -> NDArray[np.bool_]:
    """(S,) bool goal mask from a bool mask or a sequence of state ids (checked)."""
    g = np.asarray(goal)
    if g.dtype == bool:
        if g.shape != (n_states,):
            raise ConfigError(f"expected a ({n_states},) bool mask, got shape {g.shape}", key=key)
        mask = g.copy()
    else:
        ids = g.ravel()
        if ids.size and not np.issubdtype(ids.dtype, np.integer):
            raise ConfigError(f"expected state ids, got {g.tolist()!r}", key=key)
        bad = [int(s) for s in ids if not 0 <= int(s) < n_states]
        if bad:
            raise ConfigError(f"states {bad} not in [0, {n_states})", key=key)
        mask = np.zeros(n_states, dtype=bool)
        mask[ids.astype(np.int64)] = True
    if not mask.any():
        raise ConfigError("no goal state", key=key, fix="give at least one state, e.g. 18")
    return mask


def _allowed(mask: ArrayLike | None, S: int, A: int) -> NDArray[np.bool_]:
    if mask is None:
        return np.ones((S, A), dtype=bool)
    m = np.asarray(mask)
    if m.dtype != bool or m.shape != (S, A):
        raise ConfigError(f"expected an ({S}, {A}) bool mask, got {m.dtype} {m.shape}",
                          key="mask")
    return m


def _sure_reach(P: NDArray[np.float64], goal: NDArray[np.bool_], allowed: NDArray[np.bool_]
                ) -> tuple[NDArray[np.bool_], NDArray[np.bool_], NDArray[np.int64]]:
    """States from which some policy reaches ``goal`` with probability 1.

    The fixed point of Baier & Katoen (2008), sec. 10.6.1: keep the states ``U`` that can
    reach the goal with positive probability using only actions whose successors all stay in
    ``U``; repeat until ``U`` no longer shrinks. Returns ``(U (S,), safe (S, A), layer (S,))``
    with ``safe`` the allowed actions that never leave ``U`` and ``layer[s]`` the number of
    such steps from ``s`` to the goal (-1 outside ``U``).
    """
    S = P.shape[0]
    support = P > 0
    U = np.ones(S, dtype=bool)
    while True:
        safe = allowed & ~(support & ~U[None, None, :]).any(axis=2)
        safe[~U] = False
        layer = np.full(S, -1, dtype=np.int64)
        layer[goal] = 0
        reach = goal.copy()
        k = 0
        while True:
            k += 1
            into = (safe[:, :, None] & support & reach[None, None, :]).any(axis=(1, 2))
            new = into & U & ~reach
            if not new.any():
                break
            layer[new] = k
            reach |= new
        if np.array_equal(reach, U):
            return U, safe, layer
        U = reach


def _evaluate(P_pi: NDArray[np.float64], F: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Hitting times (S,) of the absorbing chain ``P_pi`` (S, S) from the states ``F``,
    every other state counted as arrived (0); ``F`` must be sure to leave itself."""
    h = np.zeros(P_pi.shape[0])
    idx = np.flatnonzero(F)
    if idx.size:
        M = np.eye(idx.size) - P_pi[np.ix_(idx, idx)]
        h[idx] = np.linalg.solve(M, np.ones(idx.size))
    return h


def _q_steps(P: NDArray[np.float64], V: NDArray[np.float64], safe: NDArray[np.bool_]
             ) -> NDArray[np.float64]:
    """(S, A) expected steps of taking ``a`` then acting optimally; inf for unsafe actions."""
    Vf = np.where(np.isfinite(V), V, 0.0)
    Q = 1.0 + P @ Vf
    return np.where(safe, Q, np.inf)


def _solve(P: NDArray[np.float64], goal: NDArray[np.bool_], allowed: NDArray[np.bool_]
           ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """``(V (S,), Q (S, A), policy (S,))`` of the unit-cost shortest path to ``goal``.

    Policy iteration from the proper policy of the reachability layers (each state steps
    with positive probability to a lower layer), so every iterate is proper and evaluated
    exactly; improvement keeps the current action unless another is better by more than the
    tie tolerance (so it terminates). Then the greedy policy with ties to the lowest index.
    """
    S, A = P.shape[:2]
    U, safe, layer = _sure_reach(P, goal, allowed)
    F = U & ~goal
    policy = np.zeros(S, dtype=np.int64)
    lower = layer[None, None, :] < layer[:, None, None]  # (S, 1, S'): s' in a lower layer
    down = safe & ((P > 0) & lower & U[None, None, :]).any(axis=2)
    for s in np.flatnonzero(F):
        policy[s] = int(np.flatnonzero(down[s])[0])
    for s in np.flatnonzero(~F):
        ok = np.flatnonzero(allowed[s])
        policy[s] = int(ok[0]) if ok.size else 0
    rows = np.arange(S)
    V = np.zeros(S)
    for _ in range(S * A + 1):
        V = _evaluate(P[rows, policy], F)
        Q = _q_steps(P, V, safe)
        best = Q.min(axis=1)
        current = Q[rows, policy]
        better = F & (current > best + TIE_RTOL * (1.0 + best))
        if not better.any():
            break
        policy[better] = np.argmin(Q[better], axis=1)
    V = np.where(U, V, np.inf)
    V[goal] = 0.0
    Q = _q_steps(P, V, safe)
    ties = Q <= (V + TIE_RTOL * (1.0 + np.where(np.isfinite(V), V, 0.0)))[:, None]
    greedy = policy.copy()
    for s in np.flatnonzero(F):
        greedy[s] = int(np.flatnonzero(ties[s])[0])
    if not np.array_equal(greedy, policy):
        # a greedy policy of V* is optimal (Bertsekas & Tsitsiklis 1991, prop. 2); within the
        # tie tolerance it could close a loop, so it is checked and the iterate kept if so
        h = _evaluate_policy(P, greedy, goal, None)
        if np.all(np.isfinite(h[F])) and np.allclose(h[F], V[F], rtol=1e-7, atol=1e-9):
            policy = greedy
    return V, Q, policy


def optimal_steps(P: ArrayLike, goal: ArrayLike, mask: ArrayLike | None = None
                  ) -> NDArray[np.float64]:
    """Minimum expected number of decisions to reach the goal, (S,) float64.

    Args:
        P: (S, A, S) transition probabilities, rows summing to 1.
        goal: (S,) bool goal mask, or the goal state ids (arrival ends the count: 0 there).
        mask: (S, A) bool actions allowed (None: all). On a real count model, the pairs the
            robot tried: an untried pair has no data, so no plan may use it.

    Returns:
        (S,) expected steps of the best policy; ``inf`` where no policy using allowed
        actions reaches the goal with probability 1 (module docstring).
    """
    P = _check_P(P)
    g = goal_mask(goal, P.shape[0])
    return _solve(P, g, _allowed(mask, *P.shape[:2]))[0]


def real_optimal_actions(P: ArrayLike, goal: ArrayLike, mask: ArrayLike | None = None
                         ) -> NDArray[np.bool_]:
    """(S, A) bool: the allowed actions that are optimal (within the tie tolerance) from
    each state with a finite optimum; all False at goal states and where the goal is out of
    reach."""
    P = _check_P(P)
    S, A = P.shape[:2]
    g = goal_mask(goal, S)
    V, Q, _ = _solve(P, g, _allowed(mask, S, A))
    return _optimal_actions(V, Q, g)


def _optimal_actions(V: NDArray[np.float64], Q: NDArray[np.float64], goal: NDArray[np.bool_]
                     ) -> NDArray[np.bool_]:
    fin = np.isfinite(V) & ~goal
    out = Q <= (V + TIE_RTOL * (1.0 + np.where(np.isfinite(V), V, 0.0)))[:, None]
    out &= np.isfinite(Q)
    out[~fin] = False
    return out


def _evaluate_policy(P: NDArray[np.float64], policy: NDArray[np.int64],
                     goal: NDArray[np.bool_], allowed: NDArray[np.bool_] | None
                     ) -> NDArray[np.float64]:
    S = P.shape[0]
    rows = np.arange(S)
    P_pi = P[rows, policy].copy()
    if allowed is not None:
        stuck = ~allowed[rows, policy]
        P_pi[stuck] = 0.0
        P_pi[stuck, rows[stuck]] = 1.0
    support = P_pi > 0
    support[goal] = False  # the goal absorbs
    reach = goal.copy()
    while True:
        new = (support & reach[None, :]).any(axis=1) & ~reach
        if not new.any():
            break
        reach |= new
    doomed = ~reach
    while True:  # a positive chance of entering a doomed state dooms too
        new = (support & doomed[None, :]).any(axis=1) & ~doomed & ~goal
        if not new.any():
            break
        doomed |= new
    h = _evaluate(P_pi, ~doomed & ~goal)
    h[doomed] = np.inf
    return h


def _check_policy(policy: ArrayLike, S: int, A: int) -> NDArray[np.int64]:
    pi = np.asarray(policy)
    if pi.shape != (S,) or (pi.size and not np.issubdtype(pi.dtype, np.integer)):
        raise ConfigError(f"expected ({S},) action indices, got {pi.dtype} {pi.shape}",
                          key="policy")
    if pi.size and (pi.min() < 0 or pi.max() >= A):
        raise ConfigError(f"actions must lie in 0..{A - 1}", key="policy")
    return pi.astype(np.int64)


def policy_steps(P: ArrayLike, policy: ArrayLike, goal: ArrayLike,
                 mask: ArrayLike | None = None) -> NDArray[np.float64]:
    """Expected number of decisions to reach the goal under a deterministic policy, (S,).

    Args:
        P: (S, A, S) transition probabilities.
        policy: (S,) action of each state.
        goal: (S,) bool goal mask or goal state ids (0 steps there).
        mask: (S, A) bool pairs with data (None: all). A policy choosing an untried pair
            **stays put** there (module docstring), so it never arrives from that state.

    Returns:
        (S,) hitting times of the goal in the policy's absorbing chain (Kemeny & Snell 1960,
        thm. 3.3.5: ``(I - Q)^-1 1``); ``inf`` for states from which the chain reaches the
        goal with probability below 1.
    """
    P = _check_P(P)
    S, A = P.shape[:2]
    pi = _check_policy(policy, S, A)
    g = goal_mask(goal, S)
    return _evaluate_policy(P, pi, g, None if mask is None else _allowed(mask, S, A))


def twin_policy(P_twin: ArrayLike, goal: ArrayLike, mask: ArrayLike | None = None
                ) -> NDArray[np.int64]:
    """(S,) the twin's shortest-path policy: fewest expected decisions to ``goal`` on
    ``P_twin`` (S, A, S) over the ``mask`` (S, A) actions; ties to the lowest action index, a
    state without a way to the goal its lowest allowed action (module docstring)."""
    P = _check_P(P_twin)
    S, A = P.shape[:2]
    return _solve(P, goal_mask(goal, S), _allowed(mask, S, A))[2]


# --------------------------------------------------------------------------------------
# Models, twins and action sets
# --------------------------------------------------------------------------------------


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
        object.__setattr__(self, "allowed", _allowed(self.allowed, S, A))
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

    @classmethod
    def from_counts(cls, counts: ArrayLike, *, name: str = "counts",
                    action_set: ActionSet | None = None,
                    centres: ArrayLike | None = None) -> TransferModel:
        """From counts n(s, a, s') (S, A, S): T the frequencies, an untried pair a stay."""
        from simlab.data.estimate import transition_matrix

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
        visits = None
        if mdp.counts is not None:
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
        return cls(T=T, allowed=allowed, name=name or str(mdp.source or "mdp"),
                   action_set=mdp.action_set, visits=visits,
                   counts=None if mdp.counts is None else np.asarray(mdp.counts, np.int64),
                   centres=None if mdp.centres is None else np.asarray(mdp.centres),
                   goals=goals)


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


# --------------------------------------------------------------------------------------
# The report
# --------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class TwinScore:
    """One twin's policy for one goal, scored on the real model.

    ``policy`` (S,) real action numbers; ``steps`` (S,) expected decisions to the goal on
    the real model (inf: never); ``excess`` (S,) ``steps - optimum`` (nan where the optimum
    is infinite, 0 at goal states); ``disagree`` (S,) bool the action is not a real-optimal
    one (False at goal states and where the optimum is infinite); ``regret`` (S,) one-step
    regret, the extra expected steps of taking the twin's action once and then acting
    optimally, ``Q*(s, pi(s)) - V*(s)`` (inf for an untried action, nan where the optimum is
    infinite, 0 at goal states); ``untried`` (S,) bool the
    action was never tried by the real robot there; ``mean_steps`` the weighted mean over
    the start states; ``never_share`` share (weighted) of start states that never arrive.
    """

    name: str
    policy: NDArray[np.int64]
    steps: NDArray[np.float64]
    excess: NDArray[np.float64]
    disagree: NDArray[np.bool_]
    regret: NDArray[np.float64]
    untried: NDArray[np.bool_]
    mean_steps: float
    never_share: float
    ratio: float


@dataclass(frozen=True, eq=False)
class GoalTransfer:
    """The transfer to one goal: the real optimum and every twin's score.

    ``goal`` (S,) bool; ``starts`` (n,) start states scored, ``weights`` (n,) summing to 1;
    ``unreachable_starts`` start states dropped (the real optimum is infinite there);
    ``optimum`` (S,) real optimal steps; ``optimum_mean`` its weighted mean over starts.
    """

    name: str
    goal: NDArray[np.bool_]
    starts: NDArray[np.int64]
    weights: NDArray[np.float64]
    unreachable_starts: tuple[int, ...]
    optimum: NDArray[np.float64]
    optimum_mean: float
    twins: tuple[TwinScore, ...]
    floor: TransferFloor | None = None

    @property
    def means(self) -> NDArray[np.float64]:
        """(n_twins,) mean steps of each twin."""
        return np.array([t.mean_steps for t in self.twins])

    def summary(self) -> dict[str, float]:
        """Across twins: ``mean``, ``worst``, ``best``, ``spread`` (standard deviation) of
        the mean steps (inf when any twin never arrives from some start), and ``excess``
        of the mean over the optimum (fraction)."""
        m = self.means
        anyinf = not np.all(np.isfinite(m))
        mean = math.inf if anyinf else float(m.mean())
        return {"mean": mean, "worst": float(m.max()), "best": float(m.min()),
                "spread": math.inf if anyinf else float(m.std()),
                "excess": (mean / self.optimum_mean - 1.0) if self.optimum_mean > 0
                else math.nan}


@dataclass(frozen=True, eq=False)
class TransferResult:
    """:func:`transfer_report`'s result: one :class:`GoalTransfer` per goal."""

    goals: tuple[GoalTransfer, ...]
    real_name: str
    twin_names: tuple[str, ...]
    action_set: ActionSet | None
    weighting: str
    centres: NDArray[np.float64] | None = None
    untried: str = "stay"

    def to_json(self) -> dict[str, Any]:
        """Plain types; infinite steps are ``null`` ("never")."""
        return {
            "kind": KIND,
            "real": self.real_name,
            "twins": list(self.twin_names),
            "action_set": None if self.action_set is None else self.action_set.to_json(),
            "weights": self.weighting,
            "untried": self.untried,
            "untried_rule": UNTRIED_RULES[self.untried],
            "goals": [_goal_json(g) for g in self.goals],
        }

    def summary_line(self) -> str:
        """``twin policy: mean X steps, worst Y, real optimum Z (+N %)``, one such clause
        per goal (prefixed by its name when there are several); a mean over twins of which
        some never arrive says how many."""
        parts = []
        for g in self.goals:
            s = g.summary()
            label = "twin policy" if len(self.goals) == 1 else f"goal {g.name}: twin policy"
            never = int(np.sum(~np.isfinite(g.means)))
            mean = (f"mean {_steps(s['mean'])} steps" if math.isfinite(s["mean"]) else
                    f"{never} of {len(g.twins)} twin(s) never arrive from some start, best "
                    f"{_steps(s['best'])} steps")
            part = (f"{label}: {mean}, worst {_steps(s['worst'])}, real optimum "
                    f"{_steps(g.optimum_mean)} ({_pct(s['excess'])})")
            if g.floor is not None:
                part += (f"; a perfect twin would score {_pct(g.floor.median - 1.0)} (95 %: "
                         f"{_pct(g.floor.low - 1.0)} to {_pct(g.floor.high - 1.0)})")
            parts.append(part)
        return "; ".join(parts)


def _num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _steps(x: float) -> str:
    return f"{x:.2f}" if math.isfinite(x) else "never"


def _pct(x: float) -> str:
    if math.isnan(x):
        return "n/a"
    return f"{100 * x:+.1f} %" if math.isfinite(x) else "never"


def _floats(a: ArrayLike) -> list[float | None]:
    return [_num(float(v)) for v in np.asarray(a, dtype=np.float64)]


def _goal_json(g: GoalTransfer) -> dict[str, Any]:
    s = g.summary()
    return {
        "name": g.name,
        "goal_states": np.flatnonzero(g.goal).tolist(),
        "start_states": g.starts.tolist(),
        "weights": g.weights.tolist(),
        "unreachable_starts": list(g.unreachable_starts),
        "optimum_mean": _num(g.optimum_mean),
        "optimum": _floats(g.optimum),
        "across_twins": {k: _num(v) for k, v in s.items()},
        "perfect_twin_floor": None if g.floor is None else g.floor.to_json(),
        "twins": [{
            "name": t.name, "mean_steps": _num(t.mean_steps), "ratio": _num(t.ratio),
            "never_share": t.never_share,
            "disagreements": int(t.disagree.sum()),
            "untried_choices": int(t.untried.sum()),
            "policy": t.policy.tolist(), "steps": _floats(t.steps),
            "excess": _floats(t.excess), "regret": _floats(t.regret),
            "disagree_states": np.flatnonzero(t.disagree).tolist(),
        } for t in g.twins],
    }


def _start_states(real: TransferModel, goal: NDArray[np.bool_],
                  starts: ArrayLike | None) -> NDArray[np.int64]:
    S = real.n_states
    if starts is None:
        left = real.allowed.any(axis=1) if real.visits is None else real.visits > 0
        return np.flatnonzero(left & ~goal).astype(np.int64)
    ids = np.asarray(starts).ravel()
    if ids.size and not np.issubdtype(ids.dtype, np.integer):
        raise ConfigError(f"expected state ids, got {ids.tolist()!r}", key="start_states")
    bad = [int(s) for s in ids if not 0 <= int(s) < S]
    if bad:
        raise ConfigError(f"states {bad} not in [0, {S})", key="start_states")
    ids = np.unique(ids.astype(np.int64))
    return ids[~goal[ids]]


def _weights(real: TransferModel, starts: NDArray[np.int64], weighting: str
             ) -> NDArray[np.float64]:
    if weighting == "uniform" or starts.size == 0:
        return np.full(starts.size, 1.0 / max(starts.size, 1))
    if weighting != "visits":
        raise ConfigError(f"expected uniform or visits, got {weighting!r}", key="weights")
    if real.visits is None:
        raise ConfigError("the real model has no visit counts", key="weights",
                          fix="use --weights uniform, or give the real counts")
    w = real.visits[starts].astype(np.float64)
    if w.sum() <= 0:
        raise ConfigError("the start states were never visited by the real robot",
                          key="weights", fix="use --weights uniform")
    return w / w.sum()


def _weighted_mean(values: NDArray[np.float64], w: NDArray[np.float64]) -> float:
    if values.size == 0:
        return math.nan
    pos = w > 0
    if not np.all(np.isfinite(values[pos])):
        return math.inf
    return float(np.sum(values[pos] * w[pos]))


def _twin_policy_for(twin: TransferModel | QTableTwin, goal: NDArray[np.bool_], name: str,
                     columns: NDArray[np.int64], restrict: NDArray[np.bool_] | None
                     ) -> NDArray[np.int64]:
    if isinstance(twin, QTableTwin):
        table = twin.table_for(goal)
        if table is None:
            raise ConfigError(f"no Q-table for goal {name} (states "
                              f"{np.flatnonzero(goal).tolist()})", path=twin.name,
                              key="goal", fix="train it with simlab train --goal-states, or "
                              "choose --goal-states of a trained goal")
        return policy_from_q(table, columns, restrict)
    mask = twin.allowed[:, columns]
    if restrict is not None:
        mask = mask & restrict
    return twin_policy(twin.T[:, columns], goal, mask)


def transfer_report(
    real: TransferModel,
    twins: Sequence[TransferModel | QTableTwin],
    goals: Mapping[str, ArrayLike],
    starts: ArrayLike | None = None,
    *,
    weights: str = "uniform",
    untried: str = "stay",
    n_boot: int = 0,
    rng: np.random.Generator | None = None,
) -> TransferResult:
    """Score each twin's policy on the real model, for each goal.

    Args:
        real: the real robot's model (:meth:`TransferModel.from_counts` or ``from_mdp``);
            its ``allowed`` pairs are the only ones a real plan may use, an untried pair
            chosen by a twin keeps the robot in place (module docstring).
        twins: one per twin seed: a :class:`TransferModel` (its shortest-path policy,
            :func:`twin_policy`, over its allowed pairs) or a :class:`QTableTwin` (the
            greedy policy of its Q-table for the goal, :func:`policy_from_q`). Same states
            as ``real``; actions mapped onto the real ones by :func:`twin_columns`.
        goals: goal name -> (S,) bool mask or goal state ids.
        starts: start state ids (goal states removed); None: every non-goal state the real
            robot left (visits > 0, else any tried pair).
        weights: ``uniform`` over the start states, or ``visits`` (the real decisions taken
            in each start state).
        untried: ``stay`` (default): the twin's policy as it is; where it picks a pair the
            real robot never tried, the robot stays put (never arrives from there, module
            docstring). ``mask``: the twin's policy is chosen among the pairs the real
            robot tried (a twin that knows the real coverage); the strict score is then
            no longer what the twin alone would do.
        n_boot: resamples of :func:`transfer_floor` (0: no floor); needs ``real.counts``.
        rng: the Generator of those resamples (required when ``n_boot > 0``).

    Returns:
        A :class:`TransferResult`; steps in decisions (actions), ``inf`` = never arrives.

    Raises:
        ConfigError: no twin or goal, states or actions that disagree, a goal without a
            Q-table, bad start states or weights.
    """
    if not twins:
        raise ConfigError("no twin to score", key="sim")
    if not goals:
        raise ConfigError("no goal", key="goal_states", fix="give --goal-states, e.g. 18,34")
    if weights not in ("uniform", "visits"):
        raise ConfigError(f"expected uniform or visits, got {weights!r}", key="weights")
    if untried not in UNTRIED_RULES:
        raise ConfigError(f"expected stay or mask, got {untried!r}", key="untried")
    restrict = real.allowed if untried == "mask" else None
    if n_boot and rng is None:
        raise ConfigError("the sampling floor needs a numpy Generator", key="rng",
                          fix="pass rng=np.random.default_rng(seed), or n_boot=0")
    S, A = real.n_states, real.n_actions
    cols = []
    for t in twins:
        if t.n_states != S:
            raise ConfigError(f"{t.n_states} states against the real model's {S}",
                              path=t.name, key="states",
                              fix="use twins built on the real model's states file")
        cols.append(twin_columns(t.action_set, real.action_set, n_twin=t.n_actions,
                                 n_real=A, where=t.name))
    out = []
    for gname, gspec in goals.items():
        g = goal_mask(gspec, S)
        V, Q, _ = _solve(real.T, g, real.allowed)
        best_actions = _optimal_actions(V, Q, g)
        st = _start_states(real, g, starts)
        unreachable = tuple(int(s) for s in st if not np.isfinite(V[s]))
        st = st[np.isfinite(V[st])]
        w = _weights(real, st, weights)
        opt_mean = _weighted_mean(V[st], w)
        scores = []
        for t, c in zip(twins, cols, strict=True):
            pi = _twin_policy_for(t, g, gname, c, restrict)
            steps = _evaluate_policy(real.T, pi, g, real.allowed)
            fin = np.isfinite(V)
            excess = np.where(fin, steps - np.where(fin, V, 0.0), np.nan)
            excess[g] = 0.0
            disagree = fin & ~g & ~best_actions[np.arange(S), pi]
            regret = np.where(fin, Q[np.arange(S), pi] - np.where(fin, V, 0.0), np.nan)
            regret[g] = 0.0
            mean = _weighted_mean(steps[st], w)
            never = float(np.sum(w[~np.isfinite(steps[st])])) if st.size else 0.0
            ratio = mean / opt_mean if opt_mean > 0 else math.nan
            scores.append(TwinScore(name=t.name, policy=pi, steps=steps, excess=excess,
                                    disagree=disagree, regret=regret,
                                    untried=~g & ~real.allowed[np.arange(S), pi],
                                    mean_steps=mean,
                                    never_share=never, ratio=ratio))
        floor = None
        if n_boot and real.counts is not None and st.size:
            floor = transfer_floor(real, g, st, w, n_boot=n_boot, rng=rng)  # type: ignore[arg-type]
        out.append(GoalTransfer(name=str(gname), goal=g, starts=st, weights=w,
                                unreachable_starts=unreachable, optimum=V,
                                optimum_mean=opt_mean, twins=tuple(scores), floor=floor))
    return TransferResult(goals=tuple(out), real_name=real.name,
                          twin_names=tuple(t.name for t in twins),
                          action_set=real.action_set, weighting=weights,
                          centres=real.centres, untried=untried)


@dataclass(frozen=True)
class TransferFloor:
    """What a perfect twin scores against a real model estimated from this much data.

    ``ratios`` (n_boot,) mean steps of the perfect twin's policy over the resampled real
    optimum (inf: it never arrives from some start in that resample); ``median``, ``low``,
    ``high`` their 50, 2.5 and 97.5 % quantiles.
    """

    ratios: NDArray[np.float64]
    median: float
    low: float
    high: float

    def to_json(self) -> dict[str, Any]:
        return {"n_boot": int(self.ratios.size), "ratio_median": _num(self.median),
                "ratio_low_2.5": _num(self.low), "ratio_high_97.5": _num(self.high),
                "never_share": float(np.mean(~np.isfinite(self.ratios)))}


def transfer_floor(real: TransferModel, goal: ArrayLike, starts: ArrayLike,
                   weights: ArrayLike, *, n_boot: int, rng: np.random.Generator
                   ) -> TransferFloor:
    """The ratio a perfect twin scores, by parametric bootstrap of the real counts.

    The optimum of an estimated model is biased low: its plan exploits the transitions that
    were lucky in the sample (the optimizer's curse, Smith & Winkler 2006, Management
    Science 52(3)), so even a twin equal to the true robot scores above the "real optimum".
    How much depends on the number of real transitions per pair. Each resample draws
    ``counts*(s, a, .) ~ Multinomial(n(s, a), T(s, a, .))`` (Efron & Tibshirani 1993, ch. 6),
    then scores the real optimum's policy (standing for the true robot's plan) on the
    resampled model against that model's own optimum: mean steps over ``starts`` with
    ``weights`` (starts the resample cannot reach are left out of that resample). A
    resample never holds a transition the real data missed, so with few real transitions per
    pair the gap it finds is rather a lower bound of the true one.

    Args:
        real: the real model with its ``counts`` (S, A, S).
        goal: (S,) bool or goal state ids.
        starts: (n,) start states; weights: (n,) their weights.
        n_boot: resamples (>= 1); rng: their Generator.
    """
    from simlab.data.estimate import transition_matrix

    if real.counts is None:
        raise ConfigError("the real model has no counts", path=real.name, key="counts",
                          fix="give the real count file or an mdp.npz with counts")
    S = real.n_states
    g = goal_mask(goal, S)
    st = np.asarray(starts, dtype=np.int64)
    w = np.asarray(weights, dtype=np.float64)
    pi = _solve(real.T, g, real.allowed)[2]
    n_sa = real.counts.sum(axis=2)
    ratios = np.empty(int(n_boot))
    for b in range(int(n_boot)):
        T, visited = transition_matrix(rng.multinomial(n_sa, real.T / real.T.sum(axis=2,
                                                                                keepdims=True)))
        V = _solve(T, g, visited)[0]
        h = _evaluate_policy(T, pi, g, visited)
        keep = np.isfinite(V[st]) & (w > 0)
        if not keep.any():
            ratios[b] = math.nan
            continue
        wk = w[keep] / w[keep].sum()
        opt = float(np.sum(V[st][keep] * wk))
        hk = h[st][keep]
        ratios[b] = math.inf if not np.all(np.isfinite(hk)) else float(np.sum(hk * wk)) / opt
    r = ratios[~np.isnan(ratios)]
    if r.size == 0:
        return TransferFloor(ratios=ratios, median=math.nan, low=math.nan, high=math.nan)
    q = np.quantile(r, [0.5, 0.025, 0.975], method="inverted_cdf")
    return TransferFloor(ratios=ratios, median=float(q[0]), low=float(q[1]), high=float(q[2]))


# --------------------------------------------------------------------------------------
# Markdown and figure
# --------------------------------------------------------------------------------------


def transfer_markdown(result: TransferResult) -> str:
    """The markdown report: per goal, the real optimum and every twin's score."""
    out = io.StringIO()
    out.write(f"# Transfer of twin policies to {result.real_name}\n\n")
    aset = "unknown action set" if result.action_set is None else result.action_set.describe()
    out.write(f"Real model: `{result.real_name}` ({aset}). Twins: "
              + ", ".join(f"`{n}`" for n in result.twin_names) + ".\n\n"
              "Steps are expected decisions to the goal on the real model; \"never\" = the "
              f"policy is not sure to arrive. Rule `{result.untried}`: "
              f"{UNTRIED_RULES[result.untried]}. A state disagrees when the twin's action is "
              "not one of the real optimal ones; its one-step regret is the extra expected "
              "steps of that action once. Start states are weighted "
              f"`{result.weighting}`.\n")
    for g in result.goals:
        s = g.summary()
        out.write(f"\n## Goal {g.name} (states {', '.join(map(str, np.flatnonzero(g.goal)))})"
                  f"\n\n{g.starts.size} start states; real optimum "
                  f"**{_steps(g.optimum_mean)}** steps.")
        if g.unreachable_starts:
            out.write(f" Dropped: start states {list(g.unreachable_starts)}, from which no "
                      "real policy reaches the goal.")
        out.write("\n\n| twin | mean steps | / optimum | starts never arriving | "
                  "states disagreeing | their mean one-step regret (steps) | "
                  "untried real pairs chosen |\n|---|---|---|---|---|---|---|\n")
        for t in g.twins:
            ratio = "never" if math.isinf(t.ratio) else _cell(t.ratio, "{:.3f}")
            r = t.regret[t.disagree]
            regret = "never" if np.isinf(r).any() else (f"{r.mean():.2f}" if r.size else "-")
            out.write(f"| `{t.name}` | {_steps(t.mean_steps)} | {ratio} | "
                      f"{100 * t.never_share:.0f} % | {int(t.disagree.sum())} | {regret} | "
                      f"{int(t.untried.sum())} |\n")
        out.write(f"\nAcross {len(g.twins)} twin(s): mean {_steps(s['mean'])}, worst "
                  f"{_steps(s['worst'])}, best {_steps(s['best'])}, spread (std) "
                  f"{_steps(s['spread'])} steps; mean over the optimum "
                  f"{_pct(s['excess'])}.\n")
        if g.floor is not None:
            f = g.floor
            out.write(f"\nThe real optimum of an estimated model is biased low, so even a "
                      "perfect twin scores above it. A perfect twin (the real robot's own "
                      "plan) scored on real models re-estimated from the same number of "
                      f"transitions ({f.ratios.size} resamples) is {_pct(f.median - 1.0)} "
                      f"above their optimum (95 %: {_pct(f.low - 1.0)} to "
                      f"{_pct(f.high - 1.0)}). The resamples never hold a transition the "
                      "real data missed, so with few transitions per pair this gap is "
                      "rather a lower bound.\n")
    out.write("\n![transfer](transfer.png)\n")
    return out.getvalue()


def _cell(x: float, fmt: str) -> str:
    return fmt.format(x) if math.isfinite(x) else "n/a"


def _panels(g: GoalTransfer) -> list[TwinScore]:
    """The twins drawn on the map: the worst and the best (one when they coincide)."""
    order = sorted(g.twins, key=lambda t: (t.mean_steps, t.never_share))
    return [order[-1]] if len(order) == 1 or order[-1] is order[0] else [order[-1], order[0]]


def _draw_map(ax: Any, g: GoalTransfer, t: TwinScore, centres: NDArray[np.float64] | None,
              vmax: float, grid: Any = None, disc: Any = None) -> Any:
    """One map panel: states coloured by excess steps, ``x`` never arrives, a black ring a
    disagreement with the real optimum, a gold star the goal, hollow the non-start states."""
    from matplotlib import colormaps
    from matplotlib.colors import Normalize

    S = t.steps.size
    if centres is None:
        xy = np.stack([np.arange(S, dtype=float), np.zeros(S)], axis=1)
        ax.set_xlabel("state")
        ax.set_yticks([])
    else:
        xy = np.asarray(centres, dtype=np.float64)
        if grid is not None and disc is not None:
            from discretize.plot import draw_states

            draw_states(ax, grid, disc, numbers=False, robot_radius=None)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_aspect("equal")
    norm = Normalize(0.0, vmax)
    cmap = colormaps["viridis"]
    start = np.zeros(S, dtype=bool)
    start[g.starts] = True
    fin = np.isfinite(t.excess)
    show = start & fin
    ax.scatter(xy[show, 0], xy[show, 1], c=cmap(norm(t.excess[show])), s=90, zorder=3,
               edgecolors=[(0, 0, 0, 1.0 if d else 0.0) for d in t.disagree[show]],
               linewidths=1.8)
    other = ~start & ~g.goal & fin
    ax.scatter(xy[other, 0], xy[other, 1], s=60, facecolors="none",
               edgecolors=cmap(norm(t.excess[other])), zorder=3)
    never = ~g.goal & np.isinf(t.excess)
    if never.any():
        ax.scatter(xy[never, 0], xy[never, 1], marker="X", s=90, color="tab:red", zorder=4,
                   label="never arrives")
    nan = ~g.goal & np.isnan(t.excess)
    if nan.any():
        ax.scatter(xy[nan, 0], xy[nan, 1], marker=".", s=40, color="0.5", zorder=3,
                   label="goal out of real reach")
    untried = t.untried & ~g.goal
    if untried.any():
        ax.scatter(xy[untried, 0], xy[untried, 1], marker="s", s=200, facecolors="none",
                   edgecolors="tab:red", linewidths=1.5, zorder=4,
                   label="action the real robot never tried")
    if t.disagree.any():
        ax.scatter([], [], s=90, facecolors="none", edgecolors="black", linewidths=1.8,
                   label="not a real-optimal action")
    ax.scatter(xy[g.goal, 0], xy[g.goal, 1], marker="*", s=220, color="gold",
               edgecolors="black", zorder=5, label="goal")
    for s in range(S):
        ax.annotate(str(s), xy[s], xytext=(3, 3), textcoords="offset points", fontsize=6)
    score = (f"{_steps(t.mean_steps)} steps" if math.isfinite(t.mean_steps) else
             f"never arrives from {100 * t.never_share:.0f} % of the starts")
    ax.set_title(f"{_short(t.name)}: {score}, {int(t.disagree.sum())} states disagree",
                 fontsize=8)
    from matplotlib.cm import ScalarMappable

    return ScalarMappable(norm=norm, cmap=cmap)


def _draw_bars(ax: Any, g: GoalTransfer) -> None:
    means = g.means
    fin = np.isfinite(means)
    top = max([g.optimum_mean, *means[fin].tolist()]) if math.isfinite(g.optimum_mean) \
        else (float(means[fin].max()) if fin.any() else 1.0)
    top = 1.15 * top if top > 0 else 1.0
    x = np.arange(means.size)
    ax.bar(x[fin], means[fin], color="tab:blue", label="twin policy")
    if not fin.all():
        ax.bar(x[~fin], np.full(int((~fin).sum()), top), color="none", edgecolor="tab:red",
               hatch="//", label="never arrives")
    if math.isfinite(g.optimum_mean):
        ax.axhline(g.optimum_mean, color="k", ls="--", label="real optimum")
        f = g.floor
        if f is not None and math.isfinite(f.low) and math.isfinite(f.high):
            ax.axhspan(g.optimum_mean * f.low, g.optimum_mean * f.high, color="0.85",
                       zorder=0, label="a perfect twin (95 %)")
    ax.set_xticks(x)
    ax.set_xticklabels([_short(t.name) for t in g.twins], rotation=45, ha="right", fontsize=7)
    ax.set_ylabel("expected steps to the goal (real)")
    ax.set_ylim(0, top * 1.05)
    ax.legend(fontsize=7)
    ax.set_title(f"goal {g.name}", fontsize=8)


def _short(name: str) -> str:
    parts = Path(name).parts
    return "/".join(parts[-2:]) if len(parts) > 1 else name


def render_transfer_png(result: TransferResult, *, grid: Any = None, disc: Any = None,
                        dpi: int = 110) -> bytes:
    """The figure as PNG bytes: per goal (a row), the worst and best twins' policies on the
    map (states coloured by excess steps over the real optimum, disagreements ringed), then
    a bar per twin seed of its mean steps against the optimum (dashed)."""
    from matplotlib.figure import Figure

    centres = result.centres if disc is None else np.asarray(disc.centres)
    # a long lab (a corridor, or states in a line without centres) gets one map per row
    wide = True
    if centres is not None:
        span = np.ptp(np.asarray(centres), axis=0)
        wide = bool(span[0] > 2.0 * max(span[1], 1e-9))
    n_maps = max(len(_panels(g)) for g in result.goals)
    if wide:
        per_goal = n_maps + 1
        fig = Figure(figsize=(10.0, 3.0 * per_goal * len(result.goals)), layout="constrained")
        grid_axes = fig.subplots(per_goal * len(result.goals), 1, squeeze=False)[:, 0]
        slots = [(list(grid_axes[i * per_goal: i * per_goal + n_maps]),
                  grid_axes[i * per_goal + n_maps]) for i in range(len(result.goals))]
    else:
        fig = Figure(figsize=(4.6 * (n_maps + 1), 4.2 * len(result.goals)),
                     layout="constrained")
        grid_axes = fig.subplots(len(result.goals), n_maps + 1, squeeze=False)
        slots = [(list(row[:n_maps]), row[n_maps]) for row in grid_axes]
    for g, (map_axes, bar_ax) in zip(result.goals, slots, strict=True):
        panels = _panels(g)
        ex = np.concatenate([t.excess[np.isfinite(t.excess)] for t in g.twins])
        vmax = max(1.0, float(ex.max()) if ex.size else 1.0)
        for ax, t in zip(map_axes, panels, strict=False):
            mappable = _draw_map(ax, g, t, centres, vmax, grid, disc)
            cbar = fig.colorbar(mappable, ax=ax, fraction=0.04)
            cbar.set_label("excess steps", fontsize=7)
            ax.legend(fontsize=6, loc="upper left", bbox_to_anchor=(0.0, -0.18 if wide
                                                                   else -0.12), ncols=3)
        for ax in map_axes[len(panels):]:
            ax.axis("off")
        _draw_bars(bar_ax, g)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def plot_transfer(result: TransferResult, path: str | os.PathLike[str], *, grid: Any = None,
                  disc: Any = None) -> Path:
    """Write :func:`render_transfer_png` to ``path`` atomically."""
    from simlab.base.io import atomic_write_bytes

    atomic_write_bytes(path, render_transfer_png(result, grid=grid, disc=disc))
    return Path(path)


# --------------------------------------------------------------------------------------
# Files
# --------------------------------------------------------------------------------------


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


@dataclass(frozen=True, kw_only=True)
class TransferConfig(ActionSetOptions):
    """Options of ``simlab transfer`` / :func:`transfer_command`. The action-set group
    (``--n-actions/--convention/--speed``) describes a real **count file** only; an
    ``mdp.npz`` records its own."""

    COMMAND = "transfer"
    ARGUMENTS = ("real", "sim", "out")

    real: Path = option(help="the real robot's model: mdp.npz of `simlab estimate --counts`, "
                        "or a count file (CSV/JSON/ISIR) with --states and --n-actions")
    sim: tuple[Path, ...] = option(
        help="the twins, one per seed: mdp.npz of `simlab estimate` (its shortest-path "
        "policy is scored) or a `simlab train` directory / q_*.npz file (its greedy policy)",
        metavar="MDP_OR_QTABLES")
    out: Path = option(help="output directory: transfer.json, transfer.md, transfer.png")
    states: Path | None = option(
        None, "states file of the real data (S and centres of a count file; the map figure)")
    occupancy_map: Path | None = option(
        None, "map.yaml drawn under the states (needs --states)", flag="map")
    goal_states: Any | None = option(
        None, "one goal made of these state ids, e.g. 18,34 (default: the goals recorded in "
        "the real mdp.npz, else those of the twins' Q-tables)", parse=str)
    start_states: Any | None = option(
        None, "start states, e.g. 0,5,7 (default: every non-goal state the real robot left)",
        parse=str)
    weights: str = option("uniform", "mean over the start states: uniform, or weighted by "
                          "the real visits of each", choices=("uniform", "visits"))
    untried: str = option(
        "stay", "a twin action the real robot never tried in that state: stay = it stays "
        "put there (never arrives); mask = choose the twin's policy among the tried ones",
        choices=tuple(UNTRIED_RULES))
    n_boot: int = option(200, "resamples of the perfect-twin floor (0: none; needs the "
                         "real counts)")
    seed: int = option(0, "seed of those resamples")
    plot: bool = option(True, "the figure transfer.png (--no-plot skips it)")
    overwrite: bool = option(False, "replace the outputs of an earlier `simlab transfer`")

    def validate(self) -> None:
        if not self.sim:
            raise ConfigError("no twin given", key="sim", fix="--sim MDP_OR_QTABLES ...")
        for key in ("goal_states", "start_states"):
            object.__setattr__(self, key, validation.state_ids(getattr(self, key), key))
        if self.occupancy_map is not None and self.states is None:
            raise ConfigError("the map figure needs the states file", key="map",
                              fix="add --states STATES.json")
        if self.action_set_given and Path(self.real).suffix == ".npz":
            raise ConfigError("--n-actions/--convention/--speed describe a count file; an "
                              "mdp.npz records its own action set", key="n_actions",
                              fix="drop them")
        self.make_action_set(16)
        validation.whole(self.n_boot, "n_boot", minimum=0)
        validation.whole(self.seed, "seed", minimum=0)


@dataclass(frozen=True)
class TransferFiles:
    """Result of :func:`transfer_command`: the report and the files written."""

    result: TransferResult
    files: dict[str, Path]


def _resolve(p: Path) -> Path:
    return p.expanduser().resolve()


def _check_outputs(cfg: TransferConfig) -> dict[str, Path]:
    """Refuse before any work: an output that is an input, an ``--out`` inside a Q-table
    directory, an existing output (without ``--overwrite``, or not one of ours)."""
    import json

    out = Path(cfg.out)
    paths = {name: out / name for name in FILES if cfg.plot or name != "transfer.png"}
    inputs = [Path(cfg.real), *cfg.sim, *(p for p in (cfg.states, cfg.occupancy_map)
                                          if p is not None)]
    ro = _resolve(out)
    for src in inputs:
        rs = _resolve(src)
        if rs.is_dir() and (ro == rs or rs in ro.parents):
            raise ConfigError("the output directory is inside an input directory",
                              path=out, key="out", fix="choose another --out")
        if any(_resolve(p) == rs for p in paths.values()):
            raise ConfigError("an output would replace this input", path=src, key="out",
                              fix="choose another --out")
    from simlab.base.io import ensure_new

    if out.exists() and not out.is_dir():
        raise ConfigError("the output directory is a file", path=out, key="out",
                          fix="choose another --out, or remove the file in the way")
    for p in paths.values():
        if p.is_dir():
            raise ConfigError("transfer output is a directory", path=p,
                              fix="choose another --out")
        ensure_new(p, overwrite=cfg.overwrite, what="transfer output")
    report = paths["transfer.json"]
    if cfg.overwrite and report.is_file():
        try:
            kind = json.loads(report.read_text(encoding="utf-8")).get("kind")
        except (ValueError, UnicodeDecodeError, AttributeError):
            kind = None
        if kind != KIND:
            raise ConfigError("not written by simlab transfer; --overwrite replaces only "
                              "its own outputs", path=report, fix="choose another --out")
    return paths


def _real_model(cfg: TransferConfig, n_states: int, disc: Any) -> TransferModel:
    from simlab.data.counts import load_counts
    from simlab.data.mdp import load_mdp

    real = Path(cfg.real)
    if real.suffix == ".npz":
        model = TransferModel.from_mdp(load_mdp(real), name=str(real))
        if disc is not None and model.n_states != disc.n_states:
            raise ConfigError(f"{model.n_states} states, the states file has "
                              f"{disc.n_states}", path=real, key="states")
        if disc is not None and model.centres is None:
            model = TransferModel(**{**model.__dict__,
                                     "centres": np.asarray(disc.centres, dtype=np.float64)})
        return model
    aset = cfg.make_action_set(16)
    table = load_counts(real, n_states=n_states, n_actions=aset.n_actions)
    centres = None if disc is None else disc.centres
    return TransferModel.from_counts(table.counts, name=str(real), action_set=aset,
                                     centres=centres)


def _goals(cfg: TransferConfig, real: TransferModel,
           twins: Sequence[TransferModel | QTableTwin]) -> dict[str, Any]:
    from simlab.data.goals import state_goal_name

    if cfg.goal_states is not None:
        return {state_goal_name(cfg.goal_states): np.array(cfg.goal_states)}
    if real.goals:
        return dict(real.goals)
    first = twins[0]
    if isinstance(first, QTableTwin):
        return {tab.name: tab.goal for tab in first.tables}
    if first.goals:
        return dict(first.goals)
    raise ConfigError("no goal: neither the real model nor the first twin records one",
                      path=cfg.real, key="goal_states", fix="give --goal-states, e.g. 18,34")


@command(TransferConfig)
def transfer_command(cfg: TransferConfig) -> TransferFiles:
    """``simlab transfer``: score the twins' policies on the real model; write
    ``transfer.json`` (:meth:`TransferResult.to_json`), ``transfer.md`` and ``transfer.png``
    into ``out`` through one output transaction (nothing is written on any error)."""
    from simlab.base.io import atomic_write_json, atomic_write_text, output_transaction

    paths = _check_outputs(cfg)
    disc = grid = None
    if cfg.states is not None:
        from simlab.physics.inputs import load_discretizer

        disc = load_discretizer(cfg.states)
    if cfg.occupancy_map is not None:
        from discretize.mapio import read_map

        grid = read_map(cfg.occupancy_map)
    twins = [load_twin(p) for p in cfg.sim]
    n_states = disc.n_states if disc is not None else twins[0].n_states
    real = _real_model(cfg, n_states, disc)
    goals = _goals(cfg, real, twins)
    try:
        result = transfer_report(real, twins, goals, cfg.start_states, weights=cfg.weights,
                                 untried=cfg.untried, n_boot=cfg.n_boot,
                                 rng=np.random.default_rng(cfg.seed))
    except ConfigError as exc:
        if exc.path is not None or exc.key not in ("goal_states", "start_states"):
            raise
        raise ConfigError(exc.problem, path=cfg.real, key=exc.key, fix=exc.fix) from None
    with output_transaction(cfg.out, paths.values(), overwrite=cfg.overwrite,
                            what="transfer output") as txn:
        atomic_write_json(txn.path(paths["transfer.json"]),
                          {**result.to_json(), "config": cfg.to_dict()})
        atomic_write_text(txn.path(paths["transfer.md"]), transfer_markdown(result))
        if cfg.plot:
            plot_transfer(result, txn.path(paths["transfer.png"]), grid=grid, disc=disc)
    return TransferFiles(result=result, files=paths)
