"""Which Markov states make up each goal area.

Rule (shared by the estimator's ``mdp.npz`` and the closed-loop replay): state ``s``
belongs to goal ``g`` when its Voronoi centre lies inside the goal circle (boundary
included, :meth:`GoalArea.contains`). A goal circle containing no centre at all (a
small goal between centres) gets the single state whose centre is nearest to the goal
centre (ties: the lower state index), so that every goal is reachable in the MDP.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray


class GoalMasks(NamedTuple):
    """Goal names ``(G,)`` (numpy unicode) and membership ``masks`` ``(G, S)`` bool."""

    names: NDArray[np.str_]
    masks: NDArray[np.bool_]


def _goal_fields(goal: Any) -> tuple[str, float, float, float]:
    if isinstance(goal, Mapping):
        return str(goal["name"]), float(goal["x"]), float(goal["y"]), float(goal["radius"])
    return str(goal.name), float(goal.x), float(goal.y), float(goal.radius)


def goals_from_manifest(goals: Iterable[Mapping[str, Any]]) -> tuple[Any, ...]:
    """Goal areas rebuilt from a manifest's ``arena.goals`` list of dicts."""
    from simlab.physics.arena import GoalArea

    return tuple(GoalArea(*_goal_fields(g)) for g in goals)


def goal_state_masks(arena: Any, centres: ArrayLike) -> GoalMasks:
    """Goal membership of every state.

    Args:
        arena: an :class:`~simlab.physics.arena.ArenaConfig` (anything with ``.goals``),
            or a sequence of goals (``GoalArea`` or dicts with name, x, y, radius; m).
        centres: Voronoi centres ``(S, 2)`` in metres, in state order.

    Returns:
        :class:`GoalMasks` ``(names (G,), masks (G, S))``; every row has at least one
        True (see the module docstring for the rule).
    """
    goals = tuple(getattr(arena, "goals", arena))
    c = np.asarray(centres, dtype=np.float64)
    if c.ndim != 2 or c.shape[1] != 2 or len(c) == 0:
        raise ValueError(f"centres: expected a non-empty (S, 2) array, got shape {c.shape}")
    names = np.array([_goal_fields(g)[0] for g in goals], dtype=np.str_)
    masks = np.zeros((len(goals), len(c)), dtype=bool)
    for i, goal in enumerate(goals):
        _, x, y, radius = _goal_fields(goal)
        if hasattr(goal, "contains"):
            inside = np.asarray(goal.contains(c), dtype=bool)
        else:
            inside = np.hypot(c[:, 0] - x, c[:, 1] - y) <= radius
        if not inside.any():
            inside[int(np.argmin(np.hypot(c[:, 0] - x, c[:, 1] - y)))] = True
        masks[i] = inside
    return GoalMasks(names=names, masks=masks)


#: A goal made of state ids, as ``simlab train --goal-states 18,19`` names it: ``s18+19``.
_STATE_GOAL = re.compile(r"^s(\d+(?:\+\d+)*)$")


def state_goal_name(states: Iterable[int]) -> str:
    """The name of the goal made of ``states`` (``(18, 19)`` -> ``"s18+19"``)."""
    return "s" + "+".join(str(int(s)) for s in states)


def is_state_goal(name: str) -> bool:
    """True for names of state-id goals (``s18``, ``s18+19``)."""
    return _STATE_GOAL.match(name) is not None


def select_goals(masks: GoalMasks, goals: str | Iterable[str] | None, n_states: int) -> GoalMasks:
    """The goals a run uses: all of ``masks`` (``goals`` None or ``"all"``) or the named ones.

    A name of the form ``s18`` or ``s18+19`` is the goal made of those states (the name
    ``simlab train --goal-states`` gives its Q-table); it takes precedence over an arena
    goal of the same name, so a replay rewards exactly what training rewarded. Any other
    name must be one of ``masks.names``.
    """
    from simlab.base.errors import ConfigError

    if goals is None or goals == "all":
        return masks
    names = [g.strip() for g in (goals.split(",") if isinstance(goals, str) else goals)]
    if not names or any(not g for g in names):
        raise ConfigError(f"expected goal names, got {goals!r}", key="goals",
                          fix="e.g. --goals NW,C or --goals s18 (a state-id goal)")
    if len(set(names)) != len(names):
        raise ConfigError(f"goal listed twice in {names}", key="goals")
    known = [str(n) for n in masks.names]
    rows = []
    for name in names:
        m = _STATE_GOAL.match(name)
        if m is not None:
            ids = [int(v) for v in m.group(1).split("+")]
            bad = [s for s in ids if s >= n_states]
            if bad:
                raise ConfigError(f"goal {name!r}: states {bad} not in [0, {n_states})",
                                  key="goals")
            row = np.zeros(n_states, dtype=bool)
            row[ids] = True
        elif name in known:
            row = np.asarray(masks.masks[known.index(name)], dtype=bool)
        else:
            raise ConfigError(f"unknown goal {name!r}", key="goals",
                              fix=f"the arena's goals are {', '.join(known) or 'none'}; "
                                  "or name states as s18 / s18+19")
        rows.append(row)
    return GoalMasks(np.array(names, dtype=np.str_), np.stack(rows))
