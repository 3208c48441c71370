"""The top-down replay video (thesis Fig. 4.11): GIF, and MP4 when imageio-ffmpeg exists.

Each frame shows, on the arena drawn by :class:`simlab.physics.render.TopDown`:

* the heat map of ``max_a Q(s, a)`` of the **current goal** over the Voronoi cells
  (cells rasterised with :func:`simlab.training.heatmap.rasterize_cells`, colours
  normalised per goal), the cell boundaries and an arrow per cell for
  ``argmax_a Q(s, a)`` over the valid actions (direction from the Q-tables' action set,
  longer for fast actions);
* the occupancy map's occupied cells (dark), so the map can be compared with the
  arena's true walls and obstacles (brown/grey);
* the current goal area (bold circle) and the other goals (thin circles);
* the cell of the state the robot believes it is in (red outline; the thesis's red
  state), the recent true trajectory (yellow), the MCL particles (blue dots) when MCL runs,
  the true robot (dark footprint) and the pose estimate (red arrow);
* a header line: robot time, goal, rewards.

Frames are recorded every ``stride`` transitions during the replay (:class:`FrameState`)
and rendered at the end, so recording costs almost nothing in the loop.
"""

from __future__ import annotations

import importlib.util
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from simlab.base.io import atomic_write
from simlab.physics.render import (
    FLOOR,
    GOAL,
    GOAL_ACTIVE,
    HEADING,
    OBSTACLE,
    ROBOT,
    SCAN,
    TRAIL,
    WALL,
    TopDown,
)

HEADER_PX = 26
CELL_EDGE = (70, 70, 70)
MAP_OCCUPIED = (25, 25, 25)
STATE_OUTLINE = (230, 30, 30)
ESTIMATE = (230, 30, 30)
PARTICLE = (40, 90, 230)
ARROW = (255, 255, 255)
HEADER_TEXT = (20, 20, 20)

#: The colours the replay draws flat (arena, robot, trail, overlays, header): the GIF's one
#: palette keeps each of them exactly, whatever else the frames hold.
SCENE_COLOURS: tuple[tuple[int, int, int], ...] = (
    (255, 255, 255), HEADER_TEXT, FLOOR, WALL, OBSTACLE, GOAL, GOAL_ACTIVE, ROBOT, HEADING,
    TRAIL, SCAN, CELL_EDGE, MAP_OCCUPIED, STATE_OUTLINE, PARTICLE)


@dataclass(frozen=True)
class FrameState:
    """What one frame shows: robot time ``t`` (s), ``goal`` index, believed ``state``,
    ``truth`` and ``estimate`` poses (3,), the number of true poses of the trail so far
    ``trail_end``, the particles ``(k, 3)`` (or None) and the ``rewards`` so far."""

    t: float
    goal: int
    state: int
    truth: NDArray[np.float64]
    estimate: NDArray[np.float64]
    trail_end: int
    particles: NDArray[np.float64] | None
    rewards: int


def mp4_available() -> bool:
    """Whether imageio can write MP4 here (needs the optional imageio-ffmpeg package)."""
    return importlib.util.find_spec("imageio_ffmpeg") is not None


class ReplayCanvas:
    """Renders :class:`FrameState` records over a static, per-goal background.

    Parameters: the ``arena`` and robot ``spec``; ``centres`` ``(S, 2)`` of the
    discretizer; ``Q`` ``(G, S, A)`` (None: no heat map); ``goal_names``; ``grid`` an
    occupancy map to overlay (None: none); ``pixels_per_metre``; ``trail_length`` the
    number of recent transitions whose true path is drawn.
    """

    def __init__(self, arena: Any, spec: Any, centres: NDArray[np.float64],
                 Q: NDArray[np.float64] | None, goal_names: Sequence[str], grid: Any = None,
                 pixels_per_metre: float = 200.0, trail_length: int = 30, *,
                 action_set: Any = None, valid: NDArray[np.bool_] | None = None) -> None:
        from simlab.base.actions import SIMLAB16
        from simlab.training.heatmap import ARROW_DIRECTIONS, rasterize_cells

        self.action_set = SIMLAB16 if action_set is None else action_set
        self.valid = None if valid is None else np.asarray(valid, dtype=bool)

        self.arena, self.spec = arena, spec
        self.goal_names = tuple(goal_names)
        self.trail_length = int(trail_length)
        self.centres = np.asarray(centres, dtype=np.float64)
        self.Q = None if Q is None else np.asarray(Q, dtype=np.float64)
        base = TopDown(arena, pixels_per_metre)
        self._topdown = base
        h, w = base.height, base.width
        bounds = (base.x0, base.y1 - h / base.scale, base.x0 + w / base.scale, base.y1)
        self.labels, _ = rasterize_cells(self.centres, bounds, 1.0 / base.scale)
        cols = base.x0 + (np.arange(w) + 0.5) / base.scale
        rows = base.y1 - (np.arange(h) + 0.5) / base.scale
        gx, gy = np.meshgrid(cols, rows)
        pts = np.stack([gx, gy], axis=-1)
        self.floor = ~np.asarray(arena.occupied(pts), dtype=bool)
        edge = np.zeros((h, w), dtype=bool)
        edge[:, 1:] |= self.labels[:, 1:] != self.labels[:, :-1]
        edge[1:, :] |= self.labels[1:, :] != self.labels[:-1, :]
        self.edges = edge & self.floor
        self.map_occupied = np.zeros((h, w), dtype=bool)
        if grid is not None:
            rc = grid.world_to_pixel(pts)
            inside = grid.in_bounds(rc)
            occ = np.zeros((h, w), dtype=bool)
            occ[inside] = grid.occupancy[rc[inside][:, 0], rc[inside][:, 1]] >= 65
            self.map_occupied = occ
        self._arrows = ARROW_DIRECTIONS
        self._backgrounds: dict[int, NDArray[np.uint8]] = {}

    def _q(self, goal: int) -> NDArray[np.float64]:
        """Q of ``goal`` with masked actions at -inf."""
        from simlab.training.heatmap import masked_q

        return masked_q(self.Q[goal], None if self.valid is None else self.valid[goal])

    @property
    def shape(self) -> tuple[int, int]:
        return self.labels.shape[0] + HEADER_PX, self.labels.shape[1]

    def background(self, goal: int) -> NDArray[np.uint8]:
        """The static picture of goal ``goal`` (cached)."""
        if goal in self._backgrounds:
            return self._backgrounds[goal]
        import matplotlib

        canvas = TopDown(self.arena, self._topdown.scale)
        canvas.draw_arena(goals=False)
        img = canvas.image
        if self.Q is not None:
            v = self._q(goal).max(axis=1)
            lo, hi = float(v.min()), float(v.max())
            norm = (v - lo) / (hi - lo) if hi > lo else np.zeros_like(v)
            lut = (matplotlib.colormaps["viridis"](np.linspace(0, 1, 256))[:, :3] * 255)
            colours = lut[np.clip((norm * 255).round().astype(int), 0, 255)].astype(np.uint8)
            heat = colours[self.labels]
            img[self.floor] = (0.35 * img[self.floor] + 0.65 * heat[self.floor]).astype(np.uint8)
        img[self.edges] = CELL_EDGE
        img[self.map_occupied] = MAP_OCCUPIED
        if self.Q is not None:
            q = self._q(goal)
            for s, c in enumerate(self.centres):
                row = q[s][np.isfinite(q[s])]
                if np.ptp(row) <= 0:
                    continue  # nothing learned in this state
                a = int(np.argmax(q[s]))
                length = 0.04 if self.action_set.speed_index(a) == 0 else 0.07
                tip = c + length * self._arrows[int(self.action_set.direction(a))]
                cv2.arrowedLine(img, tuple(canvas.px(c)), tuple(canvas.px(tip)), ARROW, 1,
                                cv2.LINE_AA, tipLength=0.35)
        canvas.draw_goals(self.goal_names[goal] if self.goal_names else None, labels=True)
        out = np.full((self.shape[0], self.shape[1], 3), 255, dtype=np.uint8)
        out[HEADER_PX:] = canvas.image
        self._backgrounds[goal] = out
        return out

    def render(self, frame: FrameState, trail: NDArray[np.float64]) -> NDArray[np.uint8]:
        """One RGB frame ``(H, W, 3)``; ``trail`` ``(n, 2+)`` true positions of the run."""
        img = self.background(frame.goal).copy()
        canvas = self._topdown
        canvas.image = img[HEADER_PX:]  # a row slice: contiguous, so OpenCV draws into img
        cell = (self.labels == frame.state).astype(np.uint8)
        outline = cell.astype(bool) & ~cv2.erode(cell, np.ones((3, 3), np.uint8)).astype(bool)
        canvas.image[outline & self.floor] = STATE_OUTLINE
        first = max(0, frame.trail_end - self.trail_length)
        if frame.trail_end - first >= 2:
            canvas.draw_trail(np.asarray(trail)[first:frame.trail_end, :2], TRAIL, 2)
        if frame.particles is not None and len(frame.particles):
            canvas.draw_points(frame.particles[:, :2], PARTICLE, 1)
        canvas.draw_robot(frame.truth, self.spec)
        x, y, th = (float(v) for v in frame.estimate)
        tip = (x + 0.08 * math.cos(th), y + 0.08 * math.sin(th))
        cv2.arrowedLine(canvas.image, tuple(canvas.px([x, y])), tuple(canvas.px(tip)),
                        ESTIMATE, 2, cv2.LINE_AA, tipLength=0.4)
        goal = self.goal_names[frame.goal] if self.goal_names else str(frame.goal)
        text = f"t = {frame.t / 3600:.2f} h   goal {goal}   reward {frame.rewards}"
        cv2.putText(img, text, (6, HEADER_PX - 8), cv2.FONT_HERSHEY_SIMPLEX, 0.45, HEADER_TEXT,
                    1, cv2.LINE_AA)
        return img


def gif_palette(stack: NDArray[np.uint8], keep: Sequence[tuple[int, int, int]] = SCENE_COLOURS,
                samples: int = 12) -> NDArray[np.uint8]:
    """One 256-colour palette ``(256, 3)`` for all frames of ``stack`` ``(n, H, W, 3)``: the
    ``keep`` colours exactly, the rest by median cut over ``samples`` evenly spaced frames
    (every second row and column).

    Decision: one palette for the whole GIF instead of PIL's adaptive quantisation
    of every frame (2.5 s of the 9 s video write at 146 frames): the frames share one arena
    and a few flat colours, so one palette shows the same picture; the flat colours are kept
    exact, the heat map's blends and anti-aliased edges move by a few levels at most.
    """
    from PIL import Image

    keep_arr = np.asarray(keep, dtype=np.uint8).reshape(-1, 3)[:256]
    n_free = 256 - len(keep_arr)
    idx = np.unique(np.linspace(0, len(stack) - 1, min(len(stack), samples)).round().astype(int))
    rest = np.zeros((0, 3), dtype=np.uint8)
    if n_free > 0:
        mosaic = Image.fromarray(np.ascontiguousarray(np.concatenate(stack[idx, ::2, ::2])))
        q = mosaic.quantize(colors=n_free, method=Image.Quantize.MEDIANCUT,
                            dither=Image.Dither.NONE)
        used = len(q.getcolors(n_free) or ()) or n_free
        rest = np.asarray(q.getpalette()[:3 * used], dtype=np.uint8).reshape(-1, 3)
    palette = np.zeros((256, 3), dtype=np.uint8)
    palette[:len(keep_arr)] = keep_arr
    palette[len(keep_arr):len(keep_arr) + len(rest)] = rest[:n_free]
    return palette


class _Nearest:
    """Exact nearest-palette-colour lookup ``(H, W, 3)`` uint8 -> ``(H, W)`` indices, the
    answers cached per 24-bit colour (16 MB table), so each colour is searched once."""

    def __init__(self, palette: NDArray[np.uint8]) -> None:
        self.palette = palette.astype(np.int32)
        self.table = np.zeros(1 << 24, dtype=np.uint8)
        self.known = np.zeros(1 << 24, dtype=bool)

    def __call__(self, frame: NDArray[np.uint8]) -> NDArray[np.uint8]:
        key = (frame[..., 0].astype(np.int32) << 16) | (frame[..., 1].astype(np.int32) << 8) \
            | frame[..., 2]
        new = np.unique(key[~self.known[key]])
        if new.size:
            rgb = np.stack([new >> 16, (new >> 8) & 255, new & 255], axis=1)
            d = ((rgb[:, None, :] - self.palette[None, :, :]) ** 2).sum(axis=2)
            self.table[new] = np.argmin(d, axis=1)  # first of equals: kept colours win
            self.known[new] = True
        return self.table[key]


def _write_gif(fh: Any, stack: NDArray[np.uint8], fps: float) -> None:
    """The frames ``(n, H, W, 3)`` as a looping GIF with one palette (:func:`gif_palette`)."""
    from PIL import Image

    palette = gif_palette(stack)
    nearest = _Nearest(palette)
    images = []
    for frame in stack:
        im = Image.fromarray(nearest(frame), mode="P")
        im.putpalette(palette.ravel().tolist())
        images.append(im)
    images[0].save(fh, format="GIF", save_all=True, append_images=images[1:],
                   duration=round(1000.0 / fps), loop=0, optimize=False)


def write_video(path: str | os.PathLike[str], frames: Sequence[NDArray[np.uint8]],
                fps: float = 10.0) -> Path:
    """Write ``frames`` (RGB uint8) atomically: GIF for ``.gif`` (one palette for all frames,
    :func:`gif_palette`), MP4 for ``.mp4`` (needs imageio-ffmpeg)."""
    path = Path(path)
    suffix = path.suffix.lower()
    stack = np.stack(list(frames))
    if suffix == ".gif":
        with atomic_write(path, "wb") as fh:
            _write_gif(fh, stack, fps)
    elif suffix == ".mp4":
        import imageio.v3 as iio

        # ffmpeg needs a seekable real file: write beside the target, then rename.
        tmp = path.with_name(f".{path.name}.partial.mp4")
        try:
            iio.imwrite(tmp, stack, fps=fps, codec="libx264", macro_block_size=1)
            os.replace(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)
    else:
        raise ValueError(f"unsupported video type {suffix!r} (use .gif or .mp4)")
    return path
