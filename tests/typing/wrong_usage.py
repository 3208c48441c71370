"""Mistakes ``mypy --strict`` must catch through simlab's own annotations (tests/typing):
if simlab's types were invisible (no ``py.typed``) every call here would be ``Any``."""

from __future__ import annotations

from pathlib import Path

from simlab.agents import greedy
from simlab.envs.table_arena import TableArenaEnv


def wrong(q: Path) -> str:
    TableArenaEnv(goal_conditioned="yes")  # expected "bool"
    return greedy(q)  # an int64 array, not a str
