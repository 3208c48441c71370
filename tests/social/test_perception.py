"""Social perception on the table against hand-placed poses (issue 18)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.physics.world import World
from simlab.social.human import HumanBody
from simlab.social.perception import (
    SOCIAL_DIMS,
    SocialPerception,
    distance_class,
    line_of_sight,
    percepts,
    quantise_direction,
    social_obs_index,
)

P = SocialPerception()


def _at(deg: float, r: float = 0.3) -> tuple[float, float, float]:
    """A robot at bearing ``deg`` from a human at the origin, facing the human."""
    a = math.radians(deg)
    return (r * math.cos(a), r * math.sin(a), a + math.pi)


@pytest.mark.parametrize(("deg", "sees"), [(90.0, True), (-90.0, True), (90.1, False),
                                           (-90.1, False), (89.9, True), (180.0, False)])
def test_visual_field_border_is_inclusive_at_90_degrees(deg, sees):
    perc = percepts(_at(deg), (0.0, 0.0, 0.0), True, P)
    assert perc.h_sees is sees
    assert perc.r_looks  # the robot faces the human in every case
    assert perc.level == (3 if sees else 0)


@pytest.mark.parametrize(("deg", "looks"), [(45.0, True), (-45.0, True), (45.1, False),
                                            (-45.1, False), (0.0, True)])
def test_facing_field_border_is_inclusive_at_45_degrees(deg, looks):
    perc = percepts(_at(deg), (0.0, 0.0, 0.0), True, P)
    assert perc.h_looks is looks
    assert perc.level == (4 if looks else 3)


@pytest.mark.parametrize(("deg", "looks"), [(45.0, True), (-45.0, True), (45.1, False)])
def test_robot_facing_field_border(deg, looks):
    # human at (0.3, 0) facing the robot at the origin; the robot's yaw is deg off the human
    perc = percepts((0.0, 0.0, math.radians(deg)), (0.3, 0.0, math.pi), True, P)
    assert perc.r_looks is looks
    assert perc.h_looks
    assert perc.level == (4 if looks else 2)


def test_no_line_of_sight_no_percept():
    perc = percepts(_at(0.0), (0.0, 0.0, 0.0), False, P)
    assert perc.level == 0 and not (perc.h_sees or perc.h_looks or perc.r_looks)


@pytest.mark.parametrize(("d", "cls"), [(0.0, 0), (0.15, 0), (0.1501, 1), (0.30, 1),
                                        (0.3001, 2), (0.45, 2), (0.4501, 3), (0.60, 3),
                                        (0.6001, 4), (2.0, 4)])
def test_distance_classes_at_the_thresholds(d, cls):
    assert distance_class(d, P) == cls
    assert percepts((0.0, 0.0, 0.0), (d, 0.0, math.pi), True, P).distance_class == cls


def test_default_bounds_are_the_thesis_cells_times_cell_size():
    size = HumanBody().cell_size
    assert np.allclose(P.bounds_m, [k * size for k in (1, 2, 3, 4)])


@pytest.mark.parametrize(("deg", "direction"), [(90, 0), (-90, 1), (180, 2), (0, 3), (135, 4),
                                                (45, 5), (-135, 6), (-45, 7), (22.4, 3),
                                                (22.6, 5), (-22.4, 3), (-157.6, 2)])
def test_angle_is_the_nearest_direction(deg, direction):
    assert quantise_direction(math.radians(deg)) == direction


def test_social_index_is_the_grids():
    from simlab.visitlab.dynamics import SOCIAL_DIMS as GRID_DIMS

    assert SOCIAL_DIMS == tuple(GRID_DIMS)
    for values in [(0, 0, 0, 0), (7, 4, 7, 7), (3, 1, 5, 2), (5, 2, 0, 6)]:
        assert social_obs_index(*values) == int(np.ravel_multi_index(values, GRID_DIMS))
    with pytest.raises(ValueError):
        social_obs_index(8, 0, 0, 0)


def test_bad_perception_settings_raise_config_error():
    with pytest.raises(ConfigError, match="bounds_m"):
        SocialPerception(bounds_m=(0.3, 0.2, 0.4, 0.5))
    with pytest.raises(ConfigError, match="facing_deg"):
        SocialPerception(visual_deg=30.0, facing_deg=45.0)


# ------------------------------------------------------------------ line of sight
# table_obstacles: box centred (-0.22, 0.22), 0.24 x 0.10 (x in [-0.34, -0.10],
# y in [0.17, 0.27]); cylinder centred (0.24, -0.22), radius 0.07.


@pytest.fixture(scope="module")
def obstacles_world():
    with World("table_obstacles") as world:
        yield world


@pytest.mark.parametrize(("robot", "human", "clear"), [
    ((-0.22, 0.0), (-0.22, 0.45), False),   # through the box
    ((-0.05, 0.0), (-0.05, 0.45), True),    # 5 cm beside the box's end
    ((0.24, 0.05), (0.24, -0.50), False),   # through the cylinder
    ((0.35, 0.05), (0.35, -0.50), True),    # 4 cm beside the cylinder
    ((-0.5, -0.5), (0.5, 0.5), True),       # the open diagonal
])
def test_line_of_sight_against_obstacles(obstacles_world, robot, human, clear):
    obstacles_world.reset((robot[0], robot[1], 0.0))
    assert line_of_sight(obstacles_world, human) is clear
    # symmetric in the roles: the robot standing where the human was
    obstacles_world.reset((human[0], human[1], 0.0))
    assert line_of_sight(obstacles_world, robot) is clear


def test_occluded_human_does_not_see_the_robot(obstacles_world):
    obstacles_world.reset((-0.22, 0.0, math.pi / 2))  # robot faces the human
    human = (-0.22, 0.45, -math.pi / 2)  # human faces the robot, box between
    vis = line_of_sight(obstacles_world, human[:2])
    assert percepts(obstacles_world.pose(), human, vis, P).level == 0
    assert percepts(obstacles_world.pose(), human, True, P).level == 4


def test_render_draws_the_human_and_its_fields():
    from simlab.physics.render import TopDown
    from simlab.social.render import FACING, render_social

    with World("table") as world:
        img = render_social(world.arena, world.robot_spec, (-0.5, -0.5, 0.0), (0.0, 0.0, 0.0))
        canvas = TopDown(world.arena)
    assert img.shape == canvas.image.shape
    ahead = canvas.px([0.3, 0.0])    # in the facing wedge
    behind = canvas.px([-0.2, 0.1])  # behind the human: plain floor
    col = img[ahead[1], ahead[0]].astype(int)
    assert col[2] > col[0]  # tinted blue (FACING) over the floor
    assert np.array_equal(img[behind[1], behind[0]], [238, 232, 220])
    assert FACING[2] > FACING[0]
