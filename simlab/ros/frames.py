"""The robot's frames as a bag publishes them: the URDF's joints and the wheels' angles.

A TurtleBot3 recorded with ``ros2 bag record -a`` carries what its ``robot_state_publisher``
sends: the description itself (the URDF's text on ``/robot_description``), every fixed
joint of it on ``/tf_static`` and the wheels' continuous joints on ``/tf``, from the wheel
angles of ``/joint_states``. :func:`robot_frames` reads
them from simlab's URDF (with yourdfpy, by joint type and name), so that RViz and Foxglove
draw the whole robot from the bag alone, and a user's own ``robot_state_publisher`` (fed
the same URDF) finds its ``/joint_states``.

simlab's datasets and replays record poses, not wheel encoders: :func:`wheel_angles`
derives each wheel's angle from the motion between samples, as a primitive makes it (a
turn in place, then a straight drive along the final heading; thesis 2.1.2), which is
exact for simlab's primitives and the differential drive's inverse kinematics for any other
motion.

Rotations go through :class:`scipy.spatial.transform.Rotation` (quaternions in ROS order
``x, y, z, w``).
"""

from __future__ import annotations

import itertools
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from simlab.base.errors import ConfigError


@dataclass(frozen=True)
class Joint:
    """One URDF joint as a transform ``parent -> child``: ``xyz`` (m) and ``quat`` (x, y,
    z, w) of the joint's origin; ``axis`` (3,) unit vector of a continuous joint (None for a
    fixed one)."""

    name: str
    parent: str
    child: str
    xyz: tuple[float, float, float]
    quat: tuple[float, float, float, float]
    axis: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class RobotFrames:
    """What ``robot_state_publisher`` would publish for the robot: ``fixed`` joints (on
    ``/tf_static``), the ``wheels`` (left, right: continuous joints on ``/tf`` and
    ``/joint_states``), the wheel radius and separation (m), and the URDF's text as it
    publishes it on ``/robot_description`` (None: not published)."""

    fixed: tuple[Joint, ...]
    wheels: tuple[Joint, Joint]
    wheel_radius: float
    wheel_separation: float
    description: str | None = None

    def wheel_quats(self, k: int, angles: NDArray[np.float64]) -> NDArray[np.float64]:
        """``(n, 4)`` quaternions (x, y, z, w) of wheel ``k`` (0 left, 1 right) turned by
        ``angles`` (n,) rad about its axis: the joint's origin rotation, then the turn (its
        translation is the joint's ``xyz``)."""
        j = self.wheels[k]
        axis = np.asarray(j.axis, dtype=np.float64)
        turns = Rotation.from_rotvec(np.asarray(angles, dtype=np.float64)[:, None] * axis)
        return (Rotation.from_quat(j.quat) * turns).as_quat()


def robot_frames(urdf_path: str | os.PathLike[str] | None = None) -> RobotFrames:
    """The joints of the robot's URDF (default simlab's TurtleBot3 Burger) and its wheel
    geometry (:class:`~simlab.physics.robot.RobotSpec`'s wheels and their joints)."""
    import yourdfpy

    from simlab.physics.robot import load_robot_spec

    spec = load_robot_spec() if urdf_path is None else load_robot_spec(urdf_path)
    path = spec.urdf_path
    try:
        urdf = yourdfpy.URDF.load(str(path), load_meshes=False, build_scene_graph=False,
                                  load_collision_meshes=False)
        text = Path(path).read_text(encoding="utf-8")
    except Exception as exc:  # yourdfpy raises lxml's and its own errors
        raise ConfigError(f"cannot read the URDF's joints ({exc})", path=path) from None
    joints = {}
    for j in urdf.robot.joints:
        origin = np.eye(4) if j.origin is None else np.asarray(j.origin, dtype=np.float64)
        q = Rotation.from_matrix(origin[:3, :3]).as_quat()
        axis = None
        if j.type != "fixed":
            a = np.asarray(j.axis if j.axis is not None else (1.0, 0.0, 0.0), dtype=np.float64)
            axis = tuple(float(v) for v in a / np.linalg.norm(a))
        joints[j.name] = Joint(j.name, j.parent, j.child,
                               tuple(float(v) for v in origin[:3, 3]),  # type: ignore[arg-type]
                               tuple(float(v) for v in q), axis)  # type: ignore[arg-type]
    wheels = (joints[spec.left_wheel_joint], joints[spec.right_wheel_joint])
    fixed = tuple(j for j in joints.values() if j.axis is None)
    return RobotFrames(fixed=fixed, wheels=wheels, wheel_radius=float(spec.wheel_radius),
                       wheel_separation=float(spec.wheel_separation), description=text)


def wheel_angles(t: NDArray[np.float64], odom: NDArray[np.float64], radius: float,
                 separation: float, walk_starts: NDArray[np.int64] | None = None
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(angles, rates)``, each ``(n, 2)`` (left, right): the wheels' angles (rad, 0 at
    the first sample of each walk) and mean rates (rad/s) over the interval ending at each
    sample (0 at a walk's first sample), from the odometry poses ``odom`` (n, 3) at times
    ``t`` (n,) s.

    Between two samples the robot turns in place by ``dyaw`` and drives ``s`` along its
    final heading (the displacement projected on it, negative backwards): the left wheel
    turns ``(s - dyaw * separation / 2) / radius``, the right ``(s + dyaw * separation / 2)
    / radius`` (a positive angle about the wheel's +y axis rolls the robot forward).
    ``walk_starts``: sample indices where an independent walk begins (its wheels from 0)."""
    n = len(t)
    step = np.zeros((n, 2))
    rates = np.zeros((n, 2))
    if n > 1:
        d = np.diff(odom[:, :2], axis=0)
        heading = odom[1:, 2]
        s = np.cos(heading) * d[:, 0] + np.sin(heading) * d[:, 1]
        dyaw = (np.diff(odom[:, 2]) + np.pi) % (2 * np.pi) - np.pi
        half = 0.5 * separation * dyaw
        step[1:, 0], step[1:, 1] = (s - half) / radius, (s + half) / radius
        rates[1:] = step[1:] / np.diff(t)[:, None]
    if walk_starts is not None:
        firsts = np.asarray(walk_starts, dtype=np.int64)
        step[firsts] = 0.0
        rates[firsts] = 0.0
    angles = np.cumsum(step, axis=0)
    if walk_starts is not None:  # each walk's wheels count from its own start
        bounds = np.append(np.sort(np.asarray(walk_starts, dtype=np.int64)), n)
        for a, b in itertools.pairwise(bounds):
            angles[a:b] -= angles[a].copy()
    return angles, rates
