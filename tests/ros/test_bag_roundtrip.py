"""A bag says what a ROS tool expects and gives the dataset back: export then import is
the identity, column for column; latched topics are transient-local; too-close beams are
-inf (REP-117); the odometry twist and covariance follow the motion; the scene markers
draw the Voronoi cells."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags")

from discretize.voronoi import Discretizer
from simlab.cli import main
from simlab.data.dataset import open_dataset, read_dataset
from simlab.ros.bag import (
    BagTrajectory,
    odometry_covariance,
    odometry_twist,
    read_bag,
    read_metadata,
    write_bag,
)
from simlab.ros.markers import voronoi_cells


def _lattice() -> Discretizer:
    g = np.linspace(-0.6, 0.6, 5)
    return Discretizer(centres=np.array([(x, y) for y in g[::-1] for x in g]))


@pytest.fixture(scope="module")
def walks(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Kinematic walks on the table (3 s decision latency, some blocked moves), with the
    truth and with wheel odometry as the pose source; a short physics walk localized by
    the particle filter (mcl)."""
    from simlab.data.collect import collect

    root = tmp_path_factory.mktemp("walks")
    _lattice().save(root / "states.json")
    out = {"states": root / "states.json"}
    for source in ("truth", "odometry"):
        collect(arena="table", states=root / "states.json", out=root / source,
                transitions=120, seed=4, part_size=50, simulator="kinematic",
                progress=False, pose_source=source)
        out[source] = root / source
    collect(arena="table", states=root / "states.json", out=root / "mcl", transitions=16,
            seed=4, part_size=50, progress=False, pose_source="mcl")
    out["mcl"] = root / "mcl"
    collect(arena="table", states=root / "states.json", out=root / "two", transitions=255,
            seed=4, part_size=50, simulator="kinematic", progress=False, workers=2)
    out["two"] = root / "two"
    return out


def _assert_same_columns(a, b) -> None:
    """Column for column: exact, but for times (whole nanoseconds in a bag) and yaws
    (through a quaternion)."""
    assert a.column_names == b.column_names and a.num_rows == b.num_rows
    for name in a.column_names:
        x, y = a.column(name).to_pylist(), b.column(name).to_pylist()
        if name in ("t", "duration"):
            np.testing.assert_allclose(y, x, rtol=0, atol=1e-9, err_msg=name)
        elif name.startswith("yaw"):
            d = (np.asarray(y) - np.asarray(x) + np.pi) % (2 * np.pi) - np.pi
            assert np.abs(d).max() < 1e-12, name
        else:
            assert y == x, name


def test_a_two_worker_dataset_comes_back_whole_and_exports_again(walks, tmp_path: Path,
                                                                 capsys) -> None:
    ds = walks["two"]
    a = read_dataset(ds)
    workers = a.column("worker").to_numpy()
    assert a.num_rows == 255 and (workers == 0).sum() == 128 and (workers == 1).sum() == 127
    assert main(["export-bag", str(ds), "--out", str(tmp_path / "bag"), "--no-scans"]) == 0
    assert main(["import-bag", str(tmp_path / "bag"), "--states", str(walks["states"]),
                 "--out", str(tmp_path / "back")]) == 0
    _assert_same_columns(a, read_dataset(tmp_path / "back"))
    assert open_dataset(tmp_path / "back").manifest["workers"] == 2
    # the imported dataset knows its arena: exported again without --arena, then imported
    assert main(["export-bag", str(tmp_path / "back"), "--out", str(tmp_path / "bag2"),
                 "--no-scans"]) == 0
    assert main(["import-bag", str(tmp_path / "bag2"), "--states", str(walks["states"]),
                 "--out", str(tmp_path / "back2")]) == 0
    _assert_same_columns(a, read_dataset(tmp_path / "back2"))
    # one worker on request: worker 1's walk, as the one walk of the bag
    assert main(["export-bag", str(ds), "--worker", "1", "--out", str(tmp_path / "bag1"),
                 "--no-scans"]) == 0
    assert main(["import-bag", str(tmp_path / "bag1"), "--states", str(walks["states"]),
                 "--out", str(tmp_path / "one")]) == 0
    one = read_dataset(tmp_path / "one")
    mine = a.filter(a.column("worker").to_numpy() == 1)
    assert one.num_rows == 127
    # worker 1 stays worker 1 (with its own steps and parts), column for column
    assert set(one.column("worker").to_pylist()) == {1}
    _assert_same_columns(mine, one)
    assert open_dataset(tmp_path / "one").manifest["workers"] == 2


def test_walks_laid_end_to_end_restart_the_odometry_at_rest(walks, tmp_path: Path) -> None:
    from simlab.ros.export import export_bag

    export_bag(walks["two"], tmp_path / "bag", scans=False)
    info = read_metadata(tmp_path / "bag")
    offsets = [w["offset"] for w in json.loads(info["custom_data"]["simlab.walks"])]
    assert offsets[0] == 0.0 and offsets[1] == int(offsets[1])  # whole seconds
    back = read_bag(tmp_path / "bag", action_topic=None)
    first = int(np.searchsorted(back.t, offsets[1]))
    assert back.t[first - 1] + 1.0 <= back.t[first]  # a gap of at least a second
    # the second walk starts from rest: no velocity across the jump between the walks
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    with Reader(tmp_path / "bag") as r:
        odom = [ts.deserialize_cdr(raw, c.msgtype) for c, _, raw in
                r.messages(connections=[c for c in r.connections if c.topic == "/odom"])]
    twist = odom[first].twist
    assert twist.twist.linear.x == 0.0 and twist.twist.angular.z == 0.0
    assert not np.any(twist.covariance) and not np.any(odom[first].pose.covariance)


@pytest.mark.parametrize("source", ["truth", "odometry", "mcl"])
def test_export_then_import_gives_the_dataset_back_column_for_column(
        source: str, walks: dict[str, Path], tmp_path: Path, capsys) -> None:
    ds = walks[source]
    assert main(["export-bag", str(ds), "--out", str(tmp_path / "bag"), "--no-scans"]) == 0
    # no --n-actions/--convention: the bag records its action set
    assert main(["import-bag", str(tmp_path / "bag"), "--states", str(walks["states"]),
                 "--out", str(tmp_path / "back")]) == 0
    a, b = read_dataset(ds), read_dataset(tmp_path / "back")
    assert a.column_names == b.column_names and a.num_rows == b.num_rows
    if source != "mcl":
        assert a.num_rows == 120
        blocked = a.column("blocked").to_numpy()
        assert 0 < blocked.sum() < 120  # the walk has blocked moves and free ones
    else:  # the estimate is not the truth: both must come back, each in its columns
        assert not np.allclose(a.column("x").to_numpy(), a.column("x_true").to_numpy())
    t, dur = a.column("t").to_numpy(), a.column("duration").to_numpy()
    assert np.all(t[1:] - (t[:-1] + dur[:-1]) > 1.0)  # a decision latency between moves
    for name in a.column_names:
        x, y = a.column(name).to_pylist(), b.column(name).to_pylist()
        if name in ("t", "duration"):  # bag stamps are whole nanoseconds
            np.testing.assert_allclose(y, x, rtol=0, atol=1e-9, err_msg=name)
        elif name.startswith("yaw"):  # through a quaternion
            d = (np.asarray(y) - np.asarray(x) + np.pi) % (2 * np.pi) - np.pi
            assert np.abs(d).max() < 1e-12, name
        else:
            assert y == x, name
    assert open_dataset(tmp_path / "back").action_set == open_dataset(ds).action_set


def test_a_given_action_set_that_contradicts_the_bags_is_refused(walks, tmp_path: Path,
                                                                  capsys) -> None:
    assert main(["export-bag", str(walks["truth"]), "--out", str(tmp_path / "bag"),
                 "--no-scans"]) == 0
    capsys.readouterr()
    code = main(["import-bag", str(tmp_path / "bag"), "--states", str(walks["states"]),
                 "--out", str(tmp_path / "x"), "--n-actions", "8"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "records its actions as 16 actions" in err and "leave out --n-actions" in err
    assert not (tmp_path / "x").exists()


def test_latched_topics_are_transient_local_and_the_rest_volatile(walks, tmp_path: Path
                                                                   ) -> None:
    from simlab.ros.export import export_bag

    export_bag(walks["truth"], tmp_path / "bag", scans=False, start_time=1.7e9)
    info = read_metadata(tmp_path / "bag")
    qos = {e["topic_metadata"]["name"]: e["topic_metadata"]["offered_qos_profiles"]
           for e in info["topics_with_message_count"]}
    for topic in ("/tf_static", "/map", "/simlab/cells", "/simlab/goals",
                  "/robot_description"):
        (profile,) = qos[topic]
        assert profile["durability"] == "transient_local", topic
        assert profile["reliability"] == "reliable" and profile["depth"] == 1
    assert qos["/tf"] == qos["/odom"] == []  # recorder default: volatile
    # the start time: stamps from 1.7e9 s, times read back from the recorded origin
    assert info["starting_time"]["nanoseconds_since_epoch"] == 1_700_000_000 * 10**9
    back = read_bag(tmp_path / "bag")
    t = read_dataset(walks["truth"]).column("t").to_numpy()
    np.testing.assert_allclose(back.action_t, t, atol=1e-6)


def test_beams_nearer_than_range_min_are_minus_inf(tmp_path: Path) -> None:
    """The table's east wall is at x = 0.75 (inner face): a robot at x = 0.68 facing east
    has its LIDAR (0.032 m behind the axis) 0.648 m from the centre, about 0.10 m from the
    wall face, so the beams towards it are too close (< range_min = 0.12 m); beams away
    from the wall see far surfaces."""
    from simlab.physics.arena import load_arena
    from simlab.physics.robot import load_robot_spec
    from simlab.ros.export import _scans

    arena = load_arena("table")
    pose = np.array([[0.0, 0.0, 0.0], [0.68, 0.0, 0.0]])
    scans, geom = _scans(arena, pose)
    offset = load_robot_spec().lidar_offset  # in base_footprint, the pose's frame
    assert not np.any(np.isneginf(scans[0]))  # in the middle, nothing is that close
    east = scans[1][[0, 1, 359]]  # beams 0, +-1 deg: straight at the wall
    assert np.all(np.isneginf(east)), east
    west = scans[1][180]
    assert np.isfinite(west) and west > 1.0
    # geometry: a beam at angle a hits the wall plane at d / cos(a); -inf where that is
    # below range_min, +inf never for a wall in range
    lidar_x = 0.68 + offset[0]
    wall = 0.75 - lidar_x
    ang = np.arange(360) * geom.angle_increment
    facing = np.cos(ang) > 0
    expect_close = facing & (wall / np.where(facing, np.cos(ang), 1.0) < geom.range_min)
    got = np.isneginf(scans[1])
    # within a degree of the threshold the other walls' corners may intervene
    margin = facing & (np.abs(wall / np.where(facing, np.cos(ang), 1.0) - geom.range_min)
                       < 0.003)
    assert np.array_equal(got[~margin], expect_close[~margin])
    # written and read back as -inf
    bag = write_bag(tmp_path / "b", BagTrajectory(t=np.array([0.0, 1.0]), pose=pose,
                                                  scans=scans, scan_geometry=geom))
    assert np.array_equal(np.isneginf(read_bag(bag).scans), np.isneginf(scans))


def test_odometry_twist_and_covariance_follow_the_motion() -> None:
    """Hand-worked: a turn of pi/2 in 2 s, then 0.5 m straight north in 2 s, then idle."""
    t = np.array([0.0, 2.0, 4.0, 7.0])
    odom = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, np.pi / 2], [0.0, 0.5, np.pi / 2],
                     [0.0, 0.5, np.pi / 2]])
    tw = odometry_twist(t, odom)
    np.testing.assert_allclose(tw, [[0, 0, 0], [0, 0, np.pi / 4], [0.25, 0, 0], [0, 0, 0]],
                               atol=1e-12)
    pose_cov, twist_cov = odometry_covariance(t, odom)
    a = 0.01  # OdometryMotionParams' alphas
    # the turn: rot1 = 0 (no translation), rot2 = pi/2: var(yaw) = a (pi/2)^2
    assert pose_cov[1][2, 2] == pytest.approx(a * (np.pi / 2) ** 2)
    # ... and var(trans) = a4 (rot1^2 + rot2^2) along the heading at the start (east)
    assert pose_cov[1][0, 0] == pytest.approx(a * (np.pi / 2) ** 2)
    assert pose_cov[1][1, 1] == 0.0
    assert twist_cov[1][2, 2] == pytest.approx(a * (np.pi / 2) ** 2 / 4)
    # the drive north: var(trans) = a3 0.5^2 along y, plus var(rot1) = a2 0.5^2 of the
    # heading; x gains the heading's variance times the lever arm 0.5^2
    assert pose_cov[2][1, 1] == pytest.approx(a * 0.25)
    var_yaw = a * (np.pi / 2) ** 2
    assert pose_cov[2][0, 0] == pytest.approx(a * (np.pi / 2) ** 2 + 0.25 * var_yaw
                                              + 0.25 * a * 0.25)
    assert twist_cov[2][0, 0] == pytest.approx(a * 0.25 / 4)
    # idle: the pose covariance stays, the twist covariance is zero
    np.testing.assert_allclose(pose_cov[3], pose_cov[2])
    assert not twist_cov[3].any()
    # covariances are symmetric positive semi-definite
    for c in pose_cov:
        np.testing.assert_allclose(c, c.T)
        assert np.linalg.eigvalsh(c).min() > -1e-15


def test_voronoi_cells_tile_the_rectangle_and_hold_their_centre() -> None:
    rng = np.random.default_rng(7)
    centres = rng.uniform(-1, 1, (12, 2))
    bounds = (-1.0, -1.0, 1.0, 1.0)
    cells = voronoi_cells(centres, bounds)

    def area(p):
        x, y = p[:, 0], p[:, 1]
        return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))

    assert sum(area(c) for c in cells) == pytest.approx(4.0)
    disc = Discretizer(centres=centres)
    for i, poly in enumerate(cells):
        # every corner is nearest to its own centre (ties on the edges)
        d = np.linalg.norm(poly[:, None, :] - centres[None], axis=2)
        assert np.all(d[:, i] <= d.min(axis=1) + 1e-9)
        assert disc.state_of(poly.mean(axis=0)[None])[0] == i


def test_the_bag_shows_cells_goals_and_a_human(walks, tmp_path: Path) -> None:
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    from simlab.ros.export import export_bag
    from simlab.ros.markers import SceneMarkers

    export_bag(walks["truth"], tmp_path / "bag", scans=False)
    ts = get_typestore(Stores.ROS2_HUMBLE)
    seen: dict[str, list] = {}
    with Reader(tmp_path / "bag") as r:
        for c, _, raw in r.messages():
            if c.topic in ("/simlab/cells", "/simlab/goals"):
                seen[c.topic] = ts.deserialize_cdr(raw, c.msgtype).markers
    cells = [m for m in seen["/simlab/cells"] if m.ns == "cells"]
    labels = [m.text for m in seen["/simlab/cells"] if m.ns == "state_ids"]
    assert len(cells) == 25 and labels == [str(i) for i in range(25)]
    assert all(m.header.frame_id == "map" and len(m.points) >= 4 for m in cells)
    goals = [m.text for m in seen["/simlab/goals"] if m.ns == "goal_names"]
    from simlab.physics.arena import load_arena

    assert goals == list(load_arena("table").goal_names)
    # a human, when the trajectory has one, is drawn at every sample
    human = np.array([[1.0, 0.5, 0.0], [1.0, 0.6, 0.1]])
    write_bag(tmp_path / "h", BagTrajectory(t=np.array([0.0, 1.0]), pose=np.zeros((2, 3)),
                                            human=human, scene=SceneMarkers()))
    with Reader(tmp_path / "h") as r:
        hs = [ts.deserialize_cdr(raw, c.msgtype) for c, _, raw in r.messages()
              if c.topic == "/simlab/human"]
    assert [m.markers[0].pose.position.y for m in hs] == [0.5, 0.6]


def test_exported_frames_match_the_robot_urdf(walks, tmp_path: Path) -> None:
    """The bag's tf tree is map -> odom -> base_footprint -> base_link -> base_scan, and its
    static transforms are the URDF's joints (ROBOTIS's tree: base_footprint the root), so
    robot_state_publisher and the bag agree on every frame."""
    import xml.etree.ElementTree as ET

    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    from simlab.physics.robot import load_robot_spec
    from simlab.ros.export import export_bag

    export_bag(walks["truth"], tmp_path / "bag", scans=False)
    ts = get_typestore(Stores.ROS2_HUMBLE)
    static = {}
    with Reader(tmp_path / "bag") as r:
        for c, _, raw in r.messages():
            if c.topic == "/tf_static":
                for tr in ts.deserialize_cdr(raw, c.msgtype).transforms:
                    v, q = tr.transform.translation, tr.transform.rotation
                    assert (q.x, q.y, q.z, q.w) == (0.0, 0.0, 0.0, 1.0)
                    static[(tr.header.frame_id, tr.child_frame_id)] = (v.x, v.y, v.z)
    joints, fixed = {}, set()
    for joint in ET.parse(load_robot_spec().urdf_path).getroot().findall("joint"):
        key = (joint.find("parent").get("link"), joint.find("child").get("link"))
        origin = joint.find("origin")
        joints[key] = tuple(float(v) for v in origin.get("xyz").split())
        assert origin.get("rpy") in (None, "0 0 0")
        if joint.get("type") == "fixed":
            fixed.add(key)
    # every fixed joint of the URDF: base_link, base_scan, the caster and the IMU
    assert set(static) == fixed and {("base_link", "caster_back_link"),
                                     ("base_link", "imu_link")} <= fixed
    for edge, xyz in static.items():
        assert xyz == pytest.approx(joints[edge], abs=1e-12), edge


def test_the_bag_carries_every_frame_and_the_wheel_joint_states(walks, tmp_path: Path
                                                                 ) -> None:
    """Every link of the URDF has a transform in the bag (robot_state_publisher's whole
    tree), and the wheels' /tf rotations are the /joint_states angles about the wheel axis,
    which follow the motion: the left wheel turns (s - dyaw b/2) / r between samples."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore
    from scipy.spatial.transform import Rotation

    from simlab.physics.robot import load_robot_spec
    from simlab.ros.export import export_bag

    export_bag(walks["truth"], tmp_path / "bag", scans=False)
    ts = get_typestore(Stores.ROS2_HUMBLE)
    children, wheel_tf, states = set(), [], []
    with Reader(tmp_path / "bag") as r:
        for c, _, raw in r.messages():
            msg = ts.deserialize_cdr(raw, c.msgtype)
            if c.topic in ("/tf", "/tf_static"):
                children |= {tr.child_frame_id for tr in msg.transforms}
                wheel_tf += [tr for tr in msg.transforms if tr.child_frame_id.startswith("wheel")]
            elif c.topic == "/joint_states":
                states.append(msg)
    spec = load_robot_spec()
    import xml.etree.ElementTree as ET

    links = {x.get("name") for x in ET.parse(spec.urdf_path).getroot().findall("link")}
    assert links - {"base_footprint"} <= children and "odom" in children
    assert len(states) == len(wheel_tf) // 2 and len(states) > 100
    assert list(states[0].name) == ["wheel_left_joint", "wheel_right_joint"]
    angles = np.array([m.position for m in states])
    for k, tr in enumerate(wheel_tf[:40]):  # left, right, left, ...
        q = tr.transform.rotation
        rotvec = Rotation.from_quat([q.x, q.y, q.z, q.w]).as_rotvec()
        expected = Rotation.from_rotvec([0.0, angles[k // 2, k % 2], 0.0]).as_rotvec()
        np.testing.assert_allclose(rotvec, expected, atol=1e-9)
    # the wheels follow the motion: their difference is the heading change, their sum the
    # distance driven along the heading (turn in place, then drive: thesis primitives)
    back = read_bag(tmp_path / "bag")
    d = np.diff(back.pose, axis=0)
    dyaw = (d[:, 2] + np.pi) % (2 * np.pi) - np.pi
    drive = np.cos(back.pose[1:, 2]) * d[:, 0] + np.sin(back.pose[1:, 2]) * d[:, 1]
    step = np.diff(angles, axis=0)
    r, b = spec.wheel_radius, spec.wheel_separation
    np.testing.assert_allclose((step[:, 1] - step[:, 0]) * r / b, dyaw, atol=1e-9)
    np.testing.assert_allclose((step[:, 1] + step[:, 0]) * r / 2, drive, atol=1e-9)
    assert np.abs(drive).max() > 0.05 and np.abs(dyaw).max() > 0.5  # it drove and turned


def test_wheel_angles_of_a_hand_worked_turn_and_drive() -> None:
    """A quarter turn left in place (2 s), then 0.5 m north (2 s), then a new walk: the left
    wheel turns -pi/2 b/2 / r then +0.5 / r, the right +pi/2 b/2 / r then +0.5 / r."""
    from simlab.ros.frames import wheel_angles

    t = np.array([0.0, 2.0, 4.0, 10.0, 12.0])
    odom = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, np.pi / 2], [0.0, 0.5, np.pi / 2],
                     [1.0, 1.0, 0.0], [1.2, 1.0, 0.0]])
    r, b = 0.033, 0.160
    angles, rates = wheel_angles(t, odom, r, b, walk_starts=np.array([0, 3]))
    turn = np.pi / 2 * b / 2 / r
    np.testing.assert_allclose(angles[:3], [[0, 0], [-turn, turn],
                                            [-turn + 0.5 / r, turn + 0.5 / r]], atol=1e-12)
    np.testing.assert_allclose(rates[1], [-turn / 2, turn / 2], atol=1e-12)
    # the second walk starts at rest from 0, not from the jump between the walks
    np.testing.assert_allclose(angles[3:], [[0, 0], [0.2 / r, 0.2 / r]], atol=1e-12)
    assert not rates[3].any()

def test_a_foreign_bags_decisions_end_with_their_motion_not_at_the_next_action(
        tmp_path: Path) -> None:
    """A robot's bag with an action topic only (no recorded durations), poses at 10 Hz:
    decision 0 turns 1 s (pi/2) then drives 1 s at 0.2 m/s, then waits 3 s; decision 1
    drives 1 s and waits 2 s; decision 2 does nothing (blocked, no turn). Durations are the
    motion's (2 s, 1 s, one sample), not the 5 s and 3 s between the actions."""
    from simlab.ros.importer import import_bag

    t = np.round(np.arange(0, 10.0, 0.1), 6)
    yaw = np.clip(t, 0, 1) * np.pi / 2
    y = 0.2 * np.clip(t - 1, 0, 1) + 0.2 * np.clip(t - 5, 0, 1)
    pose = np.column_stack([np.zeros_like(t), y, yaw])
    bag = write_bag(tmp_path / "b", BagTrajectory(
        t=t, pose=pose, actions=np.array([2, 2, 0]), action_t=np.array([0.0, 5.0, 8.0])))
    centres = np.array([[0.0, 0.0], [0.0, 0.4], [1.0, 0.0]])
    res = import_bag(bag, states=Discretizer(centres=centres), out=tmp_path / "ds",
                     n_actions=8, convention="ccw-east")
    ds = open_dataset(tmp_path / "ds")
    np.testing.assert_allclose(ds.column("duration"), [2.0, 1.0, 0.1], atol=1e-9)
    np.testing.assert_allclose(ds.column("y_next"), [0.2, 0.4, 0.4], atol=1e-9)
    assert ds.column("blocked").tolist() == [False, False, True] and res.blocked == 1


def test_the_bag_carries_the_robot_description_for_rviz(walks, tmp_path: Path) -> None:
    """``/robot_description`` holds the URDF's text once, latched as robot_state_publisher
    publishes it (transient local), so that RViz draws the robot from the bag alone."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    from simlab.ros.export import export_bag

    export_bag(walks["truth"], tmp_path / "bag", scans=False)
    ts = get_typestore(Stores.ROS2_HUMBLE)
    with Reader(tmp_path / "bag") as r:
        conns = [c for c in r.connections if c.topic == "/robot_description"]
        assert [c.msgtype for c in conns] == ["std_msgs/msg/String"]
        texts = [ts.deserialize_cdr(raw, c.msgtype).data for c, _, raw in
                 r.messages(connections=conns)]
    urdf = Path(__file__).resolve().parents[2] / "robots" / "turtlebot3_burger.urdf"
    assert texts == [urdf.read_text(encoding="utf-8")]
    (profile,) = next(e["topic_metadata"]["offered_qos_profiles"]
                      for e in read_metadata(tmp_path / "bag")["topics_with_message_count"]
                      if e["topic_metadata"]["name"] == "/robot_description")
    assert profile["durability"] == "transient_local" and profile["depth"] == 1


def test_yaws_go_through_the_quaternion_bit_for_bit() -> None:
    from simlab.ros.bag import quat_yaws, yaw_quats

    rng = np.random.default_rng(3)
    yaw = np.concatenate([rng.uniform(-np.pi, np.pi, 20000), rng.uniform(-1e-3, 1e-3, 2000),
                          [np.pi, np.nextafter(np.pi, 0), np.nextafter(-np.pi, 0), 0.0]])
    q = yaw_quats(yaw)
    assert np.array_equal(quat_yaws(q), yaw)
    assert np.abs(np.linalg.norm(q, axis=1) - 1).max() < 1e-15  # still a unit quaternion
    assert not np.any(q[:, :2])  # planar
    assert float(quat_yaws(yaw_quats(3 * np.pi + 0.5))) == pytest.approx(0.5 - np.pi)


def test_times_go_through_whole_nanoseconds_exactly_where_they_can() -> None:
    """A whole number of nanoseconds, or a UNIX time (float64 steps of 238 ns there), comes
    back bit for bit; any other time to the nearest nanosecond."""
    from simlab.ros.bag import nanoseconds, seconds

    rng = np.random.default_rng(5)
    whole = np.round(rng.uniform(0, 1e5, 5000), 9)
    unix = 1.5e9 + rng.uniform(0, 1e6, 5000)
    np.testing.assert_array_equal(seconds(nanoseconds(whole)), whole)
    np.testing.assert_array_equal(seconds(nanoseconds(unix)), unix)
    other = rng.uniform(0, 10, 5000)
    assert np.abs(seconds(nanoseconds(other)) - other).max() <= 0.5e-9


def test_a_unix_time_pose_log_with_whole_turns_comes_back_from_a_bag_exactly(
        walks, tmp_path: Path, capsys) -> None:
    """A robot's log stamped in UNIX time with its yaw counting whole turns (6 pi more):
    import-log stores the yaw in (-pi, pi], and export-bag then import-bag give that
    dataset back bit for bit, every column."""
    from tests.data.test_import_log import PLAN, _simulate

    samples, _ = _simulate(PLAN, np.random.default_rng(4))
    samples[:, 0] += 1_500_000_000.0
    samples[:, 1:3] = (samples[:, 1:3] - [1.5, 1.0]) * 0.3  # on the table
    samples[:, 3] = np.unwrap(samples[:, 3]) + 6 * np.pi
    log = tmp_path / "unix.log"
    log.write_text("".join(" ".join(repr(float(v)) for v in row) + "\n" for row in samples))
    states = str(walks["states"])
    assert main(["import-log", str(log), "--states", states, "--out",
                 str(tmp_path / "ds")]) == 0
    a = read_dataset(tmp_path / "ds")
    for name in ("yaw", "yaw_next"):
        yaw = a.column(name).to_numpy()
        assert np.all((yaw > -np.pi) & (yaw <= np.pi)), name
    assert main(["export-bag", str(tmp_path / "ds"), "--out", str(tmp_path / "bag"),
                 "--no-scans", "--arena", "table"]) == 0
    assert main(["import-bag", str(tmp_path / "bag"), "--states", states, "--out",
                 str(tmp_path / "back")]) == 0
    b = read_dataset(tmp_path / "back")
    assert a.column_names == b.column_names and a.num_rows == b.num_rows == len(PLAN) + 1
    for name in a.column_names:
        assert a.column(name).to_pylist() == b.column(name).to_pylist(), name
