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

A change may also replace the whole model (``after``: "from this decision the world is this
other model", e.g. the published files of the goal change and of the closed passages, whose
every row is the lab's after the change), and may offer *alternatives* chosen by use: several
``after`` models, or several passages closed one at a time, each with a counting state
(``use_states``); the alternative whose counting state saw the most decisions before the
change is the one that happens (the first listed on ties). This is how the published
simulator chooses the passage it closes (Dromnelle et al. 2022; their code counts the
decisions in state 19, towards 20-21, and in state 7, towards 6-7).

A start state that is a goal is refused: after a reward the run would restart in the goal
and be rewarded for standing still.

The compiled form :class:`OnlineMdp` holds one ``(S, A, S)`` cumulative ``T`` and one
``(S,)`` reward per phase; phase ``i`` runs from decision ``phase_start[i]`` on; phases
that start at the same decision are the alternatives of one change.
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
#: (``phase_start[0] == 0``), ``start_cdf`` (S,) cumulative start distribution, ``use_state``
#: (P,) int64 the counting state of an alternative phase (-1: not chosen by use).
OnlineMdp = namedtuple("OnlineMdp", ["cdf", "reward_next", "phase_start", "start_cdf",
                                     "use_state"])

CHANGE_KINDS = ("goal", "passages", "model")


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


@dataclass(frozen=True, eq=False)
class Change:
    """A change of the task at decision ``at`` (0-based: decision ``at`` is the first in
    the changed world): ``kind`` ``goal`` (the goal becomes ``goal``), ``passages``
    (``passages`` close) or ``model`` (the world becomes the ``after`` model).

    ``after`` (``(S, A, S)`` arrays): the model of the world from ``at`` on (a goal change
    or a passage closing then applies to it); several are alternatives of a ``model``
    change. ``use_states``: one counting state per alternative (several ``after`` models,
    or the ``passages`` closed one at a time); empty: a single outcome (every passage
    closes). ``names`` name the ``after`` models in descriptions (their files)."""

    at: int
    kind: str
    goal: tuple[int, ...] = ()
    passages: tuple[tuple[int, int], ...] = ()
    after: tuple[Any, ...] = ()
    use_states: tuple[int, ...] = ()
    names: tuple[str, ...] = ()

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
        if self.kind == "model" and not self.after:
            raise ConfigError("a model change needs the model of the world after it",
                              key="after", fix="give --after MODEL (an mdp.npz)")
        if len(self.after) > 1 and self.kind != "model":
            raise ConfigError(f"{len(self.after)} --after models for a {self.kind} change: "
                              "only a model change chooses among several", key="after",
                              fix="give one --after model, or --change model")
        n = self.alternatives()
        if self.use_states and len(self.use_states) != n:
            what = "--after models" if self.kind == "model" else "passages"
            raise ConfigError(f"{len(self.use_states)} counting states for {n} {what}",
                              key="use_states", fix=f"give one counting state per {what[:-1]}")
        if n > 1 and self.kind == "model" and not self.use_states:
            raise ConfigError(f"{n} --after models and no counting state to choose among "
                              "them", key="use_states",
                              fix="give --use-states S (one per model: the model whose "
                              "state saw the most decisions before the change is applied)")

    def alternatives(self) -> int:
        """How many outcomes the change offers (1: no choice)."""
        if self.kind == "model":
            return len(self.after)
        if self.kind == "passages" and self.use_states:
            return len(self.passages)
        return 1

    def describe(self) -> str:
        world = " or ".join(self.names or ("another model",))
        by_use = (f" (the more used: decisions in {'/'.join(map(str, self.use_states))})"
                  if self.use_states else "")
        if self.kind == "model":
            what = f"the world becomes {world}{by_use}"
        elif self.kind == "goal":
            what = f"goal -> {'+'.join(map(str, self.goal))}"
            what += f", the world becomes {world}" if self.after else ""
        else:
            joined = (" or " if self.use_states else ", ").join(
                f"{u}<->{v}" for u, v in self.passages)
            what = f"passages {joined} closed{by_use}" + (f" in {world}" if self.after else "")
        return f"{what} at decision {self.at}"


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
        if any(c.alternatives() > 1 for c in self.changes[:-1]):
            raise ConfigError("a change chosen by use must be the last one", key="use_states",
                              fix="the phases after it would depend on the choice")
        goals = [("goal", self.goal)] + [("new_goal", c.goal) for c in self.changes if c.goal]
        for key, goal in goals:
            both = sorted(set(goal) & set(self.start_states))
            if both:
                raise ConfigError(f"start state(s) {both} are also the {key.replace('_', ' ')}:"
                                  " after a reward the run would restart in the goal and be "
                                  "rewarded for standing still", key="start_states",
                                  fix="choose start states apart from every goal")

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
        cdfs, rewards, starts, uses = [], [], [0], [-1]
        T_now = np.asarray(T, dtype=np.float64)
        goal = self.goal

        def phase(T_phase: np.ndarray) -> None:
            r = np.zeros(S)
            r[list(goal)] = 1.0
            cdfs.append(np.cumsum(T_phase, axis=2))
            rewards.append(r)

        phase(T_now)
        for c in self.changes:
            check(c.use_states, "use_states")
            outcomes = [np.asarray(m, dtype=np.float64) for m in c.after] or [T_now]
            for m, name in zip(outcomes, c.names or ("--after",) * len(outcomes), strict=False):
                if m.shape != T_now.shape:
                    raise ConfigError(f"the model after the change is {m.shape[0]} states x "
                                      f"{m.shape[1]} actions, the run's {S} x {T_now.shape[1]}",
                                      path=None if name == "--after" else name, key="after",
                                      fix="give a model of the same lab (same states and "
                                      "actions)")
            if c.kind == "goal":
                check(c.goal, "new_goal")
                goal = c.goal
            elif c.kind == "passages":
                check([x for p in c.passages for x in p], "passages")
                base = outcomes[0]
                none = [f"{u}-{v}" for u, v in c.passages
                        if not (base[u, :, v].any() or base[v, :, u].any())]
                if none:
                    raise ConfigError(f"no passage {', '.join(none)}: the model never moves "
                                      "between these states, so closing it changes nothing",
                                      path=source, key="passages",
                                      fix="name neighbouring states U-V that the robot moved "
                                          "between")
                outcomes = ([close_passages(outcomes[0], [p]) for p in c.passages]
                            if c.use_states else [close_passages(outcomes[0], c.passages)])
            for k, T_phase in enumerate(outcomes):
                phase(T_phase)
                starts.append(c.at)
                uses.append(int(c.use_states[k]) if c.use_states else -1)
            T_now = outcomes[0]
        start = np.zeros(S)
        start[list(self.start_states)] = 1.0 / len(self.start_states)
        return OnlineMdp(np.ascontiguousarray(np.stack(cdfs)), np.stack(rewards),
                         np.asarray(starts, dtype=np.int64), np.cumsum(start),
                         np.asarray(uses, dtype=np.int64))

    def as_dict(self) -> dict[str, Any]:
        return {"goal": list(self.goal), "start_states": list(self.start_states),
                "changes": [{"at": c.at, "kind": c.kind, "goal": list(c.goal),
                             "passages": [list(p) for p in c.passages],
                             "after": list(c.names), "use_states": list(c.use_states)}
                            for c in self.changes]}
