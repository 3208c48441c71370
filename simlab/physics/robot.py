"""The robot: facts read from its URDF, the differential drive, and wheel odometry.

One source of truth: wheel radius, wheel separation, motor torque and speed limits, the
LIDAR mount and the footprint are read from the URDF by tag and element name,
never written here as literals. The velocity limits ``v_max`` and ``w_max`` are the
published controller limits of the TurtleBot3 Burger (0.22 m/s, 2.84 rad/s), which the URDF
format has no place for; they are fields of :class:`RobotSpec`.

Modelling choices (see robots/turtlebot3_burger.urdf): the wheels collide as spheres of
the wheel radius (on a flat floor they roll exactly like the tyre, with one stable contact
point) with lateral but no spinning friction, the ball caster is a frictionless sphere,
and the wheels are driven by PyBullet velocity motors whose maximum force is the URDF
joint ``effort`` (a torque, N m).

Frames: the URDF's root is ``base_footprint`` (on the floor under the wheel-axis midpoint,
REP-105, as in the ROBOTIS TurtleBot3 description) with ``base_link`` 0.010 m above it;
every position of :class:`RobotSpec` is in the root frame, the frame of the robot's pose.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.base.assets import resolve
from simlab.base.errors import ConfigError
from simlab.physics._bullet import pybullet

#: Published TurtleBot3 Burger controller limits.
BURGER_V_MAX = 0.22  # m/s
BURGER_W_MAX = 2.84  # rad/s


@dataclass(frozen=True)
class RobotSpec:
    """Geometry and limits of a differential-drive robot, read from its URDF.

    Lengths in metres, masses in kg, torques in N m, speeds in m/s, rad/s. Positions are
    in the URDF's root frame ``root_link`` (``base_footprint``: origin on the floor under
    the wheel-axis midpoint, x forward, y left, z up), the frame of the robot's pose:
    ``lidar_offset`` is the scan frame's origin (x, y, z) there, ``base_link_offset`` the
    origin of ``base_link`` (the link carrying the chassis and the wheels) there.
    ``footprint`` is ``(x_min, x_max, y_min, y_max)`` of the collision outline;
    ``swept_radius`` is the largest distance of that outline from the origin (the circle it
    sweeps when turning in place).
    """

    urdf_path: str
    name: str
    wheel_radius: float
    wheel_width: float
    wheel_separation: float
    left_wheel_joint: str
    right_wheel_joint: str
    wheel_torque_limit: float
    wheel_speed_limit: float
    lidar_offset: tuple[float, float, float]
    footprint: tuple[float, float, float, float]
    swept_radius: float
    total_mass: float
    root_link: str = "base_footprint"
    base_link: str = "base_link"
    base_link_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    v_max: float = BURGER_V_MAX
    w_max: float = BURGER_W_MAX


def _joint(robot, name: str, path: Path):
    for j in robot.joints:
        if j.name == name:
            return j
    raise ConfigError(f"joint {name!r} not found", path=path, key=f"joint[@name={name!r}]")


def _link(robot, name: str, path: Path):
    for link in robot.links:
        if link.name == name:
            return link
    raise ConfigError(f"link {name!r} not found", path=path, key=f"link[@name={name!r}]")


def _floats(text: str | None, n: int, default: float = 0.0) -> list[float]:
    if text is None:
        return [default] * n
    values = [float(v) for v in text.split()]
    if len(values) != n:
        raise ValueError(f"expected {n} numbers, got {text!r}")
    return values


def _origin(el: Any) -> NDArray[np.float64]:
    """4x4 transform of an element's ``<origin xyz rpy>`` (identity when absent; URDF
    fixed-axis roll-pitch-yaw: ``R = Rz(yaw) Ry(pitch) Rx(roll)``)."""
    o = el.find("origin")
    xyz = _floats(None if o is None else o.get("xyz"), 3)
    r, p, y = _floats(None if o is None else o.get("rpy"), 3)
    cr, sr, cp, sp, cy, sy = (math.cos(r), math.sin(r), math.cos(p), math.sin(p),
                              math.cos(y), math.sin(y))
    t = np.eye(4)
    t[:3, :3] = [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                 [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                 [-sp, cp * sr, cp * cr]]
    t[:3, 3] = xyz
    return t


def _geometry(el: Any) -> SimpleNamespace:
    g = el.find("geometry")
    cyl = None if g is None else g.find("cylinder")
    box = None if g is None else g.find("box")
    return SimpleNamespace(
        cylinder=None if cyl is None else SimpleNamespace(radius=float(cyl.get("radius")),
                                                          length=float(cyl.get("length"))),
        box=None if box is None else SimpleNamespace(size=_floats(box.get("size"), 3)))


def _parse_urdf(path: Path) -> SimpleNamespace:
    """The parts of a URDF :func:`load_robot_spec` reads, by tag and attribute name (the
    shapes ``yourdfpy`` gives them: ``origin`` 4x4 transforms, ``limit``, ``geometry``),
    with the standard library's XML parser. Measured by ``benchmarks/urdf_reader.py``:
    importing yourdfpy (trimesh, lxml) costs 0.7-1.0 s in every fresh process that loads
    the robot (the walk workers, the replay's baseline process, each env), against 2 ms for
    ``xml.etree``; a parse is 0.3 ms here, 1.0 ms in yourdfpy. ``tests/physics`` checks the
    parts against yourdfpy's."""
    import xml.etree.ElementTree as ET

    try:
        root = ET.parse(path).getroot()
        joints = []
        for j in root.findall("joint"):
            lim = j.find("limit")
            joints.append(SimpleNamespace(
                name=j.get("name"), parent=j.find("parent").get("link"),
                child=j.find("child").get("link"), origin=_origin(j),
                limit=None if lim is None else SimpleNamespace(
                    effort=None if lim.get("effort") is None else float(lim.get("effort")),
                    velocity=None if lim.get("velocity") is None
                    else float(lim.get("velocity")))))
        links = []
        for link in root.findall("link"):
            inertial = link.find("inertial")
            mass = None if inertial is None else inertial.find("mass")
            links.append(SimpleNamespace(
                name=link.get("name"),
                visuals=[SimpleNamespace(geometry=_geometry(v), origin=_origin(v))
                         for v in link.findall("visual")],
                collisions=[SimpleNamespace(geometry=_geometry(c), origin=_origin(c))
                            for c in link.findall("collision")],
                inertial=None if mass is None else SimpleNamespace(
                    mass=float(mass.get("value")))))
    except (ET.ParseError, OSError, AttributeError, TypeError, ValueError) as exc:
        raise ConfigError(f"cannot parse URDF: {exc}", path=path) from None
    if root.tag != "robot":
        raise ConfigError(f"cannot parse URDF: root element <{root.tag}>, expected <robot>",
                          path=path)
    return SimpleNamespace(name=root.get("name"), joints=joints, links=links)


def _frames(robot: SimpleNamespace, path: Path) -> tuple[str, dict[str, NDArray[np.float64]]]:
    """The root link's name and every link's 4x4 pose in the root frame (joint origins
    composed down the tree)."""
    children = {j.child for j in robot.joints}
    roots = [link.name for link in robot.links if link.name not in children]
    if len(roots) != 1:
        raise ConfigError(f"the links must form one tree, found roots {roots}", path=path,
                          key="robot/link")
    poses = {roots[0]: np.eye(4)}
    pending = list(robot.joints)
    while pending:
        ready = [j for j in pending if j.parent in poses]
        if not ready:
            raise ConfigError(
                f"joint {pending[0].name!r} hangs from an unknown or cyclic link "
                f"{pending[0].parent!r}", path=path, key=f"joint[@name={pending[0].name!r}]")
        for j in ready:
            poses[j.child] = poses[j.parent] @ j.origin
            pending.remove(j)
    return roots[0], poses


def _tyre(wheel_link: Any, path: Path) -> tuple[float, float]:
    """The tyre's ``(radius, width)`` in m: the first cylinder of the wheel link's visuals."""
    cylinders = [v.geometry.cylinder for v in wheel_link.visuals if v.geometry.cylinder]
    if not cylinders:
        raise ConfigError(
            "wheel link has no <visual><geometry><cylinder> giving the tyre radius and width",
            path=path, key=f"link[@name={wheel_link.name!r}]",
        )
    return float(cylinders[0].radius), float(cylinders[0].length)


def _outline(base: Any, frames: dict[str, NDArray[np.float64]], wheels: list[tuple[float, float]],
             wheel_radius: float, wheel_width: float
             ) -> tuple[tuple[float, float, float, float], float]:
    """The footprint ``(x_min, x_max, y_min, y_max)`` and swept radius (m, root frame).

    The outline is the collision boxes of the wheels' parent link ``base`` and the two tyres
    (centres ``wheels`` (x, y) in m); the parent's frame may be offset from the root's,
    never rotated in yaw here.
    """
    boxes = []
    for col in base.collisions:
        if col.geometry.box is not None:
            sx, sy, _ = col.geometry.box.size
            centre = (frames[base.name] @ col.origin)[:2, 3]
            boxes.append((float(centre[0]), float(centre[1]), sx, sy))
    xs: list[float] = []
    ys: list[float] = []
    for ox, oy, sx, sy in boxes:
        xs += [ox - sx / 2, ox + sx / 2]
        ys += [oy - sy / 2, oy + sy / 2]
    for jx, jy in wheels:
        xs += [jx - wheel_radius, jx + wheel_radius]
        ys += [jy - wheel_width / 2, jy + wheel_width / 2]
    footprint = (min(xs), max(xs), min(ys), max(ys))
    # Swept radius from the actual outline pieces (the corner of the bounding box would
    # overestimate: the wheels do not reach the rear corners).
    corners = [(ox + a * sx / 2, oy + b * sy / 2)
               for ox, oy, sx, sy in boxes for a in (-1, 1) for b in (-1, 1)]
    corners += [(jx + a * wheel_radius, jy + b * wheel_width / 2)
                for jx, jy in wheels for a in (-1, 1) for b in (-1, 1)]
    return footprint, max(math.hypot(x, y) for x, y in corners)


def load_robot_spec(
    name_or_path: str | Path = "turtlebot3_burger",
    *,
    left_wheel_joint: str = "wheel_left_joint",
    right_wheel_joint: str = "wheel_right_joint",
    scan_joint: str = "scan_joint",
) -> RobotSpec:
    """Read a :class:`RobotSpec` from a built-in robot name or a ``.urdf`` path.

    Positions are in the root link's frame (``base_footprint``: on the floor under the
    wheel-axis midpoint), whatever the links between it and the wheels or the scanner.
    """
    path = resolve("robots", name_or_path, ".urdf")
    robot = _parse_urdf(path)
    root, frames = _frames(robot, path)

    jl = _joint(robot, left_wheel_joint, path)
    jr = _joint(robot, right_wheel_joint, path)
    wheel_radius, wheel_width = _tyre(_link(robot, jl.child, path), path)
    # wheel centres (x, y) in the root frame
    wl, wr = (frames[j.child][:2, 3] for j in (jl, jr))
    separation = abs(float(wl[1] - wr[1]))
    if separation <= 0:
        raise ConfigError("wheel joints coincide in y", path=path, key=left_wheel_joint)
    for j in (jl, jr):
        if j.limit is None or j.limit.effort is None or j.limit.velocity is None:
            raise ConfigError("wheel joint needs <limit effort=... velocity=...>", path=path,
                              key=f"joint[@name={j.name!r}]/limit")
    torque = float(min(jl.limit.effort, jr.limit.effort))
    speed = float(min(jl.limit.velocity, jr.limit.velocity))

    js = _joint(robot, scan_joint, path)
    lidar_offset = tuple(float(v) for v in frames[js.child][:3, 3])
    base_link_offset = tuple(float(v) for v in frames[jl.parent][:3, 3])

    base = _link(robot, jl.parent, path)
    wheels = [(float(w[0]), float(w[1])) for w in (wl, wr)]
    footprint, swept = _outline(base, frames, wheels, wheel_radius, wheel_width)

    mass = sum(float(link.inertial.mass) for link in robot.links if link.inertial is not None)
    return RobotSpec(
        urdf_path=str(path),
        name=robot.name,
        wheel_radius=wheel_radius,
        wheel_width=wheel_width,
        wheel_separation=separation,
        left_wheel_joint=left_wheel_joint,
        right_wheel_joint=right_wheel_joint,
        wheel_torque_limit=torque,
        wheel_speed_limit=speed,
        lidar_offset=lidar_offset,  # type: ignore[arg-type]
        footprint=footprint,
        swept_radius=swept,
        total_mass=mass,
        root_link=root,
        base_link=base.name,
        base_link_offset=base_link_offset,  # type: ignore[arg-type]
    )


_PI = math.pi
_TAU = 2 * math.pi  # exact (a doubling), so the same float the expression gave inline


def wrap_angle(a):
    """Wrap angles (rad, float or array) to [-pi, pi)."""
    return (a + _PI) % _TAU - _PI


class WheelOdometry:
    """Dead reckoning from the wheel joint angles (what the robot's encoders report).

    Each update integrates the wheel rotations since the previous one as an arc of constant
    curvature (exact for constant wheel speeds between samples). Drift comes from the
    physics: slip, the finite sampling rate, contact with walls.
    """

    def __init__(self, spec: RobotSpec, pose: NDArray[np.float64], angles: tuple[float, float]):
        self._r = spec.wheel_radius
        self._b = spec.wheel_separation
        x, y, th = (float(v) for v in pose)
        self._pose = (x, y, th)
        self._last = angles

    @property
    def pose(self) -> NDArray[np.float64]:
        """The integrated pose ``(x, y, yaw)`` (a new array)."""
        return np.array(self._pose)

    def integrate(self, angles: tuple[float, float]) -> None:
        """Integrate the wheel rotations since the previous sample (plain floats: this runs
        at every command change)."""
        dl = (angles[0] - self._last[0]) * self._r
        dr = (angles[1] - self._last[1]) * self._r
        self._last = angles
        ds = 0.5 * (dl + dr)
        dth = (dr - dl) / self._b
        x, y, th = self._pose
        if abs(dth) < 1e-9:
            x += ds * math.cos(th)
            y += ds * math.sin(th)
        else:
            rad = ds / dth
            x += rad * (math.sin(th + dth) - math.sin(th))
            y -= rad * (math.cos(th + dth) - math.cos(th))
        self._pose = (x, y, wrap_angle(th + dth))

    def update(self, angles: tuple[float, float]) -> NDArray[np.float64]:
        """Integrate up to ``angles`` and return the pose."""
        self.integrate(angles)
        return np.array(self._pose)


class DiffDrive:
    """Velocity-motor differential drive of one robot body in one physics client.

    ``command(v, w)`` saturates the body velocities to ``v_max`` / ``w_max``, converts them
    to wheel speeds (scaled down together if one would exceed the wheel speed limit, so the
    curvature is kept) and sets the two wheel motors with the URDF torque limit.

    The drive keeps the wheel odometry: it integrates the encoders at every command change
    (between commands the wheel speeds are constant, so each segment is an arc) and on
    :meth:`odometry`.
    """

    def __init__(self, client, body: int, spec: RobotSpec, pose: NDArray[np.float64]) -> None:
        self.body = body
        self.spec = spec
        names = {client.getJointInfo(body, j)[1].decode(): j for j in range(client.getNumJoints(body))}
        self.left = names[spec.left_wheel_joint]
        self.right = names[spec.right_wheel_joint]
        self._joints = [self.left, self.right]
        # Release PyBullet's default velocity motors on every joint (they act as brakes).
        for j in names.values():
            client.setJointMotorControl2(body, j, pybullet.VELOCITY_CONTROL, force=0.0)
        self.commanded = (0.0, 0.0)
        self._set_motors = client.setJointMotorControlArray  # bound once (hot path)
        self._joint_states = client.getJointStates
        # Limits as plain attributes: command() runs at every control tick.
        self._half = 0.5 * spec.wheel_separation
        self._r = spec.wheel_radius
        self._v_max, self._w_max = spec.v_max, spec.w_max
        self._wheel_limit = spec.wheel_speed_limit
        self._forces = [spec.wheel_torque_limit] * 2
        self._gains = (1.0, 1.0)
        self._odometry = WheelOdometry(spec, pose, self.wheel_angles())

    def set_wheel_gains(self, left: float, right: float) -> None:
        """Scale the wheel speeds the motors are given (actuation noise, slip): the motors
        turn at ``gain * commanded``. (1, 1) is exact; the current command is re-sent."""
        gains = (max(0.0, float(left)), max(0.0, float(right)))
        if gains == self._gains:
            return
        self._gains = gains
        v, w = self.commanded
        self.commanded = (math.nan, math.nan)  # force the re-send
        self.command(v, w)

    def saturate(self, v: float, w: float) -> tuple[float, float]:
        """Clip (v, w) to the robot limits and the wheel speed limit; returns what is applied."""
        v_max, w_max, half = self._v_max, self._w_max, self._half
        v = min(max(v, -v_max), v_max)
        w = min(max(w, -w_max), w_max)
        peak = max(abs(v - w * half), abs(v + w * half)) / self._r
        if peak > self._wheel_limit:
            k = self._wheel_limit / peak
            v, w = v * k, w * k
        return v, w

    def command(self, v: float, w: float) -> tuple[float, float]:
        """Drive at forward speed ``v`` (m/s) and yaw rate ``w`` (rad/s), saturated."""
        v, w = self.saturate(v, w)
        if (v, w) == self.commanded:
            return v, w
        self._odometry.integrate(self.wheel_angles())
        half, r = self._half, self._r
        targets = [(v - w * half) / r, (v + w * half) / r]
        if self._gains != (1.0, 1.0):
            targets = [targets[0] * self._gains[0], targets[1] * self._gains[1]]
        self._set_motors(
            self.body, self._joints, pybullet.VELOCITY_CONTROL,
            targetVelocities=targets,
            forces=self._forces,
        )
        self.commanded = (v, w)
        return v, w

    def odometry(self) -> NDArray[np.float64]:
        """Wheel-odometry pose ``(x, y, yaw)``, integrated up to now."""
        return self._odometry.update(self.wheel_angles())

    def wheel_angles(self) -> tuple[float, float]:
        """Accumulated wheel joint angles (rad), left then right."""
        states = self._joint_states(self.body, self._joints)
        return states[0][0], states[1][0]
