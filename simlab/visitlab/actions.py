"""Actions and directions of the Visit-the-lab grid (thesis Tables 2.1-2.3).

One direction order is used everywhere — robot moves, body orientations, the
required direction and the quantised robot->human angle:

====  =====  ==============  ===============================
 idx  name   (drow, dcol)    sector (45 deg, counter-clockwise
                             from RIGHT, UP = +90 deg)
====  =====  ==============  ===============================
  0   UP     (-1,  0)        2
  1   DOWN   (+1,  0)        6
  2   LEFT   ( 0, -1)        4
  3   RIGHT  ( 0, +1)        0
  4   UL     (-1, -1)        3
  5   UR     (-1, +1)        1
  6   DL     (+1, -1)        5
  7   DR     (+1, +1)        7
====  =====  ==============  ===============================

Rows grow downwards (origin top-left, cell = row * width + col), so UP is
``drow = -1``. Sectors are only used to measure angular differences (fields of
view); everything a user sees is a direction index.

Actions (thesis Table 2.1, 2.2, 2.3): ``0-3`` UP, DOWN, LEFT, RIGHT at speed 1,
``+4`` speed 2, ``+8`` speed 3; ``12-15`` UL, UR, DL, DR at speed 1, ``+4``/``+8``
for speeds 2 and 3; ``24`` STAY; ``25`` LOOK_H; ``26`` HELLO; ``27`` COME;
``28`` POINTING; ``29`` GO_TO_HUMAN.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np


class Action(IntEnum):
    """Robot actions 0-29 (navigation 0-24, social 25-28, option 29)."""

    UP = 0
    DOWN = 1
    LEFT = 2
    RIGHT = 3
    UP2 = 4
    DOWN2 = 5
    LEFT2 = 6
    RIGHT2 = 7
    UP3 = 8
    DOWN3 = 9
    LEFT3 = 10
    RIGHT3 = 11
    UP_LEFT = 12
    UP_RIGHT = 13
    DOWN_LEFT = 14
    DOWN_RIGHT = 15
    UP_LEFT2 = 16
    UP_RIGHT2 = 17
    DOWN_LEFT2 = 18
    DOWN_RIGHT2 = 19
    UP_LEFT3 = 20
    UP_RIGHT3 = 21
    DOWN_LEFT3 = 22
    DOWN_RIGHT3 = 23
    STAY = 24
    LOOK_H = 25
    HELLO = 26
    COME = 27
    POINTING = 28
    GO_TO_HUMAN = 29


#: Number of movement actions (0-23 moves, 24 STAY): the navigation and
#: go-to-human action space.
N_MOVE_ACTIONS = 25
#: Social module actions 0-29 (moves, STAY, the four social actions, GO_TO_HUMAN).
N_SOCIAL_ACTIONS = 30
N_DIRECTIONS = 8

#: (drow, dcol) of each direction, shape (8, 2), int64.
DIR_DELTA = np.array(
    [[-1, 0], [1, 0], [0, -1], [0, 1], [-1, -1], [-1, 1], [1, -1], [1, 1]], dtype=np.int64
)
#: Angular sector (units of 45 deg, counter-clockwise from RIGHT) of each direction.
DIR_SECTOR = np.array([2, 6, 4, 0, 3, 1, 5, 7], dtype=np.int64)
#: Inverse of :data:`DIR_SECTOR`: direction index of each sector.
SECTOR_DIR = np.array([3, 5, 0, 4, 2, 6, 1, 7], dtype=np.int64)
#: Direction opposite to each direction (UP <-> DOWN, UL <-> DR, ...).
DIR_OPPOSITE = SECTOR_DIR[(DIR_SECTOR + 4) % 8]

#: Direction of each movement action 0-23 (shape (24,)).
ACTION_DIR = np.array([a % 4 if a < 12 else 4 + (a - 12) % 4 for a in range(24)], dtype=np.int64)
#: Speed (cells per step, 1-3) of each movement action 0-23 (shape (24,)).
ACTION_SPEED = np.array([a // 4 + 1 if a < 12 else (a - 12) // 4 + 1 for a in range(24)], dtype=np.int64)

DIRECTION_NAMES = ("UP", "DOWN", "LEFT", "RIGHT", "UL", "UR", "DL", "DR")
#: One-character arrows for text renders, by direction index.
DIRECTION_ARROWS = ("^", "v", "<", ">", "\\", "/", "/", "\\")


def move_action(direction: int, speed: int) -> int:
    """Action index of a move in ``direction`` (0-7) at ``speed`` (1-3 cells per step)."""
    if not 0 <= direction < 8 or not 1 <= speed <= 3:
        raise ValueError(f"direction must be 0-7 and speed 1-3, got {direction}, {speed}")
    base = direction if direction < 4 else 12 + direction - 4
    return int(base + 4 * (speed - 1))
