"""Grids and lab layouts, and the movement rule (thesis 2.1.1).

A :class:`Layout` is a rectangular grid of cells (origin top-left, ``cell = row *
width + col``) with walls lying *between* cells and a room label per cell:

* ``walls_h`` — shape ``(height + 1, width)``, bool: ``walls_h[r, c]`` is the wall on
  the horizontal grid line above row ``r`` (between cells ``(r - 1, c)`` and
  ``(r, c)``); rows ``0`` and ``height`` are the outer border.
* ``walls_v`` — shape ``(height, width + 1)``, bool: ``walls_v[r, c]`` is the wall on
  the vertical grid line left of column ``c`` (between ``(r, c - 1)`` and
  ``(r, c)``); columns ``0`` and ``width`` are the outer border.
* ``labels`` — shape ``(height, width)``, int: the room label of each cell (an index
  into ``room_names``); ``goal_labels`` lists the labels that can be goals.

Three builders: :func:`gridworld` (no inner walls, labels in blocks; thesis
Fig. 2.6), :func:`lab_layout` (central corridor, rooms above and below it, doors;
random but seedable; thesis Fig. 2.4) and :func:`paper_layout` (24 x 24, nine
8 x 8 rooms with doors; the paper's setting).

Movement (:func:`move`, a numba kernel): a move of speed ``k`` is ``k`` unit steps
in one direction and stops at the last free cell; a unit step is refused when it
crosses a wall or enters the ``occupied`` cell (the other agent). A diagonal unit
step is refused if *either* L-shaped path through the two neighbouring cells
crosses a wall (so a diagonal never cuts the corner of a wall).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit

from simlab.base.errors import ConfigError
from simlab.visitlab.actions import DIR_DELTA

#: Layouts with more cells than this get no precomputed line-of-sight table
#: (it would need n_cells**2 bytes); sight lines are then traced per query.
LOS_TABLE_MAX_CELLS = 4096


@dataclass(frozen=True, eq=False)
class Layout:
    """A grid with walls between cells and labelled rooms (see the module docstring).

    Arrays are copied and made read-only at construction. ``start_cell`` is an
    optional suggested start (the navigation env uses it in its fixed-start mode).
    """

    name: str
    walls_h: np.ndarray
    walls_v: np.ndarray
    labels: np.ndarray
    room_names: tuple[str, ...]
    goal_labels: tuple[int, ...]
    start_cell: int = 0
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        walls_h = np.array(self.walls_h, dtype=bool)
        walls_v = np.array(self.walls_v, dtype=bool)
        labels = np.array(self.labels, dtype=np.int64)
        if labels.ndim != 2 or labels.shape[0] < 1 or labels.shape[1] < 1:
            raise ConfigError(f"expected a 2-D array, got shape {labels.shape}", key="labels")
        h, w = labels.shape
        if walls_h.shape != (h + 1, w):
            raise ConfigError(
                f"expected shape {(h + 1, w)} for a {h} x {w} grid, got {walls_h.shape}",
                key="walls_h",
            )
        if walls_v.shape != (h, w + 1):
            raise ConfigError(
                f"expected shape {(h, w + 1)} for a {h} x {w} grid, got {walls_v.shape}",
                key="walls_v",
            )
        if not (walls_h[0].all() and walls_h[h].all() and walls_v[:, 0].all() and walls_v[:, w].all()):
            raise ConfigError("the outer border must be walled", key="walls")
        n_labels = len(self.room_names)
        if labels.min() < 0 or labels.max() >= n_labels:
            raise ConfigError(
                f"labels must lie in 0..{n_labels - 1} (one per room name), "
                f"got {labels.min()}..{labels.max()}",
                key="labels",
            )
        goals = tuple(int(g) for g in self.goal_labels)
        if not goals or any(not 0 <= g < n_labels for g in goals):
            raise ConfigError(f"expected a non-empty list of labels in 0..{n_labels - 1}",
                              key="goal_labels")
        if not 0 <= int(self.start_cell) < h * w:
            raise ConfigError(f"must lie in 0..{h * w - 1}", key="start_cell")
        for arr in (walls_h, walls_v, labels):
            arr.flags.writeable = False
        object.__setattr__(self, "walls_h", walls_h)
        object.__setattr__(self, "walls_v", walls_v)
        object.__setattr__(self, "labels", labels)
        object.__setattr__(self, "room_names", tuple(str(n) for n in self.room_names))
        object.__setattr__(self, "goal_labels", goals)
        object.__setattr__(self, "start_cell", int(self.start_cell))

    @property
    def height(self) -> int:
        return int(self.labels.shape[0])

    @property
    def width(self) -> int:
        return int(self.labels.shape[1])

    @property
    def n_cells(self) -> int:
        return self.height * self.width

    @property
    def n_labels(self) -> int:
        return len(self.room_names)

    @property
    def cell_labels(self) -> np.ndarray:
        """Room label of every cell, flat, shape ``(n_cells,)``."""
        return self.labels.reshape(-1)

    @property
    def has_inner_walls(self) -> bool:
        return bool(self.walls_h[1:-1].any() or self.walls_v[:, 1:-1].any())

    def cell(self, row: int, col: int) -> int:
        """Cell index of ``(row, col)``."""
        if not (0 <= row < self.height and 0 <= col < self.width):
            raise ConfigError(f"({row}, {col}) is outside the {self.height} x {self.width} grid",
                              key="cell")
        return row * self.width + col

    def rowcol(self, cell: int) -> tuple[int, int]:
        """``(row, col)`` of a cell index."""
        return divmod(int(cell), self.width)

    def room_cells(self, label: int) -> np.ndarray:
        """Cell indices of room ``label``, shape ``(k,)``."""
        return np.flatnonzero(self.cell_labels == label)

    def los_table(self) -> np.ndarray:
        """Line-of-sight table for the kernels (see :mod:`simlab.visitlab.perception`).

        ``(n_cells, n_cells)`` uint8 (1 = visible) for walled layouts up to
        :data:`LOS_TABLE_MAX_CELLS` cells; ``(1, 1)`` for a layout without inner walls
        (everything visible); ``(0, 0)`` otherwise (traced per query). Cached.
        """
        if "los" not in self._cache:
            from simlab.visitlab.perception import build_los_table

            if not self.has_inner_walls:
                table = np.ones((1, 1), dtype=np.uint8)
            elif self.n_cells <= LOS_TABLE_MAX_CELLS:
                table = build_los_table(self.walls_h, self.walls_v)
            else:
                table = np.zeros((0, 0), dtype=np.uint8)
            table.flags.writeable = False
            self._cache["los"] = table
        return self._cache["los"]

    def transition_table(self) -> np.ndarray:
        """Deterministic successor of every (cell, movement action), shape ``(n_cells, 25)``.

        Read-only int64; no other agent on the grid. Cached.
        """
        if "next" not in self._cache:
            table = _transition_table(self.walls_h, self.walls_v)
            table.flags.writeable = False
            self._cache["next"] = table
        return self._cache["next"]

    def next_cell(self, cell: int, action: int) -> int:
        """Cell reached from ``cell`` by movement action ``action`` (0-24), no other agent."""
        return int(self.transition_table()[cell, action])


# --------------------------------------------------------------------------- kernels


@njit(cache=True)
def unit_step(walls_h: np.ndarray, walls_v: np.ndarray, cell: int, direction: int) -> int:
    """One-cell step from ``cell`` in ``direction`` (0-7); ``-1`` if a wall is in the way.

    Diagonals need both L-shaped paths free of walls. Ignores other agents.
    """
    width = walls_h.shape[1]
    r = cell // width
    c = cell % width
    dr = DIR_DELTA[direction, 0]
    dc = DIR_DELTA[direction, 1]
    if dc == 0:  # vertical: wall line above row r (dr=-1) or above row r+1 (dr=+1)
        if walls_h[r + (1 if dr > 0 else 0), c]:
            return -1
    elif dr == 0:  # horizontal
        if walls_v[r, c + (1 if dc > 0 else 0)]:
            return -1
    else:
        hline = r + (1 if dr > 0 else 0)  # horizontal line crossed by the vertical leg
        vline = c + (1 if dc > 0 else 0)  # vertical line crossed by the horizontal leg
        # vertical first: (r, c) -> (r+dr, c) -> (r+dr, c+dc)
        if walls_h[hline, c] or walls_v[r + dr, vline]:
            return -1
        # horizontal first: (r, c) -> (r, c+dc) -> (r+dr, c+dc)
        if walls_v[r, vline] or walls_h[hline, c + dc]:
            return -1
    return (r + dr) * width + (c + dc)


@njit(cache=True)
def move(
    walls_h: np.ndarray, walls_v: np.ndarray, cell: int, direction: int, speed: int, occupied: int
) -> int:
    """Cell reached by ``speed`` unit steps in ``direction``; stops at the last free cell.

    A step is refused by a wall or by the ``occupied`` cell (``-1``: nobody).
    """
    for _ in range(speed):
        nxt = unit_step(walls_h, walls_v, cell, direction)
        if nxt < 0 or nxt == occupied:
            break
        cell = nxt
    return cell


@njit(cache=True)
def move_action_cell(
    walls_h: np.ndarray, walls_v: np.ndarray, cell: int, action: int, occupied: int
) -> int:
    """Cell reached by movement action ``action`` (0-23 moves, 24 and above: stay)."""
    if action >= 24:
        return cell
    if action < 12:
        direction = action % 4
        speed = action // 4 + 1
    else:
        direction = 4 + (action - 12) % 4
        speed = (action - 12) // 4 + 1
    return move(walls_h, walls_v, cell, direction, speed, occupied)


@njit(cache=True)
def _transition_table(walls_h: np.ndarray, walls_v: np.ndarray) -> np.ndarray:
    n_cells = walls_v.shape[0] * walls_h.shape[1]
    out = np.empty((n_cells, 25), dtype=np.int64)
    for cell in range(n_cells):
        for a in range(25):
            out[cell, a] = move_action_cell(walls_h, walls_v, cell, a, -1)
    return out


# --------------------------------------------------------------------------- builders


def _border(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    walls_h = np.zeros((height + 1, width), dtype=bool)
    walls_v = np.zeros((height, width + 1), dtype=bool)
    walls_h[0, :] = walls_h[height, :] = True
    walls_v[:, 0] = walls_v[:, width] = True
    return walls_h, walls_v


def _check_int(value: int, key: str, low: int, high: int | None = None) -> int:
    if not isinstance(value, int | np.integer) or isinstance(value, bool):
        raise ConfigError(f"expected an integer, got {value!r}", key=key)
    if value < low or (high is not None and value > high):
        bound = f">= {low}" if high is None else f"in {low}..{high}"
        raise ConfigError(f"expected an integer {bound}, got {value}", key=key)
    return int(value)


def _block_labels(height: int, width: int, blocks: tuple[int, int]) -> np.ndarray:
    br, bc = blocks
    rows = (np.arange(height) * br) // height
    cols = (np.arange(width) * bc) // width
    return rows[:, None] * bc + cols[None, :]


def gridworld(height: int = 24, width: int = 24, blocks: tuple[int, int] = (3, 3)) -> Layout:
    """Gridworld without inner walls (thesis Fig. 2.6), labelled in ``blocks`` areas.

    Labels split the grid into ``blocks[0] x blocks[1]`` near-equal rectangles
    numbered row-major from the top-left (default: nine 8 x 8 areas of a 24 x 24
    grid, the paper's gridworld); every label can be a goal.
    """
    height = _check_int(height, "height", 2)
    width = _check_int(width, "width", 2)
    br = _check_int(blocks[0], "blocks[0]", 1, height)
    bc = _check_int(blocks[1], "blocks[1]", 1, width)
    walls_h, walls_v = _border(height, width)
    labels = _block_labels(height, width, (br, bc))
    names = tuple(f"area {k}" for k in range(br * bc))
    return Layout(f"gridworld-{height}x{width}", walls_h, walls_v, labels, names,
                  tuple(range(br * bc)))


def paper_layout(door_width: int = 2) -> Layout:
    """The paper's lab: 24 x 24 cells, nine 8 x 8 rooms (labels 0-8, row-major).

    Every pair of neighbouring rooms shares a centred door ``door_width`` cells
    wide (12 doors), so every room is reachable from every other.
    """
    door_width = _check_int(door_width, "door_width", 1, 8)
    size, room = 24, 8
    walls_h, walls_v = _border(size, size)
    lo = (room - door_width) // 2
    for k in (1, 2):
        line = k * room
        walls_h[line, :] = True
        walls_v[:, line] = True
        for block in range(3):
            start = block * room + lo
            walls_h[line, start:start + door_width] = False
            walls_v[start:start + door_width, line] = False
    labels = _block_labels(size, size, (3, 3))
    return Layout("paper-24x24", walls_h, walls_v, labels,
                  tuple(f"room {k}" for k in range(9)), tuple(range(9)))


def _split(rng: np.random.Generator, total: int, parts: int, minimum: int) -> list[int]:
    """Random composition of ``total`` into ``parts`` integers, each >= ``minimum``."""
    sizes = [minimum] * parts
    for _ in range(total - minimum * parts):
        sizes[int(rng.integers(0, parts))] += 1
    return sizes


def lab_layout(
    rng: np.random.Generator,
    height: int = 20,
    width: int = 20,
    rooms_per_side: tuple[int, int] = (2, 4),
    corridor_height: tuple[int, int] = (2, 4),
    door_width: int = 2,
    side_door_prob: float = 0.3,
    min_room_size: int = 3,
) -> Layout:
    """A random lab (thesis Fig. 2.4): a central corridor with rooms above and below.

    The corridor spans the full width (label 0, not a goal). Above and below it,
    ``rooms_per_side`` (inclusive range, drawn per side) rooms of random widths
    (each >= ``min_room_size``) are labelled 1, 2, ... left to right, top side first.
    Each room has one door ``door_width`` cells wide onto the corridor at a random
    place; each pair of neighbouring rooms on one side gets a door between them with
    probability ``side_door_prob``. Everything random comes from ``rng``, so a seed
    fixes the layout.
    """
    height = _check_int(height, "height", 2 * min_room_size + 1)
    width = _check_int(width, "width", min_room_size)
    lo_rooms = _check_int(rooms_per_side[0], "rooms_per_side[0]", 1)
    hi_rooms = _check_int(rooms_per_side[1], "rooms_per_side[1]", lo_rooms)
    lo_corr = _check_int(corridor_height[0], "corridor_height[0]", 1)
    hi_corr = _check_int(corridor_height[1], "corridor_height[1]", lo_corr)
    door_width = _check_int(door_width, "door_width", 1)
    min_room_size = _check_int(min_room_size, "min_room_size", 1)
    if not 0.0 <= float(side_door_prob) <= 1.0:
        raise ConfigError(f"expected a probability in [0, 1], got {side_door_prob}",
                          key="side_door_prob")
    if hi_rooms * min_room_size > width:
        raise ConfigError(
            f"{hi_rooms} rooms of at least {min_room_size} cells do not fit in width {width}",
            key="rooms_per_side", fix="lower the room count or min_room_size, or widen the lab")
    if hi_corr + 2 * min_room_size > height:
        raise ConfigError(
            f"a corridor of {hi_corr} rows and two rows of rooms of at least {min_room_size} "
            f"rows do not fit in height {height}", key="corridor_height")

    corridor = int(rng.integers(lo_corr, hi_corr + 1))
    top_h = _split(rng, height - corridor, 2, min_room_size)[0]
    walls_h, walls_v = _border(height, width)
    labels = np.zeros((height, width), dtype=np.int64)
    names = ["corridor"]
    next_label = 1
    for side, (r0, r1, door_line) in enumerate(
        ((0, top_h, top_h), (top_h + corridor, height, top_h + corridor))
    ):
        walls_h[door_line, :] = True
        n_rooms = int(rng.integers(lo_rooms, hi_rooms + 1))
        widths = _split(rng, width, n_rooms, min_room_size)
        c0 = 0
        for k, w in enumerate(widths):
            labels[r0:r1, c0:c0 + w] = next_label
            names.append(f"{'top' if side == 0 else 'bottom'} room {k + 1}")
            next_label += 1
            dw = min(door_width, w)
            start = c0 + int(rng.integers(0, w - dw + 1))
            walls_h[door_line, start:start + dw] = False
            if k > 0:  # wall with the previous room, maybe a door in it
                walls_v[r0:r1, c0] = True
                if rng.random() < side_door_prob:
                    dh = min(door_width, r1 - r0)
                    d0 = r0 + int(rng.integers(0, r1 - r0 - dh + 1))
                    walls_v[d0:d0 + dh, c0] = False
            c0 += w
    start_row = top_h + corridor // 2
    return Layout(f"lab-{height}x{width}", walls_h, walls_v, labels, tuple(names),
                  tuple(range(1, next_label)), start_cell=start_row * width)


def make_layout(spec: str | Layout, seed: int | None = None) -> Layout:
    """Layout by name: ``"gridworld"`` (24 x 24, 3 x 3 areas), ``"gridworld-HxW"``,
    ``"paper"`` or ``"lab"`` (random, from ``seed``; default seed 0). A :class:`Layout`
    is returned unchanged."""
    if isinstance(spec, Layout):
        return spec
    if not isinstance(spec, str):
        raise ConfigError(f"expected a layout name or Layout, got {type(spec).__name__}",
                          key="layout")
    name = spec.strip().lower()
    if name == "gridworld":
        return gridworld()
    if name.startswith("gridworld-"):
        try:
            h, w = (int(x) for x in name[len("gridworld-"):].split("x"))
        except ValueError:
            raise ConfigError(f"unknown layout {spec!r}", key="layout",
                              fix="use gridworld-HxW, e.g. gridworld-20x20") from None
        from simlab.base.guards import array_bytes, check_memory

        # cell labels, two wall rasters and per-cell tables: ~32 bytes a cell, before any
        # Q-table (cells x goals x 25 actions, checked by the trainer)
        check_memory(array_bytes((h, w), 32), what=f"a {h} x {w} grid", key="layout",
                     fix="use a smaller gridworld-HxW")
        return gridworld(h, w)
    if name == "paper":
        return paper_layout()
    if name == "lab":
        return lab_layout(np.random.default_rng(0 if seed is None else seed))
    raise ConfigError(f"unknown layout {spec!r}", key="layout",
                      fix="use gridworld, gridworld-HxW, paper or lab")
