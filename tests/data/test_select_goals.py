"""Choosing the goals of a run: arena goals by name, or state-id goals (``s18+19``)."""

from __future__ import annotations

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.data.goals import GoalMasks, is_state_goal, select_goals, state_goal_name

ARENA = GoalMasks(np.array(["NW", "C"], dtype=np.str_),
                  np.array([[1, 1, 0, 0, 0], [0, 0, 1, 0, 0]], dtype=bool))


def test_all_goals_by_default():
    for goals in (None, "all"):
        assert select_goals(ARENA, goals, 5) is ARENA


def test_arena_goals_by_name_keep_their_states_in_the_given_order():
    names, masks = select_goals(ARENA, "C,NW", 5)
    assert list(names) == ["C", "NW"]
    assert masks.tolist() == [ARENA.masks[1].tolist(), ARENA.masks[0].tolist()]


def test_state_id_goals_are_their_states():
    names, masks = select_goals(ARENA, ["s3+4", "NW"], 5)
    assert list(names) == ["s3+4", "NW"]
    assert np.flatnonzero(masks[0]).tolist() == [3, 4]
    assert state_goal_name((3, 4)) == "s3+4" and is_state_goal("s3+4")
    assert not is_state_goal("NW") and not is_state_goal("s3+")


@pytest.mark.parametrize("goals, match", [
    ("nosuch", "unknown goal 'nosuch'.*NW, C"),
    ("s9", r"states \[9\] not in \[0, 5\)"),
    ("C,C", "listed twice"),
    ("C,", "expected goal names"),
])
def test_bad_goal_lists_name_the_problem(goals, match):
    with pytest.raises(ConfigError, match=match):
        select_goals(ARENA, goals, 5)
