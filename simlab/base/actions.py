"""Action sets of the physics robot: how many primitives, and how their directions are numbered.

simlab's own robot has 16 primitives, ``index = speed * 8 + direction`` with directions in
the thesis order UP, DOWN, LEFT, RIGHT, UP-LEFT, UP-RIGHT, DOWN-LEFT, DOWN-RIGHT
(:class:`~simlab.base.directions.Direction`, UP = +y of the map). A real robot's data often
differs on both counts: the ISIR TurtleBot logs have **8 actions** (one speed) numbered
**counter-clockwise from East** (0 E, 1 NE, 2 N, 3 NW, 4 W, 5 SW, 6 S, 7 SE). Reading such
data with simlab's order sends every arrow and every replayed move the wrong way without a
word, so an :class:`ActionSet` travels with every count table, MDP and Q-table
(``action_set`` in their metadata) and every consumer asks it what action ``a`` means.

An action set is

* ``n_actions``: 8 (one speed) or 16 (slow 0-7, fast 8-15);
* ``directions``: ``directions[i]`` is the simlab :class:`Direction` of the user's
  direction number ``i`` (a permutation of 0..7). Named conventions: ``simlab`` (identity)
  and ``ccw-east``; any other permutation is ``custom``;
* ``speed``: for 8-action sets, which primitive speed the robot's single speed is
  (``slow`` by default; the speed itself, in m/s, is a primitive setting).

Metadata without an ``action_set`` (files written before it existed) means
:data:`SIMLAB16` when the arrays have 16 actions; 8-action arrays without one are refused by
:func:`action_set_from_metadata` unless the caller names a convention.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.base.directions import Direction
from simlab.base.errors import ConfigError
from simlab.base.options import CommandConfig, option

#: Heading (rad, counter-clockwise from +x of the map) of each simlab :class:`Direction`.
HEADINGS: NDArray[np.float64] = np.array(
    [math.pi / 2, -math.pi / 2, math.pi, 0.0, 3 * math.pi / 4, math.pi / 4,
     -3 * math.pi / 4, -math.pi / 4]
)
HEADINGS.flags.writeable = False

#: Named direction conventions: user direction number -> simlab Direction.
CONVENTIONS: dict[str, tuple[int, ...]] = {
    "simlab": tuple(int(d) for d in Direction),
    "ccw-east": tuple(int(d) for d in (
        Direction.RIGHT, Direction.UP_RIGHT, Direction.UP, Direction.UP_LEFT,
        Direction.LEFT, Direction.DOWN_LEFT, Direction.DOWN, Direction.DOWN_RIGHT,
    )),
}

SPEED_NAMES = ("slow", "fast")


def _permutation(values: Sequence[Any], key: str) -> tuple[int, ...]:
    try:
        perm = tuple(int(v) for v in values)
    except (TypeError, ValueError):
        raise ConfigError(f"expected 8 whole numbers, got {values!r}", key=key,
                          fix="give a permutation of 0..7, e.g. 3,5,0,4,2,6,1,7") from None
    if sorted(perm) != list(range(8)):
        raise ConfigError(f"expected a permutation of 0..7, got {list(perm)}", key=key,
                          fix="each simlab direction 0..7 must appear exactly once")
    return perm


@dataclass(frozen=True)
class ActionSet:
    """What each action index of a robot's data means (see the module docstring)."""

    n_actions: int = 16
    directions: tuple[int, ...] = CONVENTIONS["simlab"]
    speed: str = "slow"

    def __post_init__(self) -> None:
        if self.n_actions not in (8, 16):
            raise ConfigError(f"must be 8 or 16, got {self.n_actions!r}",
                              key="action_set.n_actions")
        object.__setattr__(self, "directions",
                           _permutation(self.directions, "action_set.directions"))
        if self.speed not in SPEED_NAMES:
            raise ConfigError(f"must be 'slow' or 'fast', got {self.speed!r}",
                              key="action_set.speed")

    @property
    def convention(self) -> str:
        """``simlab``, ``ccw-east`` or ``custom``."""
        for name, perm in CONVENTIONS.items():
            if perm == self.directions:
                return name
        return "custom"

    def _check(self, action: int) -> int:
        a = int(action)
        if not 0 <= a < self.n_actions:
            raise ValueError(f"action must be in 0..{self.n_actions - 1}, got {action}")
        return a

    def direction(self, action: int) -> Direction:
        """simlab :class:`Direction` of ``action``."""
        return Direction(self.directions[self._check(action) % 8])

    def speed_index(self, action: int) -> int:
        """0 (slow) or 1 (fast) for ``action``."""
        a = self._check(action)
        return a // 8 if self.n_actions == 16 else SPEED_NAMES.index(self.speed)

    def heading(self, action: int) -> float:
        """Map-frame heading (rad) of ``action``."""
        return float(HEADINGS[self.direction(action)])

    def headings(self) -> NDArray[np.float64]:
        """Heading (rad) of every action, ``(n_actions,)``."""
        return np.array([self.heading(a) for a in range(self.n_actions)])

    def to_primitive(self, action: int) -> int:
        """simlab 16-primitive index (``speed * 8 + Direction``) that executes ``action``."""
        return self.speed_index(action) * 8 + int(self.direction(action))

    def primitives(self) -> NDArray[np.int64]:
        """:meth:`to_primitive` of every action, ``(n_actions,)``."""
        return np.array([self.to_primitive(a) for a in range(self.n_actions)], dtype=np.int64)

    def from_primitive(self, primitive: int) -> int | None:
        """The action of this set that executes simlab primitive ``primitive`` (None if none)."""
        hits = np.flatnonzero(self.primitives() == int(primitive))
        return int(hits[0]) if hits.size else None

    def permutation_to(self, other: ActionSet) -> NDArray[np.int64]:
        """``perm`` with ``other``'s action ``perm[a]`` doing what this set's ``a`` does.

        So a Q-table moves between the two numberings with ``Q_other[:, perm] = Q``. Raises
        ConfigError when the two sets do not hold the same primitives.
        """
        perm = [other.from_primitive(p) for p in self.primitives()]
        if other.n_actions != self.n_actions or any(p is None for p in perm):
            raise ConfigError(f"cannot map {self.describe()} onto {other.describe()}",
                              key="action_set")
        return np.array(perm, dtype=np.int64)

    def describe(self) -> str:
        """Short text, e.g. ``8 actions (ccw-east, slow)``."""
        extra = f", {self.speed}" if self.n_actions == 8 else ""
        return f"{self.n_actions} actions ({self.convention}{extra})"

    def to_json(self) -> dict[str, Any]:
        """The ``action_set`` metadata record."""
        return {"n_actions": self.n_actions, "convention": self.convention,
                "directions": list(self.directions), "speed": self.speed}

    @classmethod
    def from_json(cls, record: Mapping[str, Any], *, where: str = "action_set") -> ActionSet:
        """Inverse of :meth:`to_json`; ``directions`` wins over the convention name."""
        if not isinstance(record, Mapping):
            raise ConfigError(f"expected a table, got {record!r}", key=where)
        try:
            n = int(record.get("n_actions", 16))
        except (TypeError, ValueError):
            raise ConfigError(f"n_actions: expected 8 or 16, got {record.get('n_actions')!r}",
                              key=where) from None
        if "directions" in record:
            directions = _permutation(record["directions"], f"{where}.directions")
        else:
            directions = convention_permutation(record.get("convention", "simlab"), key=where)
        return cls(n_actions=n, directions=directions, speed=str(record.get("speed", "slow")))


def convention_permutation(spec: str | Sequence[int], *, key: str = "convention") -> tuple[int, ...]:
    """Directions of a convention given by name (``simlab``, ``ccw-east``) or as 8 numbers.

    ``spec`` may be a string of 8 comma-separated numbers: ``"3,5,0,4,2,6,1,7"`` means the
    user's direction 0 is simlab's RIGHT, 1 is UP-RIGHT, and so on.
    """
    if isinstance(spec, str):
        name = spec.strip().lower()
        if name in CONVENTIONS:
            return CONVENTIONS[name]
        if "," in name:
            return _permutation(name.split(","), key)
        raise ConfigError(f"unknown direction convention {spec!r}", key=key,
                          fix="use 'simlab', 'ccw-east' or 8 comma-separated numbers")
    return _permutation(spec, key)


def parse_action_set(n_actions: int, convention: str | Sequence[int] = "simlab",
                     speed: str = "slow") -> ActionSet:
    """An :class:`ActionSet` from the command-line spellings."""
    return ActionSet(n_actions=int(n_actions), directions=convention_permutation(convention),
                     speed=speed)


#: simlab's own robot: 16 primitives in the thesis order.
SIMLAB16 = ActionSet()


def action_set_from_metadata(meta: Mapping[str, Any] | None, n_actions: int, *,
                             where: str) -> ActionSet:
    """The action set recorded in ``meta['action_set']``, checked against ``n_actions``.

    Old files without the record are simlab's 16 primitives; an 8-action file without one
    is refused (its direction numbering is unknown), naming ``where``.
    """
    record = None if meta is None else meta.get("action_set")
    if record is None:
        if n_actions == 16:
            return SIMLAB16
        raise ConfigError(f"{n_actions} actions and no action_set record", path=where,
                          fix="re-import it with --n-actions and --convention")
    aset = ActionSet.from_json(record, where=f"{where}: action_set")
    if aset.n_actions != n_actions:
        raise ConfigError(f"action_set says {aset.n_actions} actions, the arrays have "
                          f"{n_actions}", path=where)
    return aset


@dataclass(frozen=True, kw_only=True)
class ActionSetOptions(CommandConfig):
    """The ``--n-actions/--convention/--speed`` field group of the commands that read data
    whose action numbering is given by the user (``estimate`` of a count table; inherit it
    in a command's config and call :meth:`make_action_set`).

    ``n_actions`` and ``convention`` default to None = "not given" so that a command can
    tell a choice from the default (``estimate`` refuses the group for a dataset, which
    records its own, even ``--convention simlab``).
    """

    n_actions: int | None = option(
        None, "actions of the data: 8 (one speed) or 16 (default 16; a dataset records its "
        "own)", choices=(8, 16))
    convention: str | None = option(
        None, "direction numbering: simlab (UP, DOWN, LEFT, RIGHT, UL, UR, DL, DR; the "
        "default), ccw-east (0 E, 1 NE, ... 7 SE) or 8 numbers PERM, the simlab direction of "
        "each of yours")
    speed: str = option(
        "slow", "which primitive speed an 8-action robot's single speed is (ignored for 16 "
        "actions)", choices=("slow", "fast"))

    @property
    def action_set_given(self) -> bool:
        """Whether any field of the group differs from its default."""
        return self.n_actions is not None or self.convention is not None or self.speed != "slow"

    def make_action_set(self, default_n_actions: int = 16) -> ActionSet:
        """The :class:`ActionSet` of the fields (``n_actions`` None: ``default_n_actions``);
        a 16-action set has both speeds, so ``speed`` only describes an 8-action one."""
        n = default_n_actions if self.n_actions is None else self.n_actions
        return parse_action_set(n, self.convention or "simlab", self.speed if n == 8 else "slow")
