"""The cumulative-reward figure and the top-down frames."""

from __future__ import annotations

import numpy as np

from simlab.physics.arena import load_arena
from simlab.physics.robot import load_robot_spec
from simlab.replay.plots import RewardCurve, cumulative_steps, plot_cumulative_reward
from simlab.replay.video import HEADER_PX, FrameState, ReplayCanvas, write_video


def test_cumulative_steps() -> None:
    x, y = cumulative_steps(np.array([7200.0, 1800.0]), 3 * 3600.0)
    np.testing.assert_allclose(x, [0.0, 0.5, 2.0, 3.0])
    np.testing.assert_allclose(y, [0, 1, 2, 2])


def test_plot_is_a_png(tmp_path) -> None:
    path = tmp_path / "c.png"
    plot_cumulative_reward(path, [RewardCurve("a", np.array([10.0, 20.0]), 60.0)],
                           [("predicted", 100.0), ("none", float("nan"))], hours=60 / 3600)
    assert path.read_bytes()[:4] == b"\x89PNG"
    assert not list(tmp_path.glob(".*.tmp"))


def test_frames_show_the_current_goal_and_the_believed_state(chain, tmp_path) -> None:
    arena = load_arena("table")
    Q = np.stack([chain.Q[g] for g in chain.goal_names])
    canvas = ReplayCanvas(arena, load_robot_spec(), chain.discretizer.centres, Q,
                          chain.goal_names)
    pose = np.array([0.1, 0.2, 0.5])
    s = int(chain.discretizer.state_of(pose[:2]))
    frame = FrameState(t=10.0, goal=2, state=s, truth=pose, estimate=pose, trail_end=2,
                       particles=np.array([[0.1, 0.2, 0.0]]), rewards=3)
    img = canvas.render(frame, np.array([[0.0, 0.0, 0.0], [0.1, 0.2, 0.5]]))
    assert img.shape == (*canvas.shape, 3) and img.dtype == np.uint8
    # Backgrounds differ between goals (their heat maps), and are cached.
    assert not np.array_equal(canvas.background(0), canvas.background(2))
    assert canvas.background(2) is canvas.background(2)
    # The believed state's cell is outlined in red somewhere in the picture.
    red = (img[HEADER_PX:, :, 0] > 200) & (img[HEADER_PX:, :, 1] < 60) & \
        (img[HEADER_PX:, :, 2] < 60)
    assert red.any()
    other = canvas.render(FrameState(t=20.0, goal=0, state=0, truth=pose, estimate=pose,
                                     trail_end=1, particles=None, rewards=4), np.zeros((1, 3)))
    path = write_video(tmp_path / "v.gif", [img, other])
    import imageio.v3 as iio

    assert iio.imread(path, index=None).shape[0] == 2
