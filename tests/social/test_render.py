"""The closed loop's frame drawn from one LoopFrame record: the same pixels as the
12-parameter function it replaced, for both human bodies, with and without trail/goal."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.physics.arena import load_arena
from simlab.physics.render import TopDown
from simlab.physics.robot import load_robot_spec
from simlab.social.human import HumanBody
from simlab.social.perception import SocialPerception
from simlab.social.render import (
    HEADER_PX,
    HUMAN,
    LoopFrame,
    LoopScene,
    closed_loop_frame,
    draw_human,
)


def _frame_as_before(arena, spec, robot_pose, human_pose, level, goal, caption="", body=None,
                     perception=None, trail=None, pixels_per_metre=200.0, human_body="disc"):
    """closed_loop_frame's body as it was with its 12 parameters (the reference)."""
    canvas = TopDown(arena, pixels_per_metre).draw_arena(active_goal=goal)
    if trail is not None and len(trail) >= 2:
        canvas.draw_trail(np.asarray(trail, dtype=float)[:, :2], color=HUMAN, thickness=1)
    draw_human(canvas, human_pose, body or HumanBody(), perception or SocialPerception(),
               level, robot=spec if human_body == "turtlebot" else None)
    canvas.draw_robot(robot_pose, spec)
    header = np.full((HEADER_PX, canvas.width, 3), 255, dtype=np.uint8)
    cv2.putText(header, caption, (4, HEADER_PX - 7), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                (0, 0, 0), 1, cv2.LINE_AA)
    return np.concatenate([header, canvas.image], axis=0)


CASES = [
    # robot pose, human pose, level, goal, caption, trail
    ((0.1, -0.2, 0.3), (-0.3, 0.35, -2.0), 2, "NE", "random t=  12.5s level=2", None),
    ((-0.5, 0.5, math.pi), (0.3, 0.1, 1.0), 6, None, "",
     np.array([[0.0, 0.0], [0.1, 0.05], [0.2, 0.08], [0.3, 0.1]])),
    ((0.0, 0.0, 0.0), (0.45, -0.45, 2.4), 5, "SW", "combined level=5 reached=3",
     np.array([[0.45, -0.45]])),  # one point: no trail
]


@pytest.mark.parametrize("human_body", ["disc", "turtlebot"])
@pytest.mark.parametrize("arena_name,ppm", [("table", 200.0), ("table_obstacles", 97.0)])
def test_record_frame_has_the_pixels_of_the_parameter_frame(human_body, arena_name, ppm):
    arena, spec = load_arena(arena_name), load_robot_spec("turtlebot3_burger")
    body, perception = HumanBody(radius=0.08), SocialPerception()
    scene = LoopScene(arena, spec, body, perception, ppm, human_body)
    for robot, human, level, goal, caption, trail in CASES:
        new = closed_loop_frame(LoopFrame(scene, robot, human, level, goal, caption, trail))
        old = _frame_as_before(arena, spec, robot, human, level, goal, caption, body,
                               perception, trail, ppm, human_body)
        assert new.dtype == np.uint8 and new.shape == old.shape
        assert np.array_equal(new, old)


def test_scene_defaults_are_the_old_defaults():
    arena, spec = load_arena("table"), load_robot_spec("turtlebot3_burger")
    robot, human, level, goal, caption, trail = CASES[1]
    new = closed_loop_frame(LoopFrame(LoopScene(arena, spec), robot, human, level, goal,
                                      caption, trail))
    assert np.array_equal(new, _frame_as_before(arena, spec, robot, human, level, goal,
                                                caption, trail=trail))


def test_bad_scene_is_refused_naming_the_field():
    arena, spec = load_arena("table"), load_robot_spec("turtlebot3_burger")
    with pytest.raises(ConfigError, match="human_body"):
        LoopScene(arena, spec, human_body="robot")
    with pytest.raises(ConfigError, match="pixels_per_metre"):
        LoopScene(arena, spec, pixels_per_metre=0.0)
