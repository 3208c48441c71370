"""The required direction around obstacles (issue 18: plan from the human)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from simlab.base.actions import HEADINGS
from simlab.physics.arena import Obstacle, load_arena
from simlab.social.closedloop import goal_direction
from simlab.social.human import is_free
from simlab.social.perception import bearing, quantise_direction
from simlab.social.planning import first_leg_bearing, segment_free

RADIUS = 0.06  # the human's disc (HumanBody default)


@pytest.fixture(scope="module")
def table():
    return load_arena("table")


@pytest.fixture(scope="module")
def walled(table):
    """The table with a 0.10 x 0.60 m box standing across its middle (x = 0)."""
    box = Obstacle(kind="box", x=0.0, y=0.0, height=0.3, size=(0.10, 0.60))
    return dataclasses.replace(table, obstacles=(box,))


def test_straight_heading_when_nothing_blocks(table, walled):
    rng = np.random.default_rng(0)
    for _ in range(30):
        xy = rng.uniform(-0.69, 0.69, size=2)
        for goal in table.goals:
            straight = quantise_direction(bearing(xy, (goal.x, goal.y)))
            assert goal_direction(xy, goal, table, RADIUS) == straight
            assert goal_direction(xy, goal) == straight
    # the box does not lie between NW and N: straight as well
    nw, north = walled.goal("NW"), walled.goal("N")
    xy = np.array([nw.x, nw.y])
    assert segment_free(walled, xy, (north.x, north.y), RADIUS)
    assert goal_direction(xy, north, walled, RADIUS) == quantise_direction(0.0)


def test_the_direction_goes_around_a_blocking_obstacle(walled):
    west, east = walled.goal("W"), walled.goal("E")
    human = np.array([west.x, west.y])
    straight = quantise_direction(0.0)  # W -> E is +x
    assert not segment_free(walled, human, (east.x, east.y), RADIUS)
    d = goal_direction(human, east, walled, RADIUS)
    assert d != straight
    leg = first_leg_bearing(walled, human, np.array([east.x, east.y]), RADIUS)
    assert d == quantise_direction(leg)
    # the leg has a vertical part: it heads for one end of the box (|y| > 0.3 + radius)
    assert abs(math.sin(float(HEADINGS[d]))) > 0.5


def test_following_the_required_direction_reaches_the_goal(walled):
    """A disc stepped 5 cm along the required direction, recomputed at every step, goes
    around the box into the goal area without touching it."""
    west, east = walled.goal("W"), walled.goal("E")
    xy = np.array([west.x, west.y])
    for _ in range(80):
        if east.contains(xy):
            break
        d = goal_direction(xy, east, walled, RADIUS)
        xy = xy + 0.05 * np.array([math.cos(HEADINGS[d]), math.sin(HEADINGS[d])])
        assert is_free(walled, xy, RADIUS * 0.5)
    assert east.contains(xy)
