"""Top-down pictures of the social task: the table, the robot and the human's disc with
its visual and facing fields (thesis 2.1.2); :func:`closed_loop_frame` draws one frame of the
closed loop's GIF (:func:`simlab.social.closedloop.write_closed_loop_gif`), what it draws
given as one :class:`LoopFrame` (the run's :class:`LoopScene` and the frame's poses, level,
goal, caption and trail).

Fields are drawn as wedges of radius ``field_reach`` (m, default the last distance bound:
beyond it the human is "too far" anyway), clipped to nothing: a field drawn through a wall
does not mean the human sees through it (the percepts use the ray test).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import NDArray

from simlab.base import validation
from simlab.physics.arena import ArenaConfig
from simlab.physics.render import TopDown
from simlab.physics.robot import RobotSpec
from simlab.social.human import HumanBody
from simlab.social.perception import SocialPerception
from simlab.social.task import HUMAN_BODIES

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
               field_reach: float | None = None, robot: RobotSpec | None = None) -> TopDown:
    """Draw the human at ``pose`` (x, y, theta; m, m, rad) on ``canvas``: translucent
    visual and facing wedges, the disc (red when engaged, level >= 5) and its gaze.
    With ``robot`` (``human_body="turtlebot"``) the human is drawn as that robot's
    footprint in the human's colour instead of the disc."""
    x, y, th = (float(v) for v in pose)
    reach = perception.bounds_m[-1] if field_reach is None else float(field_reach)
    overlay = canvas.image.copy()
    cv2.fillPoly(overlay, [_wedge(canvas, (x, y), th, perception.visual, reach)], VISUAL,
                 cv2.LINE_AA)
    cv2.fillPoly(overlay, [_wedge(canvas, (x, y), th, perception.facing, reach)], FACING,
                 cv2.LINE_AA)
    canvas.image[:] = cv2.addWeighted(overlay, 0.45, canvas.image, 0.55, 0.0)
    colour = ENGAGED if level >= 5 else HUMAN
    if robot is not None:
        canvas.draw_robot((x, y, th), robot, color=colour)
        return canvas
    cv2.circle(canvas.image, tuple(canvas.px([x, y])), canvas.metres(body.radius), colour, -1,
               cv2.LINE_AA)
    tip = (x + math.cos(th) * body.radius * 1.8, y + math.sin(th) * body.radius * 1.8)
    cv2.arrowedLine(canvas.image, tuple(canvas.px([x, y])), tuple(canvas.px(tip)), colour, 2,
                    cv2.LINE_AA, tipLength=0.35)
    return canvas


def render_social(arena: ArenaConfig, spec: RobotSpec, robot_pose: Sequence[float],
                  human_pose: Sequence[float], body: HumanBody | None = None,
                  perception: SocialPerception | None = None, level: int = 0,
                  pixels_per_metre: float = 320.0, human_body: str = "disc"
                  ) -> NDArray[np.uint8]:
    """RGB image (H, W, 3) of the arena, the human with its fields and the robot
    (``human_body="turtlebot"``: the human drawn as a second robot)."""
    canvas = TopDown(arena, pixels_per_metre).draw_arena()
    draw_human(canvas, human_pose, body or HumanBody(), perception or SocialPerception(),
               level, robot=spec if human_body == "turtlebot" else None)
    canvas.draw_robot(robot_pose, spec)
    return canvas.image


HEADER_PX = 22


@dataclass(frozen=True)
class LoopScene:
    """What every frame of one closed-loop run shares: the ``arena`` and the robot
    ``spec`` drawn, the human's ``body`` and ``perception`` (the fields' angles and
    reach), the scale ``pixels_per_metre`` and ``human_body`` (``"disc"``, or
    ``"turtlebot"``: the human drawn as a second robot)."""

    arena: ArenaConfig
    spec: RobotSpec
    body: HumanBody = field(default_factory=HumanBody)
    perception: SocialPerception = field(default_factory=SocialPerception)
    pixels_per_metre: float = 200.0
    human_body: str = "disc"

    def __post_init__(self) -> None:
        validation.positive(self.pixels_per_metre, "LoopScene.pixels_per_metre")
        validation.choice(self.human_body, HUMAN_BODIES, "LoopScene.human_body")


@dataclass(frozen=True, eq=False)
class LoopFrame:
    """What one frame of the closed loop draws (:func:`closed_loop_frame`): the run's
    ``scene``, the ``robot_pose`` and ``human_pose`` (x, y, theta; m, m, rad), the human's
    social ``level`` (red when engaged, >= 5), the active ``goal`` area highlighted (None:
    none), the header's ``caption`` and the human's recent path ``trail`` (n, 2) m (None
    or fewer than 2 points: no trail). Compared by identity (it holds arrays)."""

    scene: LoopScene
    robot_pose: Sequence[float]
    human_pose: Sequence[float]
    level: int
    goal: str | None
    caption: str = ""
    trail: NDArray[np.float64] | None = None


def closed_loop_frame(frame: LoopFrame) -> NDArray[np.uint8]:
    """One frame of a closed-loop run: RGB (HEADER_PX + H, W, 3) uint8, a white header
    with the caption above the arena with the active goal area highlighted, the human's
    trail, the human with its visual and facing fields and the robot (:class:`LoopFrame`)."""
    scene = frame.scene
    canvas = TopDown(scene.arena, scene.pixels_per_metre).draw_arena(active_goal=frame.goal)
    if frame.trail is not None and len(frame.trail) >= 2:
        canvas.draw_trail(np.asarray(frame.trail, dtype=float)[:, :2], color=HUMAN,
                          thickness=1)
    draw_human(canvas, frame.human_pose, scene.body, scene.perception, frame.level,
               robot=scene.spec if scene.human_body == "turtlebot" else None)
    canvas.draw_robot(frame.robot_pose, scene.spec)
    header = np.full((HEADER_PX, canvas.width, 3), 255, dtype=np.uint8)
    cv2.putText(header, frame.caption, (4, HEADER_PX - 7), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                (0, 0, 0), 1, cv2.LINE_AA)
    return np.concatenate([header, canvas.image], axis=0)
