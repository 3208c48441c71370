"""Issue 17 part 2: the replay GIF with one palette keeps its frames, size and flat colours."""

from __future__ import annotations

import cv2
import imageio.v3 as iio
import numpy as np

from simlab.physics.render import ROBOT, TRAIL
from simlab.replay.video import SCENE_COLOURS, gif_palette, write_video


def _frames(n: int) -> np.ndarray:
    h, w = 60, 80
    yy, xx = np.mgrid[0:h, 0:w]
    out = []
    for i in range(n):
        img = np.stack([(xx * 3 + i) % 256, (yy * 4) % 256, (xx + yy) % 256], -1).astype(np.uint8)
        cv2.circle(img, (10 + 5 * i, 30), 6, ROBOT, -1)
        cv2.line(img, (0, 5), (79, 5 + i), TRAIL, 2, cv2.LINE_AA)
        out.append(img)
    return np.stack(out)


def test_gif_frames_size_and_flat_colours(tmp_path) -> None:
    frames = _frames(7)
    path = write_video(tmp_path / "v.gif", list(frames))
    back = iio.imread(path, index=None)
    assert back.shape == frames.shape
    robot = (frames == ROBOT).all(-1)
    assert robot.sum() > 7 * 50
    assert ((back == ROBOT).all(-1) == robot).all()  # exactly where it was, nowhere else
    assert (back[(frames == TRAIL).all(-1)] == TRAIL).all()
    # the gradient (6000+ colours) is approximated by the rest of the palette
    assert np.abs(back.astype(int) - frames.astype(int)).mean() < 6.0


def test_palette_keeps_scene_colours_first() -> None:
    pal = gif_palette(_frames(3))
    assert pal.shape == (256, 3) and pal.dtype == np.uint8
    np.testing.assert_array_equal(pal[:len(SCENE_COLOURS)], np.asarray(SCENE_COLOURS))
