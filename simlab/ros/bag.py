"""A trajectory as a ROS 2 bag (MCAP storage) and back, with ``rosbags`` (no ROS install).

Topics and frames (REP-105 / REP-117, as the TurtleBot3 stack publishes them; every
stamp is ``t0 + t`` with ``t`` the trajectory's seconds):

=====================  ====================================  ===============================
topic                  type                                  content
=====================  ====================================  ===============================
``/tf_static``         ``tf2_msgs/msg/TFMessage``            every fixed joint of the URDF
                                                             (``base_footprint -> base_link
                                                             -> base_scan, caster_back_link,
                                                             imu_link``), once, latched
``/tf``                ``tf2_msgs/msg/TFMessage``            ``map -> odom`` (= pose * odom
                                                             ^-1), ``odom ->
                                                             base_footprint`` and ``base_link
                                                             -> wheel_{left,right}_link``
                                                             per sample
``/joint_states``      ``sensor_msgs/msg/JointState``        the wheel joints' angles (rad)
                                                             and rates (rad/s) per sample
``/odom``              ``nav_msgs/msg/Odometry``             odometry pose (frame ``odom``),
                                                             twist and covariances
``/amcl_pose``         ``geometry_msgs/msg/                  map-frame pose (the pose a
                       PoseWithCovarianceStamped``           localizer publishes)
``/scan``              ``sensor_msgs/msg/LaserScan``         float32 ranges (frame
                                                             ``base_scan``): ``+inf`` nothing
                                                             in range, ``-inf`` too close
``/map``               ``nav_msgs/msg/OccupancyGrid``        the map, once, latched (row 0 =
                                                             bottom)
``/simlab/true_pose``  ``geometry_msgs/msg/PoseStamped``      the simulator's true pose when
                                                             the map pose is an estimate
``/simlab/state``      ``std_msgs/msg/Int32``                Markov state per sample
``/simlab/goal``       ``std_msgs/msg/String``               current goal name per sample
``/simlab/action``     ``std_msgs/msg/Int32``                action index at decision starts
``/simlab/blocked``    ``std_msgs/msg/Bool``                 the decision's translation was
                                                             not executed (decision starts)
``/simlab/duration``   ``std_msgs/msg/Float64``              the decision's duration (s,
                                                             decision starts)
``/simlab/cells``      ``visualization_msgs/msg/MarkerArray`` the states' Voronoi cells and
                                                             numbers, once, latched
``/simlab/goals``      ``visualization_msgs/msg/MarkerArray`` the goal areas, once, latched
``/simlab/human``      ``visualization_msgs/msg/MarkerArray`` the human per sample (when
                                                             there is one)
``/robot_description`` ``std_msgs/msg/String``                the robot's URDF text, once,
                                                             latched (as
                                                             ``robot_state_publisher``)
=====================  ====================================  ===============================

Latched topics are recorded with the transient-local durability that ``tf_static`` and
``map_server`` offer (``offered_qos_profiles`` of ``metadata.yaml``), so that a player
replays them to late subscribers (RViz, Foxglove). The bag's ``custom_data`` records
the writer (``simlab.writer``: what ``--overwrite`` may replace), the action set of
``/simlab/action`` (``simlab.action_set``, JSON), the pose source of the map pose and the
time origin (``simlab.time_origin_ns``: the stamp of ``t = 0``).

The robot's frames and wheel angles are those :mod:`simlab.ros.frames` derives from the
URDF and the motion (``robot``); without them, ``/tf_static`` holds the two transforms of
``base_offset`` and ``scan_offset`` and there is no ``/joint_states``.

Poses are float64 in the messages (exact). A yaw goes through a planar quaternion
``(0, 0, sin(yaw/2), cos(yaw/2))`` whose ``z`` and ``w`` are moved by a few units in the
last place so that :func:`quat_yaws` gives the yaw back bit for bit (any yaw in
``[-pi, pi]``; others come back wrapped into that range); the quaternion is unit to
~4e-16. Scans are float32 as in ``LaserScan``.

Times: a stamp is the nearest whole nanosecond to ``t0 + t`` (computed in integers, so
that a UNIX time of ~1.7e9 s loses nothing to float64 sums), and a time read back is the
float64 nearest to the stamp's nanoseconds (:func:`seconds`). So ``t`` comes back
**exactly** when it is a whole number of nanoseconds, and whenever it is 2**23 s (97
days) or more, where float64 steps are coarser than a nanosecond (a log stamped in UNIX
time); any other ``t`` comes back to the nearest nanosecond (at most 0.5 ns off).
"""

from __future__ import annotations

import contextlib
import errno
import itertools
import json
import math
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from simlab.base.errors import ConfigError, DataError
from simlab.base.io import NESTED_TOO_DEEPLY, exclusive_directory, put_back, set_aside
from simlab.ros.frames import RobotFrames, wheel_angles
from simlab.ros.markers import SceneMarkers, voronoi_cells

TOPICS = {
    "tf_static": "/tf_static", "tf": "/tf", "odom": "/odom", "amcl_pose": "/amcl_pose",
    "scan": "/scan", "map": "/map", "state": "/simlab/state", "goal": "/simlab/goal",
    "action": "/simlab/action", "blocked": "/simlab/blocked", "duration": "/simlab/duration",
    "cells": "/simlab/cells", "goals": "/simlab/goals", "human": "/simlab/human",
    "true_pose": "/simlab/true_pose", "joint_states": "/joint_states",
    "robot_description": "/robot_description",
}
_TYPES = {
    "/tf_static": "tf2_msgs/msg/TFMessage", "/tf": "tf2_msgs/msg/TFMessage",
    "/odom": "nav_msgs/msg/Odometry", "/amcl_pose": "geometry_msgs/msg/PoseWithCovarianceStamped",
    "/scan": "sensor_msgs/msg/LaserScan", "/map": "nav_msgs/msg/OccupancyGrid",
    "/simlab/state": "std_msgs/msg/Int32", "/simlab/goal": "std_msgs/msg/String",
    "/simlab/action": "std_msgs/msg/Int32", "/simlab/blocked": "std_msgs/msg/Bool",
    "/simlab/duration": "std_msgs/msg/Float64",
    "/simlab/cells": "visualization_msgs/msg/MarkerArray",
    "/simlab/goals": "visualization_msgs/msg/MarkerArray",
    "/simlab/human": "visualization_msgs/msg/MarkerArray",
    "/simlab/true_pose": "geometry_msgs/msg/PoseStamped",
    "/joint_states": "sensor_msgs/msg/JointState",
    "/robot_description": "std_msgs/msg/String",
}
#: Topics published once and latched: ``static_transform_broadcaster``, ``map_server`` and
#: ``robot_state_publisher`` (``/robot_description``) offer them transient-local (REP-105
#: tooling; ROS 2 docs "About Quality of Service settings"), and a late subscriber only gets
#: them if the bag replays them that way.
LATCHED = ("/tf_static", "/map", "/simlab/cells", "/simlab/goals", "/robot_description")

#: Value of the ``simlab.writer`` custom-data key: the mark of a bag this module wrote.
WRITER_MARK = "simlab.ros.bag"
#: Prefix of the staging directory of :func:`write_bag`, beside the bag.
STAGING_PREFIX = ".simlab-bag-"
#: Where, inside the staging folder, the bag an export replaces waits until the new one is
#: in place.
PREVIOUS = "previous"


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
    """What a bag holds, as arrays (n samples, k decisions).

    ``t`` (n,) float64 seconds, strictly increasing; ``pose`` (n, 3) map-frame (x, y, yaw)
    (m, m, rad); ``odom`` (n, 3) odometry-frame pose (None: equal to ``pose``, map -> odom
    identity); ``scans`` (n, B) float32 metres, ``+inf`` no return, ``-inf`` closer than
    ``range_min`` (REP-117; None: no /scan); ``state`` (n,) int; ``goal`` (n,) str;
    ``actions`` ``(k,)`` int with ``action_t`` (k,) s (None: no action topic), and per
    decision ``blocked`` (k,) bool and ``duration`` (k,) s (None: not recorded);
    ``action_set`` the :meth:`simlab.base.actions.ActionSet.to_json` record of the action
    indices; ``pose_source`` what the map pose is (``truth`` for a simulator's);
    ``map`` an :class:`~discretize.gridmap.OccupancyMap` (None: no /map);
    ``scan_offset`` (x, y, z) m of base_scan in base_link; ``base_offset`` (x, y, z) m of
    base_link in base_footprint; ``scene`` the cells and goals to draw; ``human`` (n, 3)
    map-frame pose of a human (None: no human); ``truth`` (n, 3) the true map-frame pose
    when ``pose`` is an estimate (a particle filter's; None: ``pose`` is the truth or
    unknown); ``custom`` further ``custom_data`` entries
    of the bag's metadata (written as given; read back: every entry); ``walk_starts`` (w,)
    the sample index where each independent walk begins (several workers' walks laid one
    after the other: the odometry's twist and covariance restart there; None: one walk);
    ``robot`` the :class:`~simlab.ros.frames.RobotFrames` to publish (every fixed joint,
    the wheels, ``/joint_states`` and ``/robot_description``; None: only the two offsets
    above, no wheels); ``t_ns`` (n,) and ``action_t_ns`` (k,) int64 the same times in
    whole nanoseconds from ``t = 0``, exact (read back: the stamps minus the time origin;
    to write: the stamps, else the nearest nanoseconds of ``t`` and ``action_t``).
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
    blocked: NDArray[np.bool_] | None = None
    duration: NDArray[np.float64] | None = None
    action_set: dict[str, Any] | None = None
    pose_source: str | None = None
    map: Any = None
    scan_offset: tuple[float, float, float] = (-0.032, 0.0, 0.182)
    base_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    scene: SceneMarkers | None = None
    human: NDArray[np.float64] | None = None
    truth: NDArray[np.float64] | None = None
    custom: dict[str, str] | None = None
    walk_starts: NDArray[np.int64] | None = None
    robot: RobotFrames | None = None
    t_ns: NDArray[np.int64] | None = None
    action_t_ns: NDArray[np.int64] | None = None


def _rosbags() -> tuple[Any, Any, Any]:
    try:
        from rosbags.rosbag2 import Reader, StoragePlugin, Writer  # noqa: F401
        from rosbags.typesys import Stores, get_typestore
    except ModuleNotFoundError:
        raise ConfigError("ROS 2 bags need the rosbags library", key="rosbags",
                          fix='pip install "simlab[ros]"') from None
    import rosbags.rosbag2 as rb

    return rb, get_typestore(Stores.ROS2_HUMBLE), StoragePlugin


def _latched_qos() -> Any:
    """The QoS profile of a latched topic: reliable, keep-last 1, transient-local."""
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    never = QosTime(sec=2147483647, nsec=4294967295)  # rmw's "infinite" duration
    return Qos(history=QosHistory.KEEP_LAST, depth=1, reliability=QosReliability.RELIABLE,
               durability=QosDurability.TRANSIENT_LOCAL, deadline=never, lifespan=never,
               liveliness=QosLiveliness.AUTOMATIC, liveliness_lease_duration=never,
               avoid_ros_namespace_conventions=False)


def _planar_yaw(z: NDArray[np.float64], w: NDArray[np.float64]) -> NDArray[np.float64]:
    """Yaw (rad, ``[-pi, pi]``) of planar quaternions ``(0, 0, z, w)``: ``2 atan2(z, w)``
    of the one of ``q``, ``-q`` (the same rotation) with ``w >= 0``."""
    flip = (w < 0) | ((w == 0) & (z < 0))
    return 2.0 * np.arctan2(np.where(flip, -z, z), np.where(flip, -w, w))


#: Units in the last place by which :func:`yaw_quats` moves ``z`` or ``w`` at most.
_NUDGES = 4


def yaw_quats(yaw: Any) -> NDArray[np.float64]:
    """Quaternions ``(..., 4)`` (x, y, z, w) of rotations by ``yaw`` (...,) rad about z,
    read back exactly by :func:`quat_yaws`.

    ``(0, 0, sin(yaw/2), cos(yaw/2))`` rounds to float64, so its yaw is off by an ulp about
    one time in ten; the nearest quaternion whose yaw is the given one bit for bit (``z``
    or ``w`` moved by at most :data:`_NUDGES` ulps, which keeps it unit to ~4e-16) is taken
    instead. A yaw outside ``[-pi, pi]`` is kept as its rotation (read back wrapped).
    Vectorized: one pass per nudge for a whole trajectory."""
    yaw = np.asarray(yaw, dtype=np.float64)
    flat = yaw.reshape(-1)
    z0, w0 = np.sin(flat / 2), np.cos(flat / 2)
    z, w = z0.copy(), w0.copy()
    inside = np.abs(flat) <= math.pi  # outside: no exact target, the rounded q is kept
    target = np.where(inside, flat, np.nan)
    found = ~inside | (_planar_yaw(z0, w0) == target)
    for k in range(1, _NUDGES + 1):
        for dz, dw in ((k, 0), (-k, 0), (0, k), (0, -k)):
            if found.all():
                break
            zc = z0 + dz * np.spacing(z0) if dz else z0
            wc = w0 + dw * np.spacing(w0) if dw else w0
            hit = ~found & (_planar_yaw(zc, wc) == target)
            z, w = np.where(hit, zc, z), np.where(hit, wc, w)
            found |= hit
    out = np.zeros((flat.size, 4))
    out[:, 2], out[:, 3] = z, w
    return out.reshape(*yaw.shape, 4)


def quat_yaws(quats: Any) -> NDArray[np.float64]:
    """Yaws ``(...,)`` (rad, ``[-pi, pi]``) of quaternions ``(..., 4)`` (x, y, z, w): the
    first angle of the intrinsic z-y'-x'' (yaw, pitch, roll) decomposition; for a planar
    quaternion (``x = y = 0``, as a ground robot's localizer and odometry publish them)
    ``2 atan2(z, w)``, which gives :func:`yaw_quats`' yaws back exactly."""
    q = np.asarray(quats, dtype=np.float64).reshape(-1, 4)
    yaw = _planar_yaw(q[:, 2], q[:, 3])
    tilted = (q[:, 0] != 0) | (q[:, 1] != 0)
    if tilted.any():
        yaw[tilted] = Rotation.from_quat(q[tilted]).as_euler("ZYX")[:, 0]
    return yaw.reshape(np.shape(quats)[:-1])


def nanoseconds(t: Any) -> NDArray[np.int64]:
    """``(...,)`` int64: the whole nanoseconds nearest to ``t`` (...,) s (>= 0). Whole seconds
    and the rest are converted apart (``t - floor(t)`` is exact), so a UNIX time of ~1.7e9 s
    is stamped to the nanosecond, not to float64's 256 ns steps of ``t * 1e9``."""
    t = np.asarray(t, dtype=np.float64)
    whole = np.floor(t)
    return whole.astype(np.int64) * 10**9 + np.rint((t - whole) * 1e9).astype(np.int64)


def seconds(ns: Any) -> NDArray[np.float64]:
    """``(...,)`` float64 s nearest to ``ns`` (...,) whole nanoseconds (correctly rounded:
    ``seconds(nanoseconds(t)) == t`` for every ``t`` that is a whole number of nanoseconds
    and every ``t >= 2**23`` s). Beyond 2**53 ns (104 days) int64 -> float64 would round
    first, so those go through Python's exact integer division."""
    ns = np.asarray(ns, dtype=np.int64)
    out = ns.astype(np.float64) / 1e9
    big = np.abs(ns) >= 2**53
    if big.any():
        out[big] = [n / 10**9 for n in ns[big].tolist()]
    return out


def _quat(yaw: float) -> tuple[float, float, float, float]:
    x, y, z, w = yaw_quats(float(yaw))
    return float(x), float(y), float(z), float(w)


def yaw_of(q: Any) -> float:
    """Yaw (rad) of a quaternion message (:func:`quat_yaws`)."""
    return float(quat_yaws([q.x, q.y, q.z, q.w]))


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


def _wrap(a: NDArray[np.float64]) -> NDArray[np.float64]:
    return (a + math.pi) % (2 * math.pi) - math.pi


def odometry_twist(t: NDArray[np.float64], odom: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(n, 3)`` twist ``(vx, vy, wz)`` (m/s, m/s, rad/s) of each odometry sample: the mean
    motion over the interval that ends at the sample, in ``base_footprint`` at the sample
    (``vx`` forward, ``vy`` left); zero at the first sample. A primitive turns then drives,
    so its translation lies along the final heading and ``vy`` is ~0."""
    twist = np.zeros((len(t), 3))
    if len(t) > 1:
        dt = np.diff(t)
        d = np.diff(odom[:, :2], axis=0)
        c, s = np.cos(odom[1:, 2]), np.sin(odom[1:, 2])
        twist[1:, 0] = (c * d[:, 0] + s * d[:, 1]) / dt
        twist[1:, 1] = (-s * d[:, 0] + c * d[:, 1]) / dt
        twist[1:, 2] = _wrap(np.diff(odom[:, 2])) / dt
    return twist


def odometry_covariance(t: NDArray[np.float64], odom: NDArray[np.float64],
                        params: Any = None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Covariances ``(n, 3, 3)`` of the odometry pose ``(x, y, yaw)`` and of the twist
    ``(vx, vy, wz)`` under the odometry motion model (Thrun, Burgard & Fox, *Probabilistic
    Robotics*, 5.4, Table 5.6: noise of ``rot1``, ``trans``, ``rot2`` with variance growing
    with the motion; ``params`` an :class:`~simlab.localization.motion.OdometryMotionParams`,
    default its defaults, the particle filter's).

    The pose covariance starts at 0 (odometry starts from a known pose) and is propagated
    to first order, ``S' = G S G^T + V M V^T`` (the book's EKF linearization, 7.4, with the
    odometry model's Jacobians); the twist covariance is the last interval's motion noise
    divided by its duration squared (``var(vx) = var(trans) / dt^2``, ``var(wz) =
    (var(rot1) + var(rot2)) / dt^2``; ``vy`` is 0 by the model).
    """
    from simlab.localization.motion import OdometryMotionParams, odometry_delta

    p = params or OdometryMotionParams()
    n = len(t)
    pose_cov, twist_cov = np.zeros((n, 3, 3)), np.zeros((n, 3, 3))
    sigma = np.zeros((3, 3))
    for i in range(1, n):
        rot1, trans, rot2 = odometry_delta(odom[i - 1], odom[i], p.min_translation)
        m = np.diag([p.alpha1 * rot1**2 + p.alpha2 * trans**2,
                     p.alpha3 * trans**2 + p.alpha4 * (rot1**2 + rot2**2),
                     p.alpha1 * rot2**2 + p.alpha2 * trans**2])
        heading = odom[i - 1, 2] + rot1
        c, s = math.cos(heading), math.sin(heading)
        g = np.array([[1.0, 0.0, -trans * s], [0.0, 1.0, trans * c], [0.0, 0.0, 1.0]])
        v = np.array([[-trans * s, c, 0.0], [trans * c, s, 0.0], [1.0, 0.0, 1.0]])
        sigma = g @ sigma @ g.T + v @ m @ v.T
        pose_cov[i] = sigma
        dt2 = float(t[i] - t[i - 1]) ** 2
        twist_cov[i, 0, 0] = m[1, 1] / dt2
        twist_cov[i, 2, 2] = (m[0, 0] + m[2, 2]) / dt2
    return pose_cov, twist_cov


def _odometry_motion(t: NDArray[np.float64], odom: NDArray[np.float64],
                     walk_starts: NDArray[np.int64] | None
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """:func:`odometry_twist` and :func:`odometry_covariance` of each walk on its own (a
    new walk starts at rest, from a known pose)."""
    bounds = [0, *sorted(set(int(i) for i in (walk_starts if walk_starts is not None else [])
                             if 0 < int(i) < len(t))), len(t)]
    twist, pose_cov, twist_cov = [], [], []
    for a, b in itertools.pairwise(bounds):
        twist.append(odometry_twist(t[a:b], odom[a:b]))
        pc, tc = odometry_covariance(t[a:b], odom[a:b])
        pose_cov.append(pc)
        twist_cov.append(tc)
    return np.concatenate(twist), np.concatenate(pose_cov), np.concatenate(twist_cov)


def _cov6(c3: NDArray[np.float64]) -> NDArray[np.float64]:
    """A planar (x, y, yaw) covariance as ROS's row-major 6x6 (x, y, z, roll, pitch, yaw);
    z, roll and pitch are exact (the robot stays on the floor): variance 0."""
    out = np.zeros((6, 6))
    idx = np.array([0, 1, 5])
    out[np.ix_(idx, idx)] = c3
    return out.reshape(-1)


_CELL_COLOR = (0.1, 0.4, 0.9, 0.8)
_GOAL_COLOR = (0.1, 0.8, 0.2, 0.5)
_HUMAN_COLOR = (0.9, 0.5, 0.1, 0.9)


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

    def pose(self, x: float, y: float, yaw: float, z: float = 0.0, quat: Any = None) -> Any:
        """A pose message; ``quat`` (x, y, z, w), when given, is ``yaw``'s quaternion."""
        q = _quat(float(yaw)) if quat is None else (float(v) for v in quat)
        return self.Pose(position=self.Point(x=float(x), y=float(y), z=float(z)),
                         orientation=self.Quat(*q))

    def tf(self, ns: int, parent: str, child: str, x: float, y: float, yaw: float,
           z: float = 0.0) -> Any:
        t = self.ts.types
        return t["geometry_msgs/msg/TransformStamped"](
            header=self.header(ns, parent), child_frame_id=child,
            transform=t["geometry_msgs/msg/Transform"](
                translation=self.Vec(x=float(x), y=float(y), z=float(z)),
                rotation=self.Quat(*_quat(float(yaw)))))

    def tf_q(self, ns: int, parent: str, child: str, xyz: tuple[float, float, float],
             quat: tuple[float, float, float, float]) -> Any:
        """A transform given by its translation (m) and quaternion (x, y, z, w)."""
        t = self.ts.types
        return t["geometry_msgs/msg/TransformStamped"](
            header=self.header(ns, parent), child_frame_id=child,
            transform=t["geometry_msgs/msg/Transform"](
                translation=self.Vec(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2])),
                rotation=self.Quat(*(float(v) for v in quat))))

    def joint_state(self, ns: int, names: list[str], position: NDArray[np.float64],
                    velocity: NDArray[np.float64]) -> Any:
        return self.ts.types["sensor_msgs/msg/JointState"](
            header=self.header(ns, ""), name=names,
            position=np.asarray(position, dtype=np.float64),
            velocity=np.asarray(velocity, dtype=np.float64),
            effort=np.zeros(0, dtype=np.float64))

    def tf_message(self, transforms: list[Any]) -> Any:
        return self.ts.types["tf2_msgs/msg/TFMessage"](transforms=transforms)

    def odometry(self, ns: int, pose: NDArray[np.float64], twist: NDArray[np.float64],
                 pose_cov: NDArray[np.float64], twist_cov: NDArray[np.float64],
                 quat: Any = None) -> Any:
        t = self.ts.types
        return t["nav_msgs/msg/Odometry"](
            header=self.header(ns, "odom"), child_frame_id="base_footprint",
            pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=self.pose(*pose, quat=quat),
                                                          covariance=_cov6(pose_cov)),
            twist=t["geometry_msgs/msg/TwistWithCovariance"](
                twist=t["geometry_msgs/msg/Twist"](
                    linear=self.Vec(x=float(twist[0]), y=float(twist[1]), z=0.0),
                    angular=self.Vec(x=0.0, y=0.0, z=float(twist[2]))),
                covariance=_cov6(twist_cov)))

    def amcl(self, ns: int, pose: NDArray[np.float64], quat: Any = None) -> Any:
        t = self.ts.types
        return t["geometry_msgs/msg/PoseWithCovarianceStamped"](
            header=self.header(ns, "map"),
            pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=self.pose(*pose, quat=quat),
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

    # -- markers ------------------------------------------------------------------------
    def marker(self, ns: int, namespace: str, ident: int, kind: str, *,
               pose: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0),
               scale: tuple[float, float, float] = (1.0, 1.0, 1.0),
               color: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0),
               points: NDArray[np.float64] | None = None, text: str = "") -> Any:
        """One ``visualization_msgs/Marker`` in the map frame; ``pose`` (x, y, z, yaw)."""
        t = self.ts.types
        m = t["visualization_msgs/msg/Marker"]
        pts = [] if points is None else [self.Point(x=float(x), y=float(y), z=0.01)
                                         for x, y in points]
        x, y, z, yaw = pose
        return m(header=self.header(ns, "map"), ns=namespace, id=int(ident),
                 type=getattr(m, kind), action=m.ADD, pose=self.pose(x, y, yaw, z),
                 scale=self.Vec(x=float(scale[0]), y=float(scale[1]), z=float(scale[2])),
                 color=t["std_msgs/msg/ColorRGBA"](*(float(c) for c in color)),
                 lifetime=t["builtin_interfaces/msg/Duration"](sec=0, nanosec=0),
                 frame_locked=False, points=pts, colors=[], texture_resource="",
                 texture=t["sensor_msgs/msg/CompressedImage"](
                     header=self.header(0, ""), format="", data=np.zeros(0, np.uint8)),
                 uv_coordinates=[], text=text, mesh_resource="",
                 mesh_file=t["visualization_msgs/msg/MeshFile"](
                     filename="", data=np.zeros(0, np.uint8)),
                 mesh_use_embedded_materials=False)

    def marker_array(self, markers: list[Any]) -> Any:
        return self.ts.types["visualization_msgs/msg/MarkerArray"](markers=markers)

    def cells(self, ns: int, scene: SceneMarkers) -> Any:
        """Each state's Voronoi cell (a closed line strip) and its number at its centre."""
        out = []
        centres = np.asarray(scene.centres, dtype=np.float64)
        bounds = scene.bounds
        if bounds is None:
            raise ValueError("cells need the scene's bounds")
        for i, poly in enumerate(voronoi_cells(centres, bounds)):
            if len(poly):
                out.append(self.marker(ns, "cells", i, "LINE_STRIP", scale=(0.01, 0, 0),
                                       color=_CELL_COLOR, points=np.vstack([poly, poly[:1]])))
            out.append(self.marker(ns, "state_ids", i, "TEXT_VIEW_FACING",
                                   pose=(centres[i, 0], centres[i, 1], 0.05, 0.0),
                                   scale=(0, 0, 0.06), color=_CELL_COLOR, text=str(i)))
        return self.marker_array(out)

    def goals(self, ns: int, scene: SceneMarkers) -> Any:
        """Each goal area as a flat disc and its name."""
        out = []
        for i, (name, x, y, r) in enumerate(scene.goals):
            out.append(self.marker(ns, "goals", i, "CYLINDER", pose=(x, y, 0.005, 0.0),
                                   scale=(2 * r, 2 * r, 0.01), color=_GOAL_COLOR))
            out.append(self.marker(ns, "goal_names", i, "TEXT_VIEW_FACING",
                                   pose=(x, y, 0.1, 0.0), scale=(0, 0, 0.08),
                                   color=_GOAL_COLOR, text=name))
        return self.marker_array(out)

    def human(self, ns: int, pose: NDArray[np.float64]) -> Any:
        """The human as a standing cylinder (0.3 m wide, 1.7 m tall) and a heading arrow."""
        x, y, yaw = (float(v) for v in pose)
        return self.marker_array([
            self.marker(ns, "human", 0, "CYLINDER", pose=(x, y, 0.85, 0.0),
                        scale=(0.3, 0.3, 1.7), color=_HUMAN_COLOR),
            self.marker(ns, "human", 1, "ARROW", pose=(x, y, 1.0, yaw),
                        scale=(0.4, 0.05, 0.05), color=_HUMAN_COLOR)])


def _check(traj: BagTrajectory) -> int:
    t = np.asarray(traj.t, dtype=np.float64)
    n = len(t)
    if n == 0 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0) or t[0] < 0:
        raise ConfigError("sample times must be >= 0 and strictly increasing", key="t")
    if traj.t_ns is not None and (np.shape(traj.t_ns) != (n,)
                                  or np.any(np.diff(traj.t_ns) < 0)):
        raise ConfigError(f"expected shape ({n},), increasing like t", key="t_ns")
    for name in ("pose", "odom", "human", "truth"):
        a = getattr(traj, name)
        if a is not None and np.shape(a) != (n, 3):
            raise ConfigError(f"expected shape ({n}, 3), got {np.shape(a)}", key=name)
    if traj.scans is not None and (np.ndim(traj.scans) != 2 or len(traj.scans) != n):
        raise ConfigError(f"expected shape ({n}, beams), got {np.shape(traj.scans)}",
                          key="scans")
    if traj.actions is not None:
        k = len(traj.actions)
        for name in ("action_t", "blocked", "duration", "action_t_ns"):
            a = getattr(traj, name)
            if (a is None and name == "action_t") or (a is not None and np.shape(a) != (k,)):
                raise ConfigError(f"expected shape ({k},) like actions, got "
                                  f"{None if a is None else np.shape(a)}", key=name)
    return n


# -- the bag directory: what may be replaced, where it is staged ------------------------
def read_metadata(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The ``rosbag2_bagfile_information`` table of a bag's ``metadata.yaml``;
    :class:`~simlab.base.errors.DataError` naming the file when it is missing or not valid."""
    from ruamel.yaml import YAML
    from ruamel.yaml.error import YAMLError

    meta = Path(path) / "metadata.yaml"
    try:
        text = meta.read_text(encoding="utf-8")
    except (FileNotFoundError, NotADirectoryError):
        raise DataError(f"{path}: not a ROS 2 bag (no metadata.yaml; a bag is the directory "
                        f"that `ros2 bag record` writes)") from None
    except UnicodeDecodeError:
        raise DataError(f"{meta}: not a text file") from None
    try:
        data = YAML(typ="safe", pure=True).load(text)
    except RecursionError:
        raise DataError(f"{meta}: {NESTED_TOO_DEEPLY}") from None
    except YAMLError as exc:
        line = " ".join(str(exc).split())
        raise DataError(f"{meta}: not valid YAML ({line})") from None
    info = data.get("rosbag2_bagfile_information") if isinstance(data, dict) else None
    if not isinstance(info, dict):
        raise DataError(f"{meta}: no rosbag2_bagfile_information table (not a ROS 2 bag's "
                        f"metadata)")
    return info


def simlab_bag_files(path: Path) -> list[Path] | None:
    """The files of ``path`` when it is a bag that :func:`write_bag` wrote (its
    ``simlab.writer`` mark, and nothing else in the directory); None otherwise."""
    if not path.is_dir():
        return None
    try:
        info = read_metadata(path)
    except DataError:
        return None
    custom = info.get("custom_data") or {}
    files = info.get("relative_file_paths") or []
    if not isinstance(custom, dict) or custom.get("simlab.writer") != WRITER_MARK:
        return None
    own = {"metadata.yaml", *(Path(str(f)).name for f in files)}
    present = [p for p in path.iterdir()]
    if any(p.name not in own or not p.is_file() for p in present):
        return None
    return present


def check_bag_target(path: str | os.PathLike[str], *, overwrite: bool = False) -> Path:
    """Refuse ``path`` as the bag to write, before any work: an existing file or
    directory unless ``overwrite`` and it is a bag written by :func:`write_bag` (anything
    else is never replaced), a parent that is a file."""
    path = Path(path)
    for parent in path.parents:
        if parent.exists() and not parent.is_dir():
            raise ConfigError("a parent of this path is a file, not a directory", path=parent,
                              fix="choose another --out")
    if not os.path.lexists(path):
        return path
    if path.is_dir() and not any(path.iterdir()):
        return path  # an empty directory: nothing to lose
    if simlab_bag_files(path) is None:
        raise ConfigError("exists and is not a bag written by simlab export-bag; it is never "
                          "replaced, even with --overwrite", path=path,
                          fix="choose another --out")
    if not overwrite:
        raise ConfigError("a bag already exists here", path=path,
                          fix="choose another --out, or pass --overwrite to replace it")
    return path


def _clear_staging(parent: Path, path: Path) -> None:
    """Remove the staging directories of the bag ``path`` (the caller holds the lock of
    ``parent``, so none of them is in use: a killed writer's, or this call's own). A writer
    stopped between its two renames (the previous bag moved aside, the new one not yet in
    place) left the only copy of the previous bag there as ``previous``: it goes back to
    ``path`` first."""
    for stale in sorted(parent.glob(f".{path.name}{STAGING_PREFIX}*")):
        put_back(stale / PREVIOUS, path)
        shutil.rmtree(stale, ignore_errors=True)


def _user_os_error(exc: OSError, path: Path) -> OSError:
    """``exc`` naming the user's bag instead of the staging file it happened on."""
    return OSError(exc.errno or errno.EIO, exc.strerror or str(exc), str(path))


def write_bag(path: str | os.PathLike[str], traj: BagTrajectory, *, t0: float = 0.0,
              overwrite: bool = False) -> Path:
    """Write ``traj`` as a ROS 2 bag directory ``path`` (MCAP storage, bag version 9).

    The bag is written in a hidden staging directory beside ``path`` and renamed, so a
    failure (full disk, Ctrl-C) leaves no partial bag and any previous bag untouched; a
    kill leaves only the staging directory, which the next write beside it removes. An
    existing ``path`` is replaced only with ``overwrite`` and only if it is a bag this
    function wrote (:func:`check_bag_target`). ``t0`` (s) is added to every stamp (ROS time
    of ``t = 0``; recorded as ``simlab.time_origin_ns``).
    """
    rb, ts, plugin = _rosbags()
    _check(traj)
    if not (math.isfinite(t0) and t0 >= 0):
        raise ConfigError(f"expected a finite number >= 0, got {t0!r}", key="start_time")
    path = check_bag_target(path, overwrite=overwrite)
    parent = path.parent
    created = [p for p in [parent, *parent.parents] if not p.exists()]
    try:
        parent.mkdir(parents=True, exist_ok=True)
        with exclusive_directory(parent, what="folder (a bag is being written into it)",
                                 fix="wait for the other export to finish, or choose "
                                     "another --out"):
            _clear_staging(parent, path)
            path = check_bag_target(path, overwrite=overwrite)  # the lock is ours now
            try:
                staging = Path(tempfile.mkdtemp(prefix=f".{path.name}{STAGING_PREFIX}",
                                                dir=parent))
                _write(rb, ts, plugin, staging / path.name, traj, t0)
                if os.path.lexists(path):
                    set_aside(path, staging / PREVIOUS)  # a bag of ours or empty
                os.replace(staging / path.name, path)
            finally:
                # by the glob, not the name: an interrupt can land after mkdtemp made the
                # folder and before its name was bound; and between the two renames it
                # puts the previous bag back
                _clear_staging(parent, path)
    except OSError as exc:
        for p in created:  # innermost first: only the directories this call made, if empty
            with contextlib.suppress(OSError):
                p.rmdir()
        raise _user_os_error(exc, path) from None
    except BaseException:
        for p in created:
            with contextlib.suppress(OSError):
                p.rmdir()
        raise
    return path


def _set_custom_data(w: Any, traj: BagTrajectory, origin_ns: int) -> None:
    """The bag's ``custom_data``: the trajectory's own, then simlab's writer mark, time
    origin (ns), action set (JSON) and pose source (these win over same-named own keys)."""
    for key, value in (traj.custom or {}).items():
        w.set_custom_data(str(key), str(value))
    w.set_custom_data("simlab.writer", WRITER_MARK)
    w.set_custom_data("simlab.time_origin_ns", str(origin_ns))
    if traj.action_set is not None:
        w.set_custom_data("simlab.action_set", json.dumps(traj.action_set))
    if traj.pose_source is not None:
        w.set_custom_data("simlab.pose_source", str(traj.pose_source))


def _put_actions(put: Any, types: Any, traj: BagTrajectory, origin_ns: int) -> None:
    """One ``/simlab/action`` message per decision (stamped ``origin_ns`` + ``action_t``),
    with its ``/simlab/blocked`` and ``/simlab/duration`` when the trajectory has them."""
    rel = (nanoseconds(np.asarray(traj.action_t, dtype=np.float64))  # _check: (k,)
           if traj.action_t_ns is None else np.asarray(traj.action_t_ns, dtype=np.int64))
    for k, (a, ns) in enumerate(zip(traj.actions, (origin_ns + rel).tolist(), strict=True)):
        put("/simlab/action", ns, types["std_msgs/msg/Int32"](data=int(a)))
        if traj.blocked is not None:
            put("/simlab/blocked", ns, types["std_msgs/msg/Bool"](data=bool(traj.blocked[k])))
        if traj.duration is not None:
            put("/simlab/duration", ns,
                types["std_msgs/msg/Float64"](data=float(traj.duration[k])))


def _write(rb: Any, ts: Any, plugin: Any, out: Path, traj: BagTrajectory, t0: float) -> None:
    m = _Msgs(ts)
    latched = [_latched_qos()]
    origin_ns = int(nanoseconds(t0))
    try:
        w_cm = rb.Writer(out, version=9, storage_plugin=plugin.MCAP)
    except rb.WriterError as exc:
        raise OSError(errno.EEXIST, str(exc), str(out)) from None
    with w_cm as w:
        conns: dict[str, Any] = {}

        def put(topic: str, ns: int, msg: Any) -> None:
            if topic not in conns:
                conns[topic] = w.add_connection(
                    topic, _TYPES[topic], typestore=ts,
                    offered_qos_profiles=latched if topic in LATCHED else ())
            w.write(conns[topic], ns, ts.serialize_cdr(msg, _TYPES[topic]))

        _set_custom_data(w, traj, origin_ns)
        t = np.asarray(traj.t, dtype=np.float64)
        rel = nanoseconds(t) if traj.t_ns is None else np.asarray(traj.t_ns, dtype=np.int64)
        stamps = (origin_ns + rel).tolist()
        pose = np.asarray(traj.pose, dtype=np.float64)
        odom = pose if traj.odom is None else np.asarray(traj.odom, dtype=np.float64)
        map_odom = compose(pose, inverse(odom))
        twist, pose_cov, twist_cov = _odometry_motion(t, odom, traj.walk_starts)
        put("/tf_static", stamps[0], m.tf_message(_static_transforms(m, stamps[0], traj)))
        if traj.robot is not None and traj.robot.description is not None:
            put("/robot_description", stamps[0],
                ts.types["std_msgs/msg/String"](data=traj.robot.description))
        q_map_odom, q_odom, q_pose = (yaw_quats(a[:, 2]) for a in (map_odom, odom, pose))
        q_truth = None if traj.truth is None else yaw_quats(np.asarray(traj.truth)[:, 2])
        robot = traj.robot
        if robot is not None:
            wheels, rates = wheel_angles(t, odom, robot.wheel_radius, robot.wheel_separation,
                                         traj.walk_starts)
            wheel_names = [j.name for j in robot.wheels]
            q_wheels = [robot.wheel_quats(k, wheels[:, k]) for k in range(2)]
        if traj.map is not None:
            put("/map", stamps[0], m.grid(stamps[0], traj.map))
        scene = traj.scene
        if scene is not None and scene.centres is not None and scene.bounds is not None:
            put("/simlab/cells", stamps[0], m.cells(stamps[0], scene))
        if scene is not None and scene.goals:
            put("/simlab/goals", stamps[0], m.goals(stamps[0], scene))
        for i, ns in enumerate(stamps):
            transforms = [m.tf_q(ns, "map", "odom", (*map_odom[i, :2], 0.0), q_map_odom[i]),
                          m.tf_q(ns, "odom", "base_footprint", (*odom[i, :2], 0.0), q_odom[i])]
            if robot is not None:
                transforms += [m.tf_q(ns, j.parent, j.child, j.xyz, q_wheels[k][i])
                               for k, j in enumerate(robot.wheels)]
                put("/joint_states", ns, m.joint_state(ns, wheel_names, wheels[i], rates[i]))
            put("/tf", ns, m.tf_message(transforms))
            put("/odom", ns, m.odometry(ns, odom[i], twist[i], pose_cov[i], twist_cov[i],
                                        q_odom[i]))
            put("/amcl_pose", ns, m.amcl(ns, pose[i], q_pose[i]))
            if traj.scans is not None:
                put("/scan", ns, m.scan(ns, traj.scans[i], traj.scan_geometry))
            if traj.state is not None:
                put("/simlab/state", ns, ts.types["std_msgs/msg/Int32"](data=int(traj.state[i])))
            if traj.goal is not None:
                put("/simlab/goal", ns, ts.types["std_msgs/msg/String"](data=str(traj.goal[i])))
            if traj.human is not None:
                put("/simlab/human", ns, m.human(ns, traj.human[i]))
            if traj.truth is not None:
                put("/simlab/true_pose", ns, ts.types["geometry_msgs/msg/PoseStamped"](
                    header=m.header(ns, "map"), pose=m.pose(*traj.truth[i], quat=q_truth[i])))
        if traj.actions is not None:
            _put_actions(put, ts.types, traj, origin_ns)


def _static_transforms(m: _Msgs, ns: int, traj: BagTrajectory) -> list[Any]:
    """``/tf_static``: every fixed joint of ``traj.robot``, or (without it) base_link and
    base_scan from the trajectory's offsets."""
    if traj.robot is not None:
        return [m.tf_q(ns, j.parent, j.child, j.xyz, j.quat) for j in traj.robot.fixed]
    sx, sy, sz = traj.scan_offset
    bx, by, bz = traj.base_offset
    return [m.tf(ns, "base_footprint", "base_link", bx, by, 0.0, bz),
            m.tf(ns, "base_link", "base_scan", sx, sy, 0.0, sz)]


def _stamp_ns(header: Any) -> int:
    return int(header.stamp.sec) * 10**9 + int(header.stamp.nanosec)


#: What rosbags and its MCAP/CDR readers raise on a damaged file (a truncated chunk, bytes
#: that are not a record, a message shorter than its type).
_READ_FAILURES: tuple[type[BaseException], ...] = (ValueError, KeyError, IndexError,
                                                   EOFError, AssertionError, TypeError)


def read_bag(path: str | os.PathLike[str], *, pose_topic: str | None = None,
             scan_topic: str | None = "/scan", action_topic: str | None = "/simlab/action",
             t0: float | None = None) -> BagTrajectory:
    """Read a bag (any storage rosbags reads: MCAP or sqlite3) into a :class:`BagTrajectory`.

    The pose comes from ``pose_topic`` (``PoseWithCovarianceStamped``, ``PoseStamped`` or
    ``Odometry``); by default ``/amcl_pose`` when the bag has it, else ``/odom``.
    ``/odom`` fills ``odom`` when it is not the pose topic and has the same stamps. Scans
    are taken when every pose sample has one with the same stamp (exact nanoseconds; else
    ``scans`` is None); the state and goal topics likewise (by bag time). Times are seconds
    since ``t0`` (s; default: the bag's recorded time origin, else the first pose stamp),
    the float64 nearest to the stamps' whole nanoseconds (which are ``t_ns`` and
    ``action_t_ns``).
    A missing or damaged bag, or a pose topic that is absent, empty or not a pose, is a
    :class:`~simlab.base.errors.DataError` naming the bag (or :class:`ConfigError` when the
    path does not exist).
    """
    _rosbags()  # a missing library is named first, whatever the path
    path = Path(path)
    if not path.exists():
        raise ConfigError("bag not found", path=path, fix="give the bag's directory")
    if not path.is_dir():
        raise ConfigError("a ROS 2 bag is a directory (with metadata.yaml), not a file",
                          path=path, fix="give the bag's directory")
    info = read_metadata(path)
    custom = info.get("custom_data") or {}
    custom = custom if isinstance(custom, dict) else {}
    topics, pose_topic = _read_topics(path, pose_topic, scan_topic, action_topic)
    if not topics.get(pose_topic):
        raise DataError(f"{path}: pose_topic: {pose_topic!r} has no messages")
    t0_ns = None if t0 is None else int(nanoseconds(t0))
    if t0_ns is None and "simlab.time_origin_ns" in custom:
        with contextlib.suppress(TypeError, ValueError):
            t0_ns = int(custom["simlab.time_origin_ns"])
    try:
        traj = _trajectory(topics, pose_topic, scan_topic, action_topic, t0_ns, path)
    except DataError:
        raise
    except _READ_FAILURES as exc:
        raise DataError(f"{path}: damaged bag, a message does not hold what its type says "
                        f"({type(exc).__name__}: {exc})") from None
    action_set = _recorded_action_set(custom, path)
    pose_source = custom.get("simlab.pose_source")
    from dataclasses import replace

    return replace(traj, action_set=action_set,
                   pose_source=None if pose_source is None else str(pose_source),
                   custom={str(k): str(v) for k, v in custom.items()})


def _read_topics(path: Path, pose_topic: str | None, scan_topic: str | None,
                 action_topic: str | None
                 ) -> tuple[dict[str, list[tuple[int, Any, str]]], str]:
    """The messages :func:`read_bag` uses, by topic: ``(bag time ns, message, type)`` in bag
    order, and the pose topic (``/amcl_pose`` when not given and present, else ``/odom``).
    An unreadable bag or an absent pose topic is a :class:`DataError` naming the bag."""
    rb, ts, _ = _rosbags()
    topics: dict[str, list[tuple[int, Any, str]]] = {}
    try:
        with rb.Reader(path) as r:
            names = {c.topic for c in r.connections}
            if pose_topic is None:
                pose_topic = "/amcl_pose" if "/amcl_pose" in names else "/odom"
            if pose_topic not in names:
                raise DataError(f"{path}: pose_topic: no topic {pose_topic!r} in the bag "
                                f"(topics: {', '.join(sorted(names)) or 'none'}; give one "
                                f"of them with --pose-topic)")
            wanted = {pose_topic, "/odom", "/map", "/simlab/state", "/simlab/goal",
                      "/simlab/true_pose",
                      scan_topic, action_topic, "/simlab/blocked", "/simlab/duration",
                      "/tf_static"} & names
            if action_topic is None:
                wanted -= {"/simlab/blocked", "/simlab/duration"}
            conns = [c for c in r.connections if c.topic in wanted]
            for c, ns, raw in r.messages(connections=conns):
                topics.setdefault(c.topic, []).append(
                    (ns, ts.deserialize_cdr(raw, c.msgtype), c.msgtype))
    except DataError:
        raise
    except rb.ReaderError as exc:
        raise DataError(f"{path}: not a readable ROS 2 bag ({' '.join(str(exc).split()).rstrip('.')}; "
                        f"a recording that was cut off can be rescued with `mcap recover`)"
                        ) from None
    except _READ_FAILURES as exc:
        raise DataError(f"{path}: damaged bag, a message cannot be read "
                        f"({type(exc).__name__}: {exc})") from None
    return topics, pose_topic


def _recorded_action_set(custom: dict[str, Any], path: Path) -> Any:
    """The action set the recorder stored in ``custom_data`` (parsed JSON; None without)."""
    if "simlab.action_set" not in custom:
        return None
    try:
        return json.loads(custom["simlab.action_set"])
    except (TypeError, ValueError):
        raise DataError(f"{path / 'metadata.yaml'}: custom_data: simlab.action_set is not "
                        f"JSON") from None


def _pose_of(msg: Any) -> tuple[float, float, float, float, float, float]:
    """``(x, y, qx, qy, qz, qw)`` of a pose message (:func:`_planar` makes the yaws)."""
    p = msg.pose.pose if hasattr(msg.pose, "pose") else msg.pose
    q = p.orientation
    return p.position.x, p.position.y, q.x, q.y, q.z, q.w


def _planar(rows: Any) -> NDArray[np.float64]:
    """``(n, 3)`` poses (x, y, yaw) of :func:`_pose_of` rows, the yaws in one call."""
    a = np.asarray(rows, dtype=np.float64).reshape(-1, 6)
    return np.column_stack([a[:, :2], quat_yaws(a[:, 2:])])


def _trajectory(topics: dict[str, list[Any]], pose_topic: str, scan_topic: str | None,
                action_topic: str | None, t0_ns: int | None, path: Path) -> BagTrajectory:
    try:
        msgs = sorted(topics[pose_topic], key=lambda e: _stamp_ns(e[1].header))
        pose = _planar([_pose_of(m) for _, m, _ in msgs])
    except AttributeError:
        raise DataError(f"{path}: pose_topic: {pose_topic!r} carries "
                        f"{topics[pose_topic][0][2]}, not a pose (give a "
                        f"PoseWithCovarianceStamped, PoseStamped or Odometry topic with "
                        f"--pose-topic)") from None
    stamps = [_stamp_ns(m.header) for _, m, _ in msgs]  # int ns (exact keys)
    t0_ns = stamps[0] if t0_ns is None else t0_ns

    def aligned(topic: str | None, value: Any) -> list[Any] | None:
        if topic is None or topic not in topics:
            return None
        by_stamp = {}
        for ns, msg, _ in topics[topic]:
            by_stamp[_stamp_ns(msg.header) if hasattr(msg, "header") else ns] = value(msg)
        out = [by_stamp.get(s) for s in stamps]
        return None if any(v is None for v in out) else out

    odom = None if pose_topic == "/odom" else aligned("/odom", _pose_of)
    truth = None if pose_topic == "/simlab/true_pose" else aligned("/simlab/true_pose",
                                                                   _pose_of)
    scans = aligned(scan_topic, lambda m: np.asarray(m.ranges, dtype=np.float32))
    geometry = ScanGeometry()
    if scans is not None and scan_topic is not None:
        s0 = topics[scan_topic][0][1]
        geometry = ScanGeometry(s0.angle_min, s0.angle_increment, s0.range_min, s0.range_max,
                                s0.scan_time)
    state = aligned("/simlab/state", lambda m: int(m.data))
    goal = aligned("/simlab/goal", lambda m: str(m.data))
    actions = action_t = action_t_ns = blocked = duration = None
    if action_topic is not None and action_topic in topics:
        acts = sorted(topics[action_topic], key=lambda e: e[0])
        actions = np.array([int(m.data) for _, m, _ in acts], dtype=np.int64)
        action_ns = [ns for ns, _, _ in acts]
        action_t_ns = np.array([ns - t0_ns for ns in action_ns], dtype=np.int64)
        action_t = seconds(action_t_ns)

        def per_action(topic: str, value: Any, dtype: Any) -> NDArray[Any] | None:
            by_ns = {ns: value(m) for ns, m, _ in topics.get(topic, [])}
            out = [by_ns.get(ns) for ns in action_ns]
            return None if not out or any(v is None for v in out) else np.array(out, dtype)

        blocked = per_action("/simlab/blocked", lambda m: bool(m.data), bool)
        duration = per_action("/simlab/duration", lambda m: float(m.data), np.float64)
    grid = None
    if "/map" in topics:
        grid = _grid_of(topics["/map"][-1][1])
    offset, base = (-0.032, 0.0, 0.182), (0.0, 0.0, 0.0)
    for _, msg, _ in topics.get("/tf_static", []):
        for tr in msg.transforms:
            v = tr.transform.translation
            if tr.child_frame_id == "base_scan":
                offset = (v.x, v.y, v.z)
            elif tr.child_frame_id == "base_link" and tr.header.frame_id == "base_footprint":
                base = (v.x, v.y, v.z)
    t_ns = np.array([ns - t0_ns for ns in stamps], dtype=np.int64)
    return BagTrajectory(
        t=seconds(t_ns), t_ns=t_ns, action_t_ns=action_t_ns, pose=pose,
        odom=None if odom is None else _planar(odom),
        scans=None if scans is None else np.stack(scans), scan_geometry=geometry,
        state=None if state is None else np.array(state, dtype=np.int64),
        goal=None if goal is None else np.array(goal), actions=actions, action_t=action_t,
        blocked=blocked, duration=duration, map=grid, scan_offset=offset, base_offset=base,
        truth=None if truth is None else _planar(truth))


def _grid_of(msg: Any) -> Any:
    from discretize.gridmap import OccupancyMap

    info = msg.info
    occ = np.asarray(msg.data, dtype=np.int8).reshape(info.height, info.width)[::-1]
    o = info.origin
    return OccupancyMap(occupancy=occ, resolution=float(info.resolution),
                        origin=(o.position.x, o.position.y, yaw_of(o.orientation)))
