"""An online task on an empirical MDP, with changes at given decisions.

The navigation protocol of Dromnelle et al. (2022, sec. 4.1; Living Machines 2020): the
robot starts in one of the start states (drawn uniformly), earns 1 when it arrives in the
goal state and then restarts from a start state; the task changes at a given decision,
either the goal moves (18 -> 34) or passages close (the transitions 20 <-> 21 and 6 <-> 7
are removed). The agent is not told of a change.

Decision for a closed passage ``u <-> v`` on an MDP, as the authors' published
simulation of the protocol does it (the transition is deleted from the model the robot's
moves are drawn from): every ``T(u, a, v)`` and ``T(v, a, u)`` is removed and the row
renormalised over the outcomes that remain (the robot that tried to pass ends where that
action's other recorded outcomes went: mostly staying, sometimes slipping to a
neighbour); a row with no other outcome becomes the self-loop (stopped where it was, as
the obstacle detector stops it in physics). Every row stays a distribution. Closing a
passage the MDP never used changes nothing (and is allowed).

The compiled form :class:`OnlineMdp` holds one ``(S, A, S)`` cumulative ``T`` and one
``(S,)`` reward per phase; phase ``i`` runs from decision ``phase_start[i]`` on.
"""

from __future__ import annotations

from collections import namedtuple
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from simlab.base.errors import ConfigError

__all__ = ["Change", "OnlineMdp", "OnlineTask", "close_passages", "parse_passages"]

#: The compiled task: ``cdf`` (P, S, A, S) cumulative T per phase, ``reward_next`` (P, S)
#: reward on arriving in each state, ``phase_start`` (P,) int64 first decision of each phase
#: (``phase_start[0] == 0``), ``start_cdf`` (S,) cumulative start distribution.
OnlineMdp = namedtuple("OnlineMdp", ["cdf", "reward_next", "phase_start", "start_cdf"])

CHANGE_KINDS = ("goal", "passages")


def parse_passages(items: Sequence[Any], *, key: str = "passages") -> tuple[tuple[int, int], ...]:
    """``["20-21", "6-7"]`` or ``[[20, 21], [6, 7]]`` -> ``((20, 21), (6, 7))``."""
    out = []
    for item in items:
        try:
            if isinstance(item, str):
                u, v = (int(x) for x in item.replace("<->", "-").split("-"))
            else:
                u, v = (int(x) for x in item)
        except (TypeError, ValueError):
            raise ConfigError(f"expected a passage such as '20-21', got {item!r}",
                              key=key) from None
        if u == v or u < 0 or v < 0:
            raise ConfigError(f"a passage joins two different states, got {item!r}", key=key)
        out.append((u, v))
    return tuple(out)


def close_passages(T: np.ndarray, passages: Sequence[tuple[int, int]]) -> np.ndarray:
    """A copy of ``T`` (S, A, S) with every ``u <-> v`` transition removed and its rows
    renormalised over the other outcomes, or made self-loops when none is left (module
    docstring); rows stay distributions."""
    T = np.array(T, dtype=np.float64)
    for u, v in passages:
        for x, y in ((u, v), (v, u)):
            T[x, :, y] = 0.0
            rest = T[x].sum(axis=1)
            left = rest > 0.0
            T[x, left] /= rest[left, None]
            T[x, ~left, x] = 1.0
    return T


@dataclass(frozen=True)
class Change:
    """A change of the task at decision ``at`` (0-based: decision ``at`` is the first in
    the changed world): ``kind`` ``goal`` (the goal becomes ``goal``) or ``passages``
    (``passages`` close)."""

    at: int
    kind: str
    goal: tuple[int, ...] = ()
    passages: tuple[tuple[int, int], ...] = ()

    def __post_init__(self) -> None:
        if self.kind not in CHANGE_KINDS:
            raise ConfigError(f"unknown change {self.kind!r}", key="change",
                              fix=f"choose one of none, {', '.join(CHANGE_KINDS)}")
        if not (isinstance(self.at, int) and self.at >= 1):
            raise ConfigError(f"expected a decision >= 1, got {self.at!r}", key="change_at")
        if self.kind == "goal" and not self.goal:
            raise ConfigError("a goal change needs the new goal state(s)", key="new_goal")
        if self.kind == "passages" and not self.passages:
            raise ConfigError("a passage closing needs the passages", key="passages",
                              fix="e.g. passages = ['20-21', '6-7']")

    def describe(self) -> str:
        if self.kind == "goal":
            return f"goal -> {'+'.join(map(str, self.goal))} at decision {self.at}"
        closed = ", ".join(f"{u}<->{v}" for u, v in self.passages)
        return f"passages {closed} closed at decision {self.at}"


@dataclass(frozen=True)
class OnlineTask:
    """Goal and start states and the changes (sorted by decision) of an online task."""

    goal: tuple[int, ...]
    start_states: tuple[int, ...]
    changes: tuple[Change, ...] = ()

    def __post_init__(self) -> None:
        if not self.goal:
            raise ConfigError("no goal state", key="goal")
        if not self.start_states:
            raise ConfigError("no start state", key="start_states")
        ats = [c.at for c in self.changes]
        if len(set(ats)) != len(ats):
            raise ConfigError("two changes at the same decision", key="change_at")
        object.__setattr__(self, "changes", tuple(sorted(self.changes, key=lambda c: c.at)))

    def compile(self, T: np.ndarray, *, source: str | None = None) -> OnlineMdp:
        """The :class:`OnlineMdp` of this task on ``T`` (S, A, S); state ids outside
        ``0..S-1`` are a :class:`ConfigError` naming ``source`` and the field."""
        S = int(T.shape[0])

        def check(states: Sequence[int], key: str) -> None:
            bad = [s for s in states if not 0 <= int(s) < S]
            if bad:
                raise ConfigError(f"states {bad} not in 0..{S - 1}", path=source, key=key)

        check(self.goal, "goal")
        check(self.start_states, "start_states")
        cdfs, rewards, starts = [], [], [0]
        T_now = np.asarray(T, dtype=np.float64)
        goal = self.goal

        def phase() -> None:
            r = np.zeros(S)
            r[list(goal)] = 1.0
            cdfs.append(np.cumsum(T_now, axis=2))
            rewards.append(r)

        phase()
        for c in self.changes:
            if c.kind == "goal":
                check(c.goal, "new_goal")
                goal = c.goal
            else:
                check([x for p in c.passages for x in p], "passages")
                T_now = close_passages(T_now, c.passages)
            phase()
            starts.append(c.at)
        start = np.zeros(S)
        start[list(self.start_states)] = 1.0 / len(self.start_states)
        return OnlineMdp(np.ascontiguousarray(np.stack(cdfs)), np.stack(rewards),
                         np.asarray(starts, dtype=np.int64), np.cumsum(start))

    def as_dict(self) -> dict[str, Any]:
        return {"goal": list(self.goal), "start_states": list(self.start_states),
                "changes": [{"at": c.at, "kind": c.kind, "goal": list(c.goal),
                             "passages": [list(p) for p in c.passages]}
                            for c in self.changes]}
