"""ROS 2 bags: written then read back exactly; an imported bag equals the pose-log import;
export of a collection; the two CLI commands."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags")

from discretize.gridmap import OccupancyMap
from discretize.voronoi import Discretizer
from simlab.base.actions import parse_action_set
from simlab.base.errors import ConfigError
from simlab.cli import main
from simlab.data.dataset import open_dataset, read_dataset
from simlab.data.poselog import import_log
from simlab.ros.bag import BagTrajectory, read_bag, write_bag
from simlab.ros.importer import import_bag
from tests.data.test_import_log import _simulate as simulate_log
from tests.data.test_import_log import help_blocks

CCW = parse_action_set(8, "ccw-east")
CENTRES = np.array([[x, y] for y in (2.0, 1.0, 0.0) for x in (0.0, 1.0, 2.0, 3.0)])
PLAN = [(0, False), (2, False), (5, True), (5, False), (3, False), (7, True), (1, False),
        (6, False), (4, True), (2, False)]


def _simulate(plan, rng):
    """The import-log tests' synthetic robot (same trace, same noise draws) with ``t`` from 0
    in whole microseconds (exact in bag nanoseconds), and the decision start times (s)."""
    s, truth = simulate_log(plan, rng)
    s[:, 0] = np.round(s[:, 0] - s[0, 0], 6)
    return s, np.asarray([start for start, *_ in truth]) - 0.13  # the log's first sample time


def _traj(samples, **kw) -> BagTrajectory:
    return BagTrajectory(t=samples[:, 0], pose=samples[:, 1:4], **kw)


def test_written_bag_reads_back_poses_scans_map_exactly(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    n = 25
    t = np.cumsum(rng.uniform(0.1, 0.5, n))
    pose = np.column_stack([rng.uniform(-1, 1, (n, 2)), rng.uniform(-3.1, 3.1, n)])
    odom = pose + rng.normal(0, 0.05, (n, 3))
    scans = rng.uniform(0.12, 3.5, (n, 360)).astype(np.float32)
    scans[rng.random((n, 360)) < 0.1] = np.inf
    occ = rng.choice(np.array([-1, 0, 100], dtype=np.int8), (30, 40))
    grid = OccupancyMap(occ, 0.05, (-1.0, -0.75, 0.0))
    traj = BagTrajectory(t=t, pose=pose, odom=odom, scans=scans, state=np.arange(n) % 7,
                         goal=np.array(["NE", "C"] * 12 + ["NE"]), map=grid)
    path = write_bag(tmp_path / "run", traj, t0=1.7e9)
    assert (path / "metadata.yaml").is_file() and list(path.glob("*.mcap"))
    back = read_bag(path)
    np.testing.assert_allclose(back.t, t, atol=1e-6)  # ns stamps at 1.7e9 s, origin recorded
    np.testing.assert_allclose(back.pose[:, :2], pose[:, :2], rtol=0, atol=1e-12)
    dyaw = (back.pose[:, 2] - pose[:, 2] + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(dyaw).max() < 1e-12
    np.testing.assert_allclose(back.odom[:, :2], odom[:, :2], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(back.scans, scans)  # float32 exactly, inf kept
    np.testing.assert_array_equal(back.map.occupancy, occ)
    assert back.map.resolution == pytest.approx(0.05) and back.map.origin == (-1.0, -0.75, 0.0)
    assert back.state.tolist() == (np.arange(n) % 7).tolist()
    assert back.goal.tolist() == traj.goal.tolist()
    assert back.scan_geometry.range_max == pytest.approx(3.5)
    # the pose through /odom instead of /amcl_pose
    np.testing.assert_allclose(read_bag(path, pose_topic="/odom").pose[:, :2], odom[:, :2],
                               atol=1e-12)
    with pytest.raises(ConfigError, match="already exists"):
        write_bag(path, traj)
    assert [p.name for p in tmp_path.iterdir()] == ["run"]  # no temporary left behind


def test_tf_tree_is_map_odom_base_footprint_base_link_base_scan(tmp_path: Path) -> None:
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    pose = np.array([[0.5, 0.2, 0.3], [0.6, 0.2, 0.3]])
    odom = np.array([[0.4, 0.0, 0.1], [0.5, 0.0, 0.1]])
    path = write_bag(tmp_path / "tf", BagTrajectory(t=np.array([0.0, 0.5]), pose=pose,
                                                     odom=odom))
    edges, map_odom = set(), None
    with Reader(path) as r:
        for c, _, raw in r.messages():
            if c.topic in ("/tf", "/tf_static"):
                for tr in ts.deserialize_cdr(raw, c.msgtype).transforms:
                    edges.add((tr.header.frame_id, tr.child_frame_id))
                    if tr.child_frame_id == "odom":
                        map_odom = tr.transform
    assert edges == {("map", "odom"), ("odom", "base_footprint"),
                     ("base_footprint", "base_link"), ("base_link", "base_scan")}
    # map -> odom composed with odom -> base gives the map pose
    from simlab.ros.bag import compose, yaw_of

    mo = np.array([map_odom.translation.x, map_odom.translation.y, yaw_of(map_odom.rotation)])
    np.testing.assert_allclose(compose(mo, odom[1]), pose[1], atol=1e-12)


def _centres_file(path: Path) -> Path:
    path.write_text("".join(f"{x} {y}\n" for x, y in CENTRES))
    return path


def test_imported_bag_equals_the_pose_log_import(tmp_path: Path) -> None:
    samples, _ = _simulate(PLAN, np.random.default_rng(4))
    log = tmp_path / "run.log"
    log.write_text("".join(" ".join(repr(float(v)) for v in row) + "\n" for row in samples))
    states = _centres_file(tmp_path / "centres.txt")
    import_log(log, states=states, out=tmp_path / "from_log")
    bag = write_bag(tmp_path / "run_bag", _traj(samples), t0=1000.0)
    res = import_bag(bag, states=states, out=tmp_path / "from_bag")
    assert res.action_source.startswith("segmentation")
    a, b = read_dataset(tmp_path / "from_log"), read_dataset(tmp_path / "from_bag")
    assert a.num_rows == b.num_rows == len(PLAN)
    assert a.column_names == b.column_names
    for name in a.column_names:
        x, y = a.column(name).to_numpy(), b.column(name).to_numpy()
        if x.dtype.kind == "f":
            np.testing.assert_allclose(y, x, rtol=0, atol=1e-6, err_msg=name)
        else:
            np.testing.assert_array_equal(y, x, err_msg=name)
    assert b.column("a").to_pylist() == [p[0] for p in PLAN]


def test_action_topic_gives_the_decisions(tmp_path: Path) -> None:
    samples, starts = _simulate(PLAN, np.random.default_rng(5))
    actions = np.array([p[0] for p in PLAN])
    bag = write_bag(tmp_path / "b", _traj(samples, actions=actions, action_t=starts))
    res = import_bag(bag, states=Discretizer(centres=CENTRES), out=tmp_path / "ds")
    assert res.action_source == "action topic /simlab/action" and res.decisions == len(PLAN)
    ds = open_dataset(tmp_path / "ds")
    assert ds.column("a").tolist() == actions.tolist()
    assert ds.column("blocked").tolist() == [p[1] for p in PLAN]


def test_export_bag_of_a_collection_and_import_cli(tmp_path: Path, capsys) -> None:
    from discretize.voronoi import Discretizer as D
    from simlab.data.collect import collect

    g = np.linspace(-0.6, 0.6, 5)
    disc = D(centres=np.array([(x, y) for y in g[::-1] for x in g]))
    states = tmp_path / "states.json"
    disc.save(states)
    collect(arena="table", states=disc, out=tmp_path / "walk", transitions=30, seed=1,
            part_size=30, simulator="kinematic", progress=False)
    assert main(["export-bag", str(tmp_path / "walk"), "--out", str(tmp_path / "bag")]) == 0
    assert "pose samples of the dataset" in capsys.readouterr().out
    back = read_bag(tmp_path / "bag")
    walk = read_dataset(tmp_path / "walk")
    np.testing.assert_allclose(back.pose[0], [walk.column(c)[0].as_py()
                                              for c in ("x", "y", "yaw")], atol=1e-12)
    assert back.actions.tolist() == walk.column("a").to_pylist()
    assert back.state[0] == walk.column("s")[0].as_py()
    assert back.scans.shape == (len(back.t), 360) and back.map.occupancy.max() == 100
    # a wall is about 0.75 m from the centre: the cast scan sees it
    assert np.isfinite(back.scans).mean() > 0.9
    assert main(["import-bag", str(tmp_path / "bag"), "--states", str(states), "--out",
                 str(tmp_path / "again"), "--n-actions", "16", "--convention",
                 "simlab"]) == 0
    again = read_dataset(tmp_path / "again")
    assert again.column("a").to_pylist() == walk.column("a").to_pylist()
    code = main(["import-bag", str(tmp_path / "nowhere"), "--states", str(states),
                 "--out", str(tmp_path / "x")])
    assert code == 2 and capsys.readouterr().err.count("\n") == 1


def _replay_dir(path: Path) -> Path:
    """A replay directory of 4 transitions along +x (goals C, C, NE, NE) in the table."""
    import json

    import pyarrow as pa
    import pyarrow.parquet as pq

    path.mkdir()
    (path / "replay.json").write_text(json.dumps({"arena": "table"}))
    n = 4
    xs = np.array([0.0, 0.1, 0.2, 0.3, 0.4])
    cols = {"t": np.arange(n) * 2.0, "duration": np.full(n, 1.0), "s": np.arange(n),
            "a": np.array([3, 3, 11, 3]), "s_next": np.arange(1, n + 1),
            "goal": ["C", "C", "NE", "NE"], "reward": np.zeros(n, dtype=np.int64),
            "blocked": np.zeros(n, dtype=bool)}
    for axis, before, after in (("x", xs[:-1], xs[1:]), ("y", np.zeros(n), np.zeros(n)),
                                ("yaw", np.zeros(n), np.zeros(n))):
        cols[f"{axis}_true"], cols[f"{axis}_true_next"] = before, after
    pq.write_table(pa.table(cols), path / "transitions.parquet")
    return path


def test_export_bag_of_a_replay_carries_goals_and_states(tmp_path: Path) -> None:
    from simlab.ros.export import export_bag

    run = _replay_dir(tmp_path / "replay")
    n = 4
    res = export_bag(run, tmp_path / "bag", scans=False)
    assert res.source == "replay" and res.samples == 2 * n
    back = read_bag(tmp_path / "bag")
    np.testing.assert_allclose(back.t, [0, 1, 2, 3, 4, 5, 6, 7], atol=1e-9)
    np.testing.assert_allclose(back.pose[:, 0], [0, .1, .1, .2, .2, .3, .3, .4], atol=1e-12)
    assert back.state.tolist() == [0, 1, 1, 2, 2, 3, 3, 4]
    assert back.goal.tolist() == ["C"] * 4 + ["NE"] * 4
    assert back.scans is None and back.actions.tolist() == [3, 3, 11, 3]


# ------------------------------------------- options (ImportBagConfig, ExportBagConfig)
def _toml(path: Path, **values: object) -> Path:
    path.write_text("".join(f"{k} = {json.dumps(v)}\n" for k, v in values.items()))
    return path


def _help(command: str, capsys, monkeypatch) -> dict[str, str]:
    monkeypatch.setenv("COLUMNS", "200")  # one option per line: no wrapped defaults
    with pytest.raises(SystemExit) as exit_:
        main([command, "--help"])
    assert exit_.value.code == 0
    return help_blocks(capsys.readouterr().out)


def test_import_bag_config_file_and_command_line(tmp_path: Path, capsys) -> None:
    samples, starts = _simulate(PLAN, np.random.default_rng(5))
    bag = write_bag(tmp_path / "b", _traj(samples, actions=np.array([p[0] for p in PLAN]),
                                          action_t=starts))
    out = tmp_path / "ds"
    toml = _toml(tmp_path / "import.toml", states=str(_centres_file(tmp_path / "c.txt")),
                 out=str(out), segment=True, convention="simlab")
    assert main(["import-bag", str(bag), "--config", str(toml), "--convention",
                 "ccw-east"]) == 0
    # the file's --segment: the poses are segmented although the bag has an action topic
    assert "actions from the segmentation of the pose" in capsys.readouterr().out
    ds = open_dataset(out)
    assert ds.action_set == CCW  # the command line's convention
    assert ds.column("a").tolist() == [p[0] for p in PLAN]


def test_import_bag_help_shows_the_defaults_and_shares_import_logs_groups(
        capsys, monkeypatch) -> None:
    bag = _help("import-bag", capsys, monkeypatch)
    log = _help("import-log", capsys, monkeypatch)
    assert "(default /simlab/action)" in bag["--action-topic"]
    assert "(default 0.04)" in bag["--move-speed"]
    assert "the bag's recorded action set, else 8" in bag["--n-actions"]
    assert {"--pose-topic", "--segment", "--overwrite", "--config"} <= set(bag)
    shared = ("--move-speed", "--turn-rate", "--join-gap", "--speed-split")
    assert [bag[f] for f in shared] == [log[f] for f in shared]  # one spelling


def test_import_bag_unknown_config_key_names_the_file_and_the_key(tmp_path: Path,
                                                                  capsys) -> None:
    toml = _toml(tmp_path / "import.toml", states=str(_centres_file(tmp_path / "c.txt")),
                 out=str(tmp_path / "ds"), **{"action-topik": "/a"})
    code = main(["import-bag", str(tmp_path / "b"), "--config", str(toml)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert str(toml) in err and "action-topik: unknown option" in err
    assert not (tmp_path / "ds").exists()


def test_import_bag_takes_the_config_or_its_fields(tmp_path: Path) -> None:
    from simlab.ros.importer import ImportBagConfig

    samples, starts = _simulate(PLAN, np.random.default_rng(6))
    actions = np.array([(p[0] + 1) % 8 for p in PLAN])  # not what the robot did
    bag = write_bag(tmp_path / "b", _traj(samples, actions=actions, action_t=starts))
    states = Discretizer(centres=CENTRES)
    by_config = import_bag(ImportBagConfig(bag=bag, states=states, out=tmp_path / "a",
                                           segment=True, move_speed=0.05))
    by_fields = import_bag(str(bag), states=states, out=tmp_path / "b2", action_topic=None,
                           move_speed=0.05)
    assert by_config == dataclasses.replace(by_fields, out=by_config.out)
    assert by_config.action_source.startswith("segmentation")
    a, b = read_dataset(tmp_path / "a"), read_dataset(tmp_path / "b2")
    assert a.equals(b) and a.column("a").to_pylist() == [p[0] for p in PLAN]
    topic = import_bag(bag, states=states, out=tmp_path / "t")
    assert read_dataset(tmp_path / "t").column("a").to_pylist() == actions.tolist()
    assert topic.action_source == "action topic /simlab/action"


def test_export_bag_config_file_and_command_line(tmp_path: Path, capsys) -> None:
    run = _replay_dir(tmp_path / "replay")
    toml = _toml(tmp_path / "export.toml", out=str(tmp_path / "bag"), scans=False,
                 resolution=0.05)
    assert main(["export-bag", str(run), "--config", str(toml), "--resolution", "0.1"]) == 0
    assert "8 pose samples of the replay" in capsys.readouterr().out
    back = read_bag(tmp_path / "bag")
    assert back.scans is None  # the file's scans = false
    assert back.map.resolution == pytest.approx(0.1)  # the command line's


def test_export_bag_help_shows_the_defaults(capsys, monkeypatch) -> None:
    blocks = _help("export-bag", capsys, monkeypatch)
    assert "(default 0.02)" in blocks["--resolution"]
    assert "(default: every worker's" in blocks["--worker"]
    assert {"--out", "--arena", "--map", "--no-scans", "--overwrite", "--config"} <= set(blocks)


def test_export_bag_unknown_config_key_names_the_file_and_the_key(tmp_path: Path,
                                                                  capsys) -> None:
    run = _replay_dir(tmp_path / "replay")
    toml = _toml(tmp_path / "export.toml", out=str(tmp_path / "bag"), scan=False)
    code = main(["export-bag", str(run), "--config", str(toml)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert str(toml) in err and "scan: unknown option" in err and "scans" in err
    assert not (tmp_path / "bag").exists()


def test_export_bag_takes_the_config_or_its_fields(tmp_path: Path) -> None:
    from simlab.ros.export import ExportBagConfig, export_bag

    run = _replay_dir(tmp_path / "replay")
    by_config = export_bag(ExportBagConfig(source=run, out=tmp_path / "a", scans=False,
                                           resolution=0.05))
    by_fields = export_bag(str(run), tmp_path / "b", scans=False, resolution=0.05)
    assert (by_config.samples, by_config.source) == (by_fields.samples, by_fields.source)
    a, b = read_bag(tmp_path / "a"), read_bag(tmp_path / "b")
    np.testing.assert_array_equal(a.pose, b.pose)
    np.testing.assert_array_equal(a.map.occupancy, b.map.occupancy)
    assert a.map.resolution == b.map.resolution == pytest.approx(0.05)
    for bad in ({"resolution": 0.0}, {"worker": -1}):
        with pytest.raises(ConfigError, match=next(iter(bad))):
            export_bag(run, tmp_path / "c", **bad)
    assert not (tmp_path / "c").exists()
