"""``simlab train`` end to end, its outputs, its errors, and the heat maps."""

from __future__ import annotations

import json

import matplotlib.image as mpimg
import numpy as np
import pytest
from scipy.spatial import cKDTree

from simlab.agents import load_q_table
from simlab.base.errors import ConfigError
from simlab.cli import main
from simlab.training.heatmap import ARROW_DIRECTIONS, rasterize_cells
from simlab.training.train import train


def test_train_writes_q_tables_curves_summary_and_heat_maps(small_mdp_file, tmp_path):
    out = tmp_path / "out"
    s = train(small_mdp_file, "vi-softmax", "g1,g5", episodes=60, runs=2, seed=3, out=out,
              progress=False)  # fmt: skip
    names = sorted(p.name for p in out.iterdir())
    assert names == ["curves.npz", "curves.png", "heatmap_g1.png", "heatmap_g5.png",
                     "heatmaps.png", "q_g1.npz", "q_g5.npz", "summary.json"]  # fmt: skip
    Q, meta = load_q_table(out / "q_g1.npz")
    assert Q.shape == (12, 16) and Q.dtype == np.float64
    assert meta["goal"] == "g1" and meta["agent"] == "vi-softmax" and meta["runs"] == 2
    with np.load(out / "q_g1.npz", allow_pickle=False) as q:
        np.testing.assert_allclose(q["Q_runs"].mean(0), Q)
        assert q["Q_star"].shape == (12, 16) and q["goal_mask"].dtype == bool
    with np.load(out / "curves.npz", allow_pickle=False) as c:
        assert c["rewards"].shape == (2, 2, 60)
        assert list(c["goal_names"]) == ["g1", "g5"]
        assert c["curve_mean"].shape == (2, 60)
        np.testing.assert_array_equal(c["rewards"], s.rewards)
    summary = json.loads((out / "summary.json").read_text())
    g1 = summary["goals"]["g1"]
    assert g1["final_mean_reward"] == pytest.approx(s.rewards[0][:, -6:].mean())
    assert g1["ratio"] == pytest.approx(g1["final_mean_reward"] / g1["optimal_return"])
    assert 0 < g1["optimal_return"] <= g1["upper_bound"] + 1e-9 <= 50
    img = mpimg.imread(out / "heatmaps.png")
    assert img.ndim == 3 and img.shape[0] > 100


def test_one_goal_alone_equals_the_same_goal_among_all(small_mdp_file):
    alone = train(small_mdp_file, "q-softmax", "g7", episodes=30, runs=2, seed=9, progress=False)
    every = train(small_mdp_file, "q-softmax", "all", episodes=30, runs=2, seed=9, progress=False)
    np.testing.assert_array_equal(alone.rewards[0], every.rewards[6])
    np.testing.assert_array_equal(alone.Q["g7"], every.Q["g7"])
    assert len(every.goals) == 9


def test_existing_outputs_are_kept_unless_overwrite(small_mdp_file, tmp_path):
    out = tmp_path / "out"
    train(small_mdp_file, "rmax", "g2", episodes=5, runs=1, out=out, plots=False, progress=False)
    before = (out / "q_g2.npz").read_bytes()
    with pytest.raises(ConfigError, match="already exists"):
        train(small_mdp_file, "rmax", "g2", episodes=5, runs=1, seed=1, out=out, plots=False,
              progress=False)  # fmt: skip
    assert (out / "q_g2.npz").read_bytes() == before
    train(small_mdp_file, "rmax", "g2", episodes=5, runs=1, seed=1, out=out, plots=False,
          progress=False, overwrite=True)  # fmt: skip
    assert (out / "q_g2.npz").read_bytes() != before


def test_cli_train(small_mdp_file, tmp_path, capsys):
    out = tmp_path / "cli"
    code = main(["train", "--mdp", str(small_mdp_file), "--agent", "vi-softmax", "--goals", "all",
                 "--episodes", "20", "--runs", "2", "--seed", "1", "--out", str(out),
                 "--no-progress", "--no-plots", "--param", "tau=0.05"])  # fmt: skip
    assert code == 0
    text = capsys.readouterr().out
    assert "9 goal(s) x 2 runs x 20 episodes" in text and "g9" in text
    assert len(list(out.glob("q_*.npz"))) == 9
    assert json.loads((out / "summary.json").read_text())["config"]["tau"] == 0.05


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--agent", "dqn"], "unknown agent 'dqn'; known agents: q-learning"),
        (["--goals", "g1,hall"], "unknown goal 'hall'; valid goals: g1, g2"),
        (["--param", "temperature=1"], "unknown parameter 'temperature'"),
        (["--param", "tau=-1"], "tau: expected a finite number > 0"),
    ],
)
def test_cli_errors_are_one_line_and_exit_2(small_mdp_file, tmp_path, capsys, args, message):
    code = main(["train", "--mdp", str(small_mdp_file), "--out", str(tmp_path / "o"),
                 "--episodes", "2", "--runs", "1", "--no-progress", *args])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o").exists()  # nothing written before the check


def test_cli_rejects_a_bad_npz(tmp_path, small_mdp, write_mdp, capsys):
    T = small_mdp.T.copy()
    T[0, 0, :] = 0
    path = write_mdp(tmp_path / "bad.npz", small_mdp, T=T)
    assert main(["train", "--mdp", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "bad.npz: T: row T[0, 0, :] sums to 0" in capsys.readouterr().err


# --------------------------------------------------------------------------- heat maps
def test_rasterized_cells_are_the_nearest_centres():
    rng = np.random.default_rng(0)
    centres = rng.uniform(-0.75, 0.75, (15, 2))
    labels, extent = rasterize_cells(centres, (-0.75, -0.75, 0.75, 0.75), resolution=0.01)
    assert labels.shape == (150, 150) and extent == (-0.75, 0.75, -0.75, 0.75)
    # pixel (row i, col j) has its centre at x = -0.75 + (j + .5) * 0.01, y = 0.75 - (i + .5) * 0.01
    i, j = rng.integers(0, 150, 200), rng.integers(0, 150, 200)
    xy = np.column_stack([-0.75 + (j + 0.5) * 0.01, 0.75 - (i + 0.5) * 0.01])
    d = np.linalg.norm(xy[:, None] - centres[None], axis=2)
    np.testing.assert_array_equal(labels[i, j], d.argmin(1))
    assert set(np.unique(labels)) <= set(range(15))
    # the top-left pixel is the cell of the centre nearest to the top-left corner
    assert labels[0, 0] == cKDTree(centres).query([-0.745, 0.745])[1]


def test_arrow_directions_follow_the_action_order():
    up, down, left, right, ul, ur, dl, dr = ARROW_DIRECTIONS
    np.testing.assert_allclose(up, [0, 1])  # UP = +y
    np.testing.assert_allclose(down, [0, -1])
    np.testing.assert_allclose(left, [-1, 0])
    np.testing.assert_allclose(right, [1, 0])
    np.testing.assert_allclose(ul, np.array([-1, 1]) / np.sqrt(2))
    np.testing.assert_allclose(ur, np.array([1, 1]) / np.sqrt(2))
    np.testing.assert_allclose(dl, np.array([-1, -1]) / np.sqrt(2))
    np.testing.assert_allclose(dr, np.array([1, -1]) / np.sqrt(2))
    np.testing.assert_allclose(np.linalg.norm(ARROW_DIRECTIONS, axis=1), 1.0)


def test_heat_map_colours_cells_by_max_q_and_draws_the_background():
    import types

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from simlab.training.heatmap import HeatmapScene, plot_q_heatmap

    centres = np.array([[-0.5, -0.5], [0.5, -0.5], [0.0, 0.5]])
    Q = np.zeros((3, 16))
    Q[0, 3] = 2.0  # RIGHT, slow
    Q[1, 8] = 5.0  # UP, fast
    occupancy = types.SimpleNamespace(occupancy=np.zeros((40, 40), np.int8), resolution=0.05,
                                      origin=(-1.0, -1.0, 0.0))  # fmt: skip
    fig, ax = plt.subplots()
    scene = HeatmapScene(centres, (-1, -1, 1, 1), background=occupancy, resolution=0.02)
    img = plot_q_heatmap(ax, scene, Q, np.array([False, True, False]))
    labels, _ = rasterize_cells(centres, (-1, -1, 1, 1), 0.02)
    np.testing.assert_array_equal(img.get_array(), Q.max(1)[labels])
    assert ax.images[0].get_extent() == [-1.0, 1.0, -1.0, 1.0]  # the map, under the cells
    from matplotlib.quiver import Quiver

    (quiver,) = [c for c in ax.collections if isinstance(c, Quiver)]
    # arrows only where something was learned (state 2 has a constant row)
    np.testing.assert_allclose(quiver.get_offsets(), centres[:2])
    assert quiver.U[0] > 0 and quiver.V[0] == 0  # RIGHT
    assert quiver.U[1] == 0 and quiver.V[1] > quiver.U[0]  # UP, fast arrow is longer
    plt.close(fig)


def test_agents_fit_a_gymnasium_env(arena_mdp):
    from simlab.agents import make_agent
    from simlab.envs.empirical_mdp import EmpiricalMDPEnv
    from simlab.training.harness import EpisodeTask, evaluate_q

    env = EmpiricalMDPEnv(arena_mdp, "g5")
    env.reset(seed=0)
    agent = make_agent("vi-softmax", 41, 16, np.random.default_rng(0))
    rewards = agent.fit(env, 60)
    assert rewards.shape == (60,)
    optimum = evaluate_q(EpisodeTask(arena_mdp.T, arena_mdp.goal_reward("g5"), horizon=50),
                         agent.Q[None], 0.9)
    assert rewards[-20:].mean() > 0.8 * optimum.optimal_return > rewards[:3].mean()


def test_train_heat_maps_over_an_arena_and_a_map_server_map(small_mdp_file, tmp_path):
    from discretize.gridmap import OccupancyMap
    from discretize.mapio import write_map

    occ = np.zeros((80, 80), dtype=np.int8)
    occ[:, :2] = 100  # a wall on the left
    yaml_path, _ = write_map(tmp_path / "map.yaml", OccupancyMap(occ, 0.02, (-0.05, -0.05, 0.0)))
    s = train(small_mdp_file, "rmax", "g1", episodes=5, runs=1, out=tmp_path / "o",
              bounds=(0.0, 0.0, 1.5, 1.5), occupancy_map=yaml_path, progress=False)  # fmt: skip
    assert (tmp_path / "o" / "heatmap_g1.png").stat().st_size > 1000
    assert s.files["heatmaps"].endswith("heatmaps.png")
    with pytest.raises(ConfigError, match=r"bounds: expected x_min y_min x_max y_max"):
        train(small_mdp_file, "rmax", "g1", episodes=5, runs=1, bounds=(0, 0, -1, 1),
              progress=False)  # fmt: skip
    b = train(small_mdp_file, "rmax", "g1", episodes=5, runs=1, out=tmp_path / "a",
              arena="table", progress=False)  # fmt: skip
    assert b.out == tmp_path / "a"


def test_heat_map_arrows_follow_the_action_set_and_skip_masked_actions():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.quiver import Quiver

    from simlab.base.actions import parse_action_set
    from simlab.training.heatmap import HeatmapScene, plot_q_heatmap

    ccw = parse_action_set(8, "ccw-east")
    centres = np.array([[-0.5, -0.5], [0.5, -0.5], [0.0, 0.5]])
    Q = np.zeros((3, 8))
    Q[0, 0] = 2.0  # ccw-east 0 = East
    Q[1, 2] = 3.0  # ccw-east 2 = North
    Q[2, 4] = 9.0  # West, but masked: the best valid action is South (6)
    Q[2, 6] = 1.0
    valid = np.ones((3, 8), dtype=bool)
    valid[2, 4] = False
    fig, ax = plt.subplots()
    img = plot_q_heatmap(ax, HeatmapScene(centres, (-1, -1, 1, 1), action_set=ccw,
                                          valid=valid, resolution=0.02), Q)
    labels, _ = rasterize_cells(centres, (-1, -1, 1, 1), 0.02)
    np.testing.assert_array_equal(img.get_array(), np.array([2.0, 3.0, 1.0])[labels])
    (quiver,) = [c for c in ax.collections if isinstance(c, Quiver)]
    assert quiver.U[0] > 0 and quiver.V[0] == 0  # East
    assert quiver.U[1] == 0 and quiver.V[1] > 0  # North
    assert quiver.U[2] == 0 and quiver.V[2] < 0  # South, not the masked West
    plt.close(fig)
    # 8 actions without an action set: directions unknown, no arrows (not simlab's order).
    fig, ax = plt.subplots()
    plot_q_heatmap(ax, HeatmapScene(centres, (-1, -1, 1, 1), resolution=0.05), Q)
    assert not [c for c in ax.collections if isinstance(c, Quiver)]
    with pytest.raises(ConfigError, match="action set"):
        plot_q_heatmap(ax, HeatmapScene(centres, action_set=ccw), np.zeros((3, 16)))
    plt.close(fig)


def test_train_cli_goal_states_start_states_and_task(small_mdp_file, tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["train", "--mdp", str(small_mdp_file), "--goal-states", "3,4",
                 "--start-states", "0,1", "--episodes", "20", "--runs", "1", "--out", str(out),
                 "--no-plots", "--no-progress"]) == 0
    Q, meta = load_q_table(out / "q_s3_4.npz")
    assert Q.shape == (12, 16)
    assert meta["goal"] == "s3+4" and meta["task"] == {
        "mode": "per-step", "goal_states": [3, 4], "start_states": [0, 1]}
    assert meta["action_set"]["n_actions"] == 16 and meta["unvisited"] == "mask"
    with np.load(out / "q_s3_4.npz", allow_pickle=False) as q:
        assert np.flatnonzero(q["goal_mask"]).tolist() == [3, 4]
    # Bad state ids, goal names together with goal states, start and start states.
    assert main(["train", "--mdp", str(small_mdp_file), "--goal-states", "99", "--out",
                 str(tmp_path / "b"), "--no-progress"]) == 2
    assert main(["train", "--mdp", str(small_mdp_file), "--goal-states", "3", "--goals", "g1",
                 "--out", str(tmp_path / "c"), "--no-progress"]) == 2
    assert main(["train", "--mdp", str(small_mdp_file), "--goal-states", "3", "--start", "0",
                 "--start-states", "1", "--out", str(tmp_path / "d"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "goal_states" in err and "start_states" in err
    assert not any((tmp_path / n).exists() for n in "bcd")
