"""Text and image renders of a Visit-the-lab scene.

:func:`render_text` draws the grid in ASCII (``+--+`` walls, ``R``/``H`` with an
orientation arrow, ``::`` goal room, ``..`` the human's visual field, ``,,`` the
robot's facing field). :func:`render_rgb` draws an RGB image (uint8, shape
``(height * cell_px + 1, width * cell_px + 1, 3)``): goal room in light blue, the
human's visual field in pale yellow and facing field in darker yellow, the robot's
facing field in pale red, walls in black, the robot as a red disc and the human as
a blue disc, each with a line showing its orientation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simlab.visitlab.actions import DIR_DELTA, DIRECTION_ARROWS
from simlab.visitlab.grid import Layout
from simlab.visitlab.perception import Perception, field_of_view


@dataclass(frozen=True)
class Scene:
    """What to draw. Cells are ``-1`` when absent (e.g. no human in navigation)."""

    robot: int
    robot_ori: int = -1
    human: int = -1
    human_ori: int = -1
    goal_label: int = -1
    caption: str = ""


def _fields(layout: Layout, perception: Perception, scene: Scene) -> dict[str, np.ndarray]:
    los = layout.los_table()
    out: dict[str, np.ndarray] = {}
    if scene.human >= 0 and scene.human_ori >= 0:
        out["h_visual"] = field_of_view(layout.walls_h, layout.walls_v, los, scene.human,
                                        scene.human_ori, perception.visual).astype(bool)
        out["h_facing"] = field_of_view(layout.walls_h, layout.walls_v, los, scene.human,
                                        scene.human_ori, perception.facing).astype(bool)
    if scene.robot >= 0 and scene.robot_ori >= 0 and scene.human >= 0:
        out["r_facing"] = field_of_view(layout.walls_h, layout.walls_v, los, scene.robot,
                                        scene.robot_ori, perception.facing).astype(bool)
    return out


def render_text(layout: Layout, perception: Perception, scene: Scene) -> str:
    """ASCII picture of the scene, one line per wall line and per cell row."""
    fields = _fields(layout, perception, scene)
    labels = layout.cell_labels
    lines = []
    wh, wv = layout.walls_h, layout.walls_v
    h, w = layout.height, layout.width

    def corner(r: int, c: int) -> str:
        touching = ((c > 0 and wh[r, c - 1]) or (c < w and wh[r, c])
                    or (r > 0 and wv[r - 1, c]) or (r < h and wv[r, c]))
        return "+" if touching else " "

    for r in range(layout.height + 1):
        top = "".join(corner(r, c) + ("--" if wh[r, c] else "  ") for c in range(w))
        lines.append(top + corner(r, w))
        if r == layout.height:
            break
        row = []
        for c in range(layout.width):
            cell = r * layout.width + c
            row.append("|" if layout.walls_v[r, c] else " ")
            if cell == scene.robot:
                arrow = DIRECTION_ARROWS[scene.robot_ori] if scene.robot_ori >= 0 else " "
                row.append("R" + arrow)
            elif cell == scene.human:
                arrow = DIRECTION_ARROWS[scene.human_ori] if scene.human_ori >= 0 else " "
                row.append("H" + arrow)
            elif "h_visual" in fields and fields["h_visual"][cell]:
                row.append("..")
            elif "r_facing" in fields and fields["r_facing"][cell]:
                row.append(",,")
            elif scene.goal_label >= 0 and labels[cell] == scene.goal_label:
                row.append("::")
            else:
                row.append("  ")
        row.append("|" if layout.walls_v[r, layout.width] else " ")
        lines.append("".join(row))
    if scene.caption:
        lines.append(scene.caption)
    return "\n".join(lines) + "\n"


_WHITE = np.array([255, 255, 255], dtype=np.float64)
_GOAL = np.array([173, 216, 245], dtype=np.float64)
_H_VISUAL = np.array([255, 245, 190], dtype=np.float64)
_H_FACING = np.array([250, 220, 120], dtype=np.float64)
_R_FACING = np.array([250, 200, 200], dtype=np.float64)


def render_rgb(layout: Layout, perception: Perception, scene: Scene, cell_px: int = 20) -> np.ndarray:
    """RGB image of the scene, uint8 ``(H * cell_px + 1, W * cell_px + 1, 3)``."""
    import cv2

    fields = _fields(layout, perception, scene)
    h, w = layout.height, layout.width
    colours = np.tile(_WHITE, (layout.n_cells, 1))
    if scene.goal_label >= 0:
        colours[layout.cell_labels == scene.goal_label] = _GOAL
    # translucent overlays: average with the underlying colour
    for key, tint in (("r_facing", _R_FACING), ("h_visual", _H_VISUAL), ("h_facing", _H_FACING)):
        if key in fields:
            m = fields[key]
            colours[m] = 0.5 * colours[m] + 0.5 * tint
    cells = colours.reshape(h, w, 3).astype(np.uint8)
    img = np.repeat(np.repeat(cells, cell_px, axis=0), cell_px, axis=1)
    img = np.pad(img, ((0, 1), (0, 1), (0, 0)), constant_values=255)
    img = np.ascontiguousarray(img)
    grey = (225, 225, 225)
    for r in range(h + 1):
        cv2.line(img, (0, r * cell_px), (w * cell_px, r * cell_px), grey, 1)
    for c in range(w + 1):
        cv2.line(img, (c * cell_px, 0), (c * cell_px, h * cell_px), grey, 1)
    thick = max(2, cell_px // 8)
    for r, c in zip(*np.nonzero(layout.walls_h), strict=True):
        cv2.line(img, (c * cell_px, r * cell_px), ((c + 1) * cell_px, r * cell_px), (0, 0, 0), thick)
    for r, c in zip(*np.nonzero(layout.walls_v), strict=True):
        cv2.line(img, (c * cell_px, r * cell_px), (c * cell_px, (r + 1) * cell_px), (0, 0, 0), thick)
    for cell, ori, colour in ((scene.human, scene.human_ori, (40, 90, 220)),
                              (scene.robot, scene.robot_ori, (220, 40, 40))):
        if cell < 0:
            continue
        r, c = divmod(cell, w)
        centre = (c * cell_px + cell_px // 2, r * cell_px + cell_px // 2)
        cv2.circle(img, centre, max(2, int(cell_px * 0.38)), colour, -1, lineType=cv2.LINE_AA)
        if ori >= 0:
            dr, dc = DIR_DELTA[ori]
            tip = (int(centre[0] + dc * cell_px * 0.75), int(centre[1] + dr * cell_px * 0.75))
            cv2.line(img, centre, tip, (0, 0, 0), max(1, cell_px // 10), lineType=cv2.LINE_AA)
    return img
