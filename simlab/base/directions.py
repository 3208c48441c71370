"""The eight directions in the thesis's order, shared by both halves of simlab.

The thesis numbers directions the same way for the tabular robot (Table 2.1, Fig. 2.5)
and for the TurtleBot's motion primitives (section 3.2): UP, DOWN, LEFT, RIGHT, UP-LEFT,
UP-RIGHT, DOWN-LEFT, DOWN-RIGHT. What a direction means in space is the user's business:
map-frame headings in :mod:`simlab.physics.motion` (UP = +y), grid steps in
:mod:`simlab.visitlab.actions` (UP = row - 1).
"""

from __future__ import annotations

from enum import IntEnum


class Direction(IntEnum):
    """The eight directions, in the thesis order."""

    UP = 0
    DOWN = 1
    LEFT = 2
    RIGHT = 3
    UP_LEFT = 4
    UP_RIGHT = 5
    DOWN_LEFT = 6
    DOWN_RIGHT = 7
