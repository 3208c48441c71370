"""Top-down pictures of the social task: the table, the robot and the human's disc with
its visual and facing fields (issue 18; the later GIF builds on :func:`render_social`).

Fields are drawn as wedges of radius ``field_reach`` (m, default the last distance bound:
beyond it the human is "too far" anyway), clipped to nothing: a field drawn through a wall
does not mean the human sees through it (the percepts use the ray test).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np
from numpy.typing import NDArray

from simlab.physics.arena import ArenaConfig
from simlab.physics.render import TopDown
from simlab.physics.robot import RobotSpec
from simlab.social.human import HumanBody
from simlab.social.perception import SocialPerception

HUMAN = (200, 60, 140)
ENGAGED = (220, 30, 30)
VISUAL = (150, 200, 240)
FACING = (70, 130, 220)


def _wedge(canvas: TopDown, xy: Sequence[float], theta: float, half: float,
           reach: float, n: int = 24) -> NDArray[np.int32]:
    angles = np.linspace(theta - half, theta + half, n)
    pts = [(xy[0], xy[1])] + [(xy[0] + reach * math.cos(a), xy[1] + reach * math.sin(a))
                              for a in angles]
    return canvas.px(pts)


def draw_human(canvas: TopDown, pose: Sequence[float], body: HumanBody,
               perception: SocialPerception, level: int = 0,
               field_reach: float | None = None) -> TopDown:
    """Draw the human at ``pose`` (x, y, theta; m, m, rad) on ``canvas``: translucent
    visual and facing wedges, the disc (red when engaged, level >= 5) and its gaze."""
    x, y, th = (float(v) for v in pose)
    reach = perception.bounds_m[-1] if field_reach is None else float(field_reach)
    overlay = canvas.image.copy()
    cv2.fillPoly(overlay, [_wedge(canvas, (x, y), th, perception.visual, reach)], VISUAL,
                 cv2.LINE_AA)
    cv2.fillPoly(overlay, [_wedge(canvas, (x, y), th, perception.facing, reach)], FACING,
                 cv2.LINE_AA)
    canvas.image[:] = cv2.addWeighted(overlay, 0.45, canvas.image, 0.55, 0.0)
    colour = ENGAGED if level >= 5 else HUMAN
    cv2.circle(canvas.image, tuple(canvas.px([x, y])), canvas.metres(body.radius), colour, -1,
               cv2.LINE_AA)
    tip = (x + math.cos(th) * body.radius * 1.8, y + math.sin(th) * body.radius * 1.8)
    cv2.arrowedLine(canvas.image, tuple(canvas.px([x, y])), tuple(canvas.px(tip)), colour, 2,
                    cv2.LINE_AA, tipLength=0.35)
    return canvas


def render_social(arena: ArenaConfig, spec: RobotSpec, robot_pose: Sequence[float],
                  human_pose: Sequence[float], body: HumanBody | None = None,
                  perception: SocialPerception | None = None, level: int = 0,
                  pixels_per_metre: float = 320.0) -> NDArray[np.uint8]:
    """RGB image (H, W, 3) of the arena, the human with its fields and the robot."""
    canvas = TopDown(arena, pixels_per_metre).draw_arena()
    draw_human(canvas, human_pose, body or HumanBody(), perception or SocialPerception(),
               level)
    canvas.draw_robot(robot_pose, spec)
    return canvas.image
