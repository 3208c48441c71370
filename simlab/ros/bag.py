"""A trajectory as a ROS 2 bag (MCAP storage) and back, with ``rosbags`` (no ROS install).

Topics and frames (REP-105 / REP-117, as the TurtleBot3 stack publishes them; every
stamp is ``t0 + t`` with ``t`` the trajectory's seconds):

=====================  ====================================  ===============================
topic                  type                                  content
=====================  ====================================  ===============================
``/tf_static``         ``tf2_msgs/msg/TFMessage``            ``base_footprint -> base_link``
                                                             (identity: simlab's base_link
                                                             origin is on the floor) and
                                                             ``base_link -> base_scan``
                                                             (the URDF's LIDAR offset), once
``/tf``                ``tf2_msgs/msg/TFMessage``            ``map -> odom`` (= pose * odom
                                                             ^-1) and ``odom ->
                                                             base_footprint`` per sample
``/odom``              ``nav_msgs/msg/Odometry``             odometry pose (frame ``odom``)
``/amcl_pose``         ``geometry_msgs/msg/                  map-frame pose (the pose a
                       PoseWithCovarianceStamped``           localizer publishes)
``/scan``              ``sensor_msgs/msg/LaserScan``         float32 ranges, ``inf`` = no
                                                             return (frame ``base_scan``)
``/map``               ``nav_msgs/msg/OccupancyGrid``        the map, once (row 0 = bottom)
``/simlab/state``      ``std_msgs/msg/Int32``                Markov state per sample
``/simlab/goal``       ``std_msgs/msg/String``               current goal name per sample
``/simlab/action``     ``std_msgs/msg/Int32``                action index at decision starts
=====================  ====================================  ===============================

Poses are float64 in the messages (exact); yaw goes through a quaternion (exact to ~1e-16
rad); scans are float32 as in ``LaserScan``.
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.errors import ConfigError, DataError

TOPICS = {
    "tf_static": "/tf_static", "tf": "/tf", "odom": "/odom", "amcl_pose": "/amcl_pose",
    "scan": "/scan", "map": "/map", "state": "/simlab/state", "goal": "/simlab/goal",
    "action": "/simlab/action",
}
_TYPES = {
    "/tf_static": "tf2_msgs/msg/TFMessage", "/tf": "tf2_msgs/msg/TFMessage",
    "/odom": "nav_msgs/msg/Odometry", "/amcl_pose": "geometry_msgs/msg/PoseWithCovarianceStamped",
    "/scan": "sensor_msgs/msg/LaserScan", "/map": "nav_msgs/msg/OccupancyGrid",
    "/simlab/state": "std_msgs/msg/Int32", "/simlab/goal": "std_msgs/msg/String",
    "/simlab/action": "std_msgs/msg/Int32",
}


@dataclass(frozen=True)
class ScanGeometry:
    """LaserScan constants: first beam angle and increment (rad), range limits (m), scan
    period (s)."""

    angle_min: float = 0.0
    angle_increment: float = 2 * math.pi / 360
    range_min: float = 0.12
    range_max: float = 3.5
    scan_time: float = 0.2


@dataclass(frozen=True)
class BagTrajectory:
    """What a bag holds, as arrays (n samples).

    ``t`` (n,) float64 seconds, strictly increasing; ``pose`` (n, 3) map-frame (x, y, yaw)
    (m, m, rad); ``odom`` (n, 3) odometry-frame pose (None: equal to ``pose``, map -> odom
    identity); ``scans`` (n, B) float32 metres (None: no /scan); ``state`` (n,) int;
    ``goal`` (n,) str; ``actions`` ``(k,)`` int with ``action_t`` (k,) s (None: no action
    topic); ``map`` an :class:`~discretize.gridmap.OccupancyMap` (None: no /map);
    ``scan_offset`` (x, y, z) m of base_scan in base_link.
    """

    t: NDArray[np.float64]
    pose: NDArray[np.float64]
    odom: NDArray[np.float64] | None = None
    scans: NDArray[np.float32] | None = None
    scan_geometry: ScanGeometry = ScanGeometry()
    state: NDArray[np.int64] | None = None
    goal: NDArray[np.str_] | None = None
    actions: NDArray[np.int64] | None = None
    action_t: NDArray[np.float64] | None = None
    map: Any = None
    scan_offset: tuple[float, float, float] = (-0.032, 0.0, 0.182)


def _rosbags() -> tuple[Any, Any, Any]:
    try:
        from rosbags.rosbag2 import Reader, StoragePlugin, Writer  # noqa: F401
        from rosbags.typesys import Stores, get_typestore
    except ModuleNotFoundError:
        raise ConfigError("ROS 2 bags need the rosbags library", key="rosbags",
                          fix='pip install "simlab[ros]"') from None
    import rosbags.rosbag2 as rb

    return rb, get_typestore(Stores.ROS2_HUMBLE), StoragePlugin


def _quat(yaw: float) -> tuple[float, float, float, float]:
    return 0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)


def yaw_of(q: Any) -> float:
    """Yaw (rad) of a quaternion message (roll and pitch ignored)."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def compose(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """SE(2) composition ``a * b`` of (..., 3) poses."""
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack([a[..., 0] + c * b[..., 0] - s * b[..., 1],
                     a[..., 1] + s * b[..., 0] + c * b[..., 1],
                     np.arctan2(np.sin(a[..., 2] + b[..., 2]), np.cos(a[..., 2] + b[..., 2]))],
                    axis=-1)


def inverse(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """SE(2) inverse of (..., 3) poses."""
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack([-c * a[..., 0] - s * a[..., 1], s * a[..., 0] - c * a[..., 1], -a[..., 2]],
                    axis=-1)


class _Msgs:
    """Message builders bound to one typestore."""

    def __init__(self, ts: Any) -> None:
        self.ts = ts
        t = ts.types
        self.Time, self.Header = t["builtin_interfaces/msg/Time"], t["std_msgs/msg/Header"]
        self.Vec, self.Quat = t["geometry_msgs/msg/Vector3"], t["geometry_msgs/msg/Quaternion"]
        self.Point, self.Pose = t["geometry_msgs/msg/Point"], t["geometry_msgs/msg/Pose"]

    def header(self, ns: int, frame: str) -> Any:
        return self.Header(stamp=self.Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=frame)

    def pose(self, x: float, y: float, yaw: float, z: float = 0.0) -> Any:
        return self.Pose(position=self.Point(x=float(x), y=float(y), z=float(z)),
                         orientation=self.Quat(*_quat(float(yaw))))

    def tf(self, ns: int, parent: str, child: str, x: float, y: float, yaw: float,
           z: float = 0.0) -> Any:
        t = self.ts.types
        return t["geometry_msgs/msg/TransformStamped"](
            header=self.header(ns, parent), child_frame_id=child,
            transform=t["geometry_msgs/msg/Transform"](
                translation=self.Vec(x=float(x), y=float(y), z=float(z)),
                rotation=self.Quat(*_quat(float(yaw)))))

    def tf_message(self, transforms: list[Any]) -> Any:
        return self.ts.types["tf2_msgs/msg/TFMessage"](transforms=transforms)

    def odometry(self, ns: int, pose: NDArray[np.float64]) -> Any:
        t = self.ts.types
        zero = self.Vec(x=0.0, y=0.0, z=0.0)
        return t["nav_msgs/msg/Odometry"](
            header=self.header(ns, "odom"), child_frame_id="base_footprint",
            pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=self.pose(*pose),
                                                          covariance=np.zeros(36)),
            twist=t["geometry_msgs/msg/TwistWithCovariance"](
                twist=t["geometry_msgs/msg/Twist"](linear=zero, angular=zero),
                covariance=np.zeros(36)))

    def amcl(self, ns: int, pose: NDArray[np.float64]) -> Any:
        t = self.ts.types
        return t["geometry_msgs/msg/PoseWithCovarianceStamped"](
            header=self.header(ns, "map"),
            pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=self.pose(*pose),
                                                          covariance=np.zeros(36)))

    def scan(self, ns: int, ranges: NDArray[np.float32], g: ScanGeometry) -> Any:
        n = len(ranges)
        return self.ts.types["sensor_msgs/msg/LaserScan"](
            header=self.header(ns, "base_scan"), angle_min=float(g.angle_min),
            angle_max=float(g.angle_min + g.angle_increment * (n - 1)),
            angle_increment=float(g.angle_increment), time_increment=0.0,
            scan_time=float(g.scan_time), range_min=float(g.range_min),
            range_max=float(g.range_max), ranges=np.asarray(ranges, dtype=np.float32),
            intensities=np.zeros(0, dtype=np.float32))

    def grid(self, ns: int, grid: Any) -> Any:
        t = self.ts.types
        occ = np.asarray(grid.occupancy, dtype=np.int8)[::-1]  # ROS row 0 = bottom
        h, w = occ.shape
        ox, oy, oyaw = grid.origin
        return t["nav_msgs/msg/OccupancyGrid"](
            header=self.header(ns, "map"),
            info=t["nav_msgs/msg/MapMetaData"](
                map_load_time=self.Time(sec=ns // 10**9, nanosec=ns % 10**9),
                resolution=float(grid.resolution), width=w, height=h,
                origin=self.pose(ox, oy, oyaw)),
            data=occ.reshape(-1).copy())


def _check(traj: BagTrajectory) -> int:
    t = np.asarray(traj.t, dtype=np.float64)
    n = len(t)
    if n == 0 or np.any(np.diff(t) <= 0) or t[0] < 0:
        raise ConfigError("sample times must be >= 0 and strictly increasing", key="t")
    for name in ("pose", "odom"):
        a = getattr(traj, name)
        if a is not None and np.shape(a) != (n, 3):
            raise ConfigError(f"expected shape ({n}, 3), got {np.shape(a)}", key=name)
    if traj.scans is not None and (np.ndim(traj.scans) != 2 or len(traj.scans) != n):
        raise ConfigError(f"expected shape ({n}, beams), got {np.shape(traj.scans)}",
                          key="scans")
    return n


def write_bag(path: str | os.PathLike[str], traj: BagTrajectory, *, t0: float = 0.0,
              overwrite: bool = False) -> Path:
    """Write ``traj`` as a ROS 2 bag directory ``path`` (MCAP storage, bag version 9).

    The bag is written under a temporary sibling name and renamed, so a failure leaves no
    partial bag; an existing ``path`` is refused unless ``overwrite``. ``t0`` (s) is added
    to every stamp (ROS time of the first sample).
    """
    rb, ts, plugin = _rosbags()
    _check(traj)
    path = Path(path)
    if path.exists() and not overwrite:
        raise ConfigError("already exists", path=path, fix="choose another --out or pass "
                          "--overwrite")
    m = _Msgs(ts)
    tmp_dir = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    tmp = tmp_dir / path.name
    try:
        with rb.Writer(tmp, version=9, storage_plugin=plugin.MCAP) as w:
            conns = {}

            def put(topic: str, ns: int, msg: Any) -> None:
                if topic not in conns:
                    conns[topic] = w.add_connection(topic, _TYPES[topic], typestore=ts)
                w.write(conns[topic], ns, ts.serialize_cdr(msg, _TYPES[topic]))

            stamps = [round((t0 + float(ti)) * 1e9) for ti in traj.t]
            pose = np.asarray(traj.pose, dtype=np.float64)
            odom = pose if traj.odom is None else np.asarray(traj.odom, dtype=np.float64)
            map_odom = compose(pose, inverse(odom))
            sx, sy, sz = traj.scan_offset
            put("/tf_static", stamps[0], m.tf_message([
                m.tf(stamps[0], "base_footprint", "base_link", 0, 0, 0),
                m.tf(stamps[0], "base_link", "base_scan", sx, sy, 0.0, sz)]))
            if traj.map is not None:
                put("/map", stamps[0], m.grid(stamps[0], traj.map))
            for i, ns in enumerate(stamps):
                put("/tf", ns, m.tf_message([m.tf(ns, "map", "odom", *map_odom[i]),
                                             m.tf(ns, "odom", "base_footprint", *odom[i])]))
                put("/odom", ns, m.odometry(ns, odom[i]))
                put("/amcl_pose", ns, m.amcl(ns, pose[i]))
                if traj.scans is not None:
                    put("/scan", ns, m.scan(ns, traj.scans[i], traj.scan_geometry))
                if traj.state is not None:
                    put("/simlab/state", ns,
                        ts.types["std_msgs/msg/Int32"](data=int(traj.state[i])))
                if traj.goal is not None:
                    put("/simlab/goal", ns, ts.types["std_msgs/msg/String"](data=str(traj.goal[i])))
            if traj.actions is not None:
                for a, ta in zip(traj.actions, traj.action_t, strict=True):
                    put("/simlab/action", round((t0 + float(ta)) * 1e9),
                        ts.types["std_msgs/msg/Int32"](data=int(a)))
        if path.exists():
            shutil.rmtree(path)
        os.replace(tmp, path)
    finally:
        shutil.rmtree(tmp_dir, ignore_errors=True)
    return path


def _stamp_ns(header: Any) -> int:
    return int(header.stamp.sec) * 10**9 + int(header.stamp.nanosec)


def read_bag(path: str | os.PathLike[str], *, pose_topic: str | None = None,
             scan_topic: str | None = "/scan", action_topic: str | None = "/simlab/action",
             t0: float | None = None) -> BagTrajectory:
    """Read a bag (any storage rosbags reads: MCAP or sqlite3) into a :class:`BagTrajectory`.

    The pose comes from ``pose_topic`` (``PoseWithCovarianceStamped``, ``PoseStamped`` or
    ``Odometry``); by default ``/amcl_pose`` when the bag has it, else ``/odom``.
    ``/odom`` fills ``odom`` when it is not the pose topic and has the same stamps. Scans
    are taken when every pose sample has one with the same stamp (exact nanoseconds; else
    ``scans`` is None); the state and goal topics likewise (by bag time). Times are seconds
    since ``t0`` (s; default: the first pose stamp). :class:`DataError` names the bag and topic when the pose is missing.
    """
    rb, ts, _ = _rosbags()
    path = Path(path)
    if not path.exists():
        raise ConfigError("bag not found", path=path)
    topics: dict[str, list[tuple[int, Any]]] = {}
    try:
        with rb.Reader(path) as r:
            names = {c.topic for c in r.connections}
            if pose_topic is None:
                pose_topic = "/amcl_pose" if "/amcl_pose" in names else "/odom"
            if pose_topic not in names:
                raise DataError(f"no pose topic {pose_topic!r} (topics: "
                                f"{', '.join(sorted(names))})", path=path, key="pose_topic")
            wanted = {pose_topic, "/odom", "/map", "/simlab/state", "/simlab/goal",
                      scan_topic, action_topic, "/tf_static"} & names
            conns = [c for c in r.connections if c.topic in wanted]
            for c, ns, raw in r.messages(connections=conns):
                topics.setdefault(c.topic, []).append(
                    (ns, ts.deserialize_cdr(raw, c.msgtype), c.msgtype))
    except rb.ReaderError as exc:
        raise DataError(f"not a readable ROS 2 bag: {exc}", path=path) from None
    return _trajectory(topics, pose_topic, scan_topic, action_topic, t0)


def _pose_of(msg: Any) -> tuple[float, float, float]:
    p = msg.pose.pose if hasattr(msg.pose, "pose") else msg.pose
    return p.position.x, p.position.y, yaw_of(p.orientation)


def _trajectory(topics: dict[str, list[Any]], pose_topic: str, scan_topic: str | None,
                action_topic: str | None, t0: float | None) -> BagTrajectory:
    msgs = sorted(topics[pose_topic], key=lambda e: _stamp_ns(e[1].header))
    stamps = [_stamp_ns(m.header) for _, m, _ in msgs]  # int ns (exact keys)
    t0_ns = stamps[0] if t0 is None else round(float(t0) * 1e9)
    pose = np.array([_pose_of(m) for _, m, _ in msgs], dtype=np.float64)

    def aligned(topic: str | None, value: Any) -> list[Any] | None:
        if topic is None or topic not in topics:
            return None
        by_stamp = {}
        for ns, msg, _ in topics[topic]:
            by_stamp[_stamp_ns(msg.header) if hasattr(msg, "header") else ns] = value(msg)
        out = [by_stamp.get(s) for s in stamps]
        return None if any(v is None for v in out) else out

    odom = None if pose_topic == "/odom" else aligned("/odom", _pose_of)
    scans = aligned(scan_topic, lambda m: np.asarray(m.ranges, dtype=np.float32))
    geometry = ScanGeometry()
    if scans is not None:
        s0 = topics[scan_topic][0][1]
        geometry = ScanGeometry(s0.angle_min, s0.angle_increment, s0.range_min, s0.range_max,
                                s0.scan_time)
    state = aligned("/simlab/state", lambda m: int(m.data))
    goal = aligned("/simlab/goal", lambda m: str(m.data))
    actions = action_t = None
    if action_topic is not None and action_topic in topics:
        acts = sorted(topics[action_topic], key=lambda e: e[0])
        actions = np.array([int(m.data) for _, m, _ in acts], dtype=np.int64)
        action_t = np.array([(ns - t0_ns) * 1e-9 for ns, _, _ in acts])
    grid = None
    if "/map" in topics:
        grid = _grid_of(topics["/map"][-1][1])
    offset = (-0.032, 0.0, 0.182)
    for _, msg, _ in topics.get("/tf_static", []):
        for tr in msg.transforms:
            if tr.child_frame_id == "base_scan":
                v = tr.transform.translation
                offset = (v.x, v.y, v.z)
    return BagTrajectory(
        t=(np.array(stamps, dtype=np.int64) - t0_ns) * 1e-9, pose=pose, odom=None if odom is None else np.array(odom),
        scans=None if scans is None else np.stack(scans), scan_geometry=geometry,
        state=None if state is None else np.array(state, dtype=np.int64),
        goal=None if goal is None else np.array(goal), actions=actions, action_t=action_t,
        map=grid, scan_offset=offset)


def _grid_of(msg: Any) -> Any:
    from discretize.gridmap import OccupancyMap

    info = msg.info
    occ = np.asarray(msg.data, dtype=np.int8).reshape(info.height, info.width)[::-1]
    o = info.origin
    return OccupancyMap(occupancy=occ, resolution=float(info.resolution),
                        origin=(o.position.x, o.position.y, yaw_of(o.orientation)))
