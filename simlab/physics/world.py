"""The physics world: one PyBullet client per arena, owning the robot and its LIDAR.

Every :class:`World` has its own ``BulletClient`` (DIRECT unless ``gui=True``), so two
arenas in one process never share state. Library code never touches the global
``pybullet`` connection.

Physics settings (chosen for speed, fidelity checked by tests/physics):

* a fixed time step of :data:`simlab.physics.rate.DEFAULT_HZ` (50 Hz) with the solver
  settings the rate needs (:func:`simlab.physics.rate.settings_for`: 30 iterations and the
  robot's separated contact points left out of the solver at 50 Hz; 5 iterations and
  Bullet's contacts at 200 Hz, the rate before it was a setting). Chosen by
  ``benchmarks/step_size.py``: primitives end within the 200 Hz ones' error of a 960 Hz
  reference, walks give transition matrices within the bootstrap floor of 200 Hz walks,
  and a transition costs 2.2x less CPU (see :mod:`simlab.physics.rate`). At 200 Hz
  commanded speeds and yaw rates are reproduced within 1.3 % and primitive headings within
  0.3 degrees; the tests of tests/physics hold at every rate of the settings table;
* the contact model is the cheapest of those measured at 200 Hz that keeps those figures
  (benchmarks/contact_model.py, 2026-11-26, 2-core VM): a bare step of the robot on the
  table costs ~15 us of CPU, of which ~8 us remain with the floor filtered out; the rest
  is the three floor contacts (two wheel spheres, the caster), each one normal and two
  friction rows in Bullet's Featherstone solver, set up at every step. Wheel spinning
  friction (one more row per wheel) is left out: 0.90-0.95x the step, and turns follow the
  command closer. Pyramid instead of cone friction (a further 0.97x) or 3 solver
  iterations (0.96x) move primitives sideways past 5 mm; 4 iterations (0.98x, within the
  machine's noise) bring them to 4.4 mm and the speed error to 1.5 %, so 5 are kept.
  Leaving out the LIDAR housing's collision only helps against walls (0.97x there);
* deterministic overlapping pairs, so the same commands give bit-identical trajectories;
* :meth:`World.reset` rebuilds the whole simulation, so the state after a reset depends
  only on the reset pose (no contact caches survive): a data collection can be resumed at
  a part boundary and continue exactly as an uninterrupted run.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from simlab.physics import rate
from simlab.physics._bullet import BulletClient, pybullet, quiet_stdout
from simlab.physics.arena import ArenaConfig, load_arena
from simlab.physics.lidar import Lidar, LidarScan, LidarSpec
from simlab.physics.robot import DiffDrive, RobotSpec, load_robot_spec
from simlab.physics.urdf_merge import merged_urdf_path

FLOOR_FRICTION = 1.0
WALL_FRICTION = 0.5
#: PyBullet's compound collision shapes take at most 16 children.
MAX_COMPOUND_CHILDREN = 16


def _boundary_walls(arena: ArenaConfig) -> list[tuple[float, float, float, float]]:
    """The four boundary walls as ``(centre x, centre y, half x, half y)`` (m)."""
    hx, hy = arena.size[0] / 2, arena.size[1] / 2
    cx, cy = arena.center
    t = arena.wall_thickness
    return [
        (cx - hx - t / 2, cy, t / 2, hy + t),
        (cx + hx + t / 2, cy, t / 2, hy + t),
        (cx, cy - hy - t / 2, hx + t, t / 2),
        (cx, cy + hy + t / 2, hx + t, t / 2),
    ]


class StaticClearance:
    """Lower bounds of the horizontal distance (m) from a point to the arena's static bodies.

    The bodies (boundary walls, map walls, box and cylinder obstacles) are taken as
    vertical prisms of unbounded height over their footprints, so the bound also holds
    for any ray that stays within it, at any height. The bound is kept on a grid of
    ``resolution`` (m) over the arena's bounds: a cell stores the exact distance from its
    centre to the nearest footprint, capped at ``CAP`` m (longer than any ray), less its
    half-diagonal (distance is 1-Lipschitz, so no point of the cell is nearer) and less
    ``1e-9`` m for the rounding of the cell index. Outside the grid the bound is 0. The
    resolution is coarsened for large arenas so that the grid keeps at most ``max_cells``
    cells; each footprint updates only the cells within ``CAP`` of its bounding box.

    Used to leave out ray tests that provably hit nothing (:meth:`World.rays_miss`).
    """

    #: m; distances are kept up to this (more than the LIDAR's 3.5 m range).
    CAP = 4.0

    def __init__(self, arena: ArenaConfig, resolution: float = 0.02,
                 max_cells: int = 250_000) -> None:
        x0, y0, x1, y1 = arena.bounds
        self.res = max(resolution, math.sqrt((x1 - x0) * (y1 - y0) / max_cells))
        self.x0, self.y0 = float(x0), float(y0)
        self.inv = 1.0 / self.res
        self.nx = max(1, math.ceil((x1 - x0) * self.inv))
        self.ny = max(1, math.ceil((y1 - y0) * self.inv))
        dist = np.full((self.ny, self.nx), self.CAP)
        for shape in _footprints(arena):
            self._lower(dist, *shape)
        #: (ny, nx) lower bounds (m) of the cells; rows are y.
        self.bounds = dist - self.res * math.sqrt(0.5) - 1e-9
        self.bounds.setflags(write=False)
        self._rows = self.bounds.tolist()  # plain floats: at() runs at every control tick

    def _lower(self, dist: NDArray[np.float64], cx: float, cy: float, ex: float, ey: float,
               yaw: float, radius: float) -> None:
        """Lower ``dist`` to the distance from the cell centres within ``CAP`` of the
        footprint: a box of half extents ``(ex, ey)`` turned by ``yaw`` around ``(cx, cy)``,
        rounded by ``radius`` (a cylinder is a box of no extent)."""
        c, s = math.cos(yaw), math.sin(yaw)
        half_x = abs(c) * ex + abs(s) * ey + radius + self.CAP + self.res
        half_y = abs(s) * ex + abs(c) * ey + radius + self.CAP + self.res
        i0 = max(0, math.floor((cx - half_x - self.x0) * self.inv))
        i1 = min(self.nx, math.ceil((cx + half_x - self.x0) * self.inv) + 1)
        j0 = max(0, math.floor((cy - half_y - self.y0) * self.inv))
        j1 = min(self.ny, math.ceil((cy + half_y - self.y0) * self.inv) + 1)
        if i0 >= i1 or j0 >= j1:
            return
        dx = self.x0 + (np.arange(i0, i1) + 0.5) * self.res - cx
        dy = (self.y0 + (np.arange(j0, j1) + 0.5) * self.res - cy)[:, None]
        u = np.maximum(np.abs(c * dx + s * dy) - ex, 0.0)
        v = np.maximum(np.abs(-s * dx + c * dy) - ey, 0.0)
        block = dist[j0:j1, i0:i1]
        np.minimum(block, np.maximum(np.hypot(u, v) - radius, 0.0), out=block)

    def at(self, x: float, y: float) -> float:
        """A lower bound (m) of the distance from ``(x, y)`` to every static footprint."""
        u = (x - self.x0) * self.inv
        v = (y - self.y0) * self.inv
        if 0.0 <= u < self.nx and 0.0 <= v < self.ny:
            return self._rows[int(v)][int(u)]
        return 0.0

    @classmethod
    def of(cls, arena: ArenaConfig) -> StaticClearance:
        """The bounds of ``arena``, kept per arena in this process (a calibration builds a
        world per candidate in the same lab)."""
        grid = _CLEARANCES.get(arena)
        if grid is None:
            if len(_CLEARANCES) >= 4:
                _CLEARANCES.clear()
            grid = _CLEARANCES[arena] = cls(arena)
        return grid


_CLEARANCES: dict[ArenaConfig, StaticClearance] = {}


def _footprints(arena: ArenaConfig) -> list[tuple[float, float, float, float, float, float]]:
    """The static footprints of ``arena`` as ``(cx, cy, half x, half y, yaw, radius)`` (m,
    rad): the boundary walls, the map walls, the box and cylinder obstacles."""
    out = [(x, y, ex, ey, 0.0, 0.0) for x, y, ex, ey in _boundary_walls(arena)]
    if arena.map_walls is not None:
        out += [((bx0 + bx1) / 2, (by0 + by1) / 2, (bx1 - bx0) / 2, (by1 - by0) / 2, 0.0, 0.0)
                for bx0, by0, bx1, by1 in arena.map_walls.boxes]
    for ob in arena.obstacles:
        if ob.kind == "box":
            out.append((ob.x, ob.y, ob.size[0] / 2, ob.size[1] / 2, ob.yaw, 0.0))
        else:
            out.append((ob.x, ob.y, 0.0, 0.0, 0.0, ob.radius))
    return out


#: Margins (m) of the scan shortcut of :meth:`World.scan`: how much farther than a ray's
#: length the nearest static footprint must be, and how high above the floor the rays
#: must stay. Bullet's shapes keep their collision margins inside the given extents, so
#: a ray never reports a hit outside a footprint; the margins are slack on top.
CLEAR_MARGIN = 0.02
FLOOR_MARGIN = 0.05
#: The shortcut holds only while the base tilts less than this (sine; 1.1 degrees): a robot
#: on a flat floor tilts ~1e-4 (measured on the benchmark lab's walk: at most 6e-4).
MAX_TILT_SIN = 0.02


def rays_clear_robot(robot: RobotSpec, lidar: LidarSpec) -> bool:
    """Whether no ray can hit the robot itself while it tilts less than ``MAX_TILT_SIN``.

    The robot's parts are taken to lie over its footprint (``robot.footprint``, base frame)
    and below twice the sensor's height. A ray point is at least ``range_min * cos(tilt)``
    from the sensor horizontally; a part at most its footprint corner's distance plus
    ``sensor height * sin(tilt)`` (the top-left block of the rotation has norm <= 1, its
    third column a horizontal length of ``sin(tilt)``). True for the Burger: 0.117 < 0.120 m.
    """
    ox, oy, oz = robot.lidar_offset
    x0, x1, y0, y1 = robot.footprint
    corner = max(math.hypot(x - ox, y - oy) for x in (x0, x1) for y in (y0, y1))
    return corner + oz * MAX_TILT_SIN < lidar.range_min * math.sqrt(1.0 - MAX_TILT_SIN ** 2)


class World:
    """An arena with one robot. Use as a context manager or call :meth:`close`.

    Parameters
    ----------
    arena:
        An :class:`ArenaConfig`, a built-in arena name or a ``.toml`` path.
    robot:
        A :class:`RobotSpec`, a built-in robot name or a ``.urdf`` path.
    gui:
        Open the PyBullet GUI (needs a display); DIRECT (headless) otherwise.
    physics_hz, solver_iterations, contact_threshold:
        Fixed time step (Hz; default :data:`simlab.physics.rate.DEFAULT_HZ`), constraint
        solver iterations and the robot's contact processing threshold (m; ``math.inf``:
        Bullet's default); None: what the rate needs
        (:func:`simlab.physics.rate.settings_for`). Any rate > 0 steps here; the commands
        refuse the rates too coarse for the primitives
        (:func:`simlab.physics.rate.check_rate`).
    lidar:
        Scanner parameters (LDS-01 defaults).
    """

    def __init__(
        self,
        arena: ArenaConfig | str | Path = "table",
        *,
        robot: RobotSpec | str | Path = "turtlebot3_burger",
        gui: bool = False,
        physics_hz: float | None = None,
        solver_iterations: int | None = None,
        contact_threshold: float | None = None,
        lidar: LidarSpec | None = None,
    ) -> None:
        self.arena = arena if isinstance(arena, ArenaConfig) else load_arena(arena)
        self.robot_spec = robot if isinstance(robot, RobotSpec) else load_robot_spec(robot)
        self.lidar_spec = lidar or LidarSpec()
        hz = rate.DEFAULT_HZ if physics_hz is None else float(physics_hz)
        if not (math.isfinite(hz) and hz > 0):
            raise ValueError(f"physics_hz must be a rate > 0 Hz, got {physics_hz!r}")
        need = rate.settings_for(hz)
        self.settings = rate.StepSettings(
            hz, need.solver_iterations if solver_iterations is None else int(solver_iterations),
            need.contact_threshold if contact_threshold is None
            else (None if contact_threshold == math.inf else float(contact_threshold)))
        self.physics_hz = hz
        self.dt = 1.0 / self.physics_hz
        self.solver_iterations = self.settings.solver_iterations
        self.gui = gui
        with quiet_stdout():
            self.client = BulletClient(connection_mode=pybullet.GUI if gui else pybullet.DIRECT)
        self._steps = 0
        self._clearance: StaticClearance | None = None  # built on first use; the arena stays
        self.reset()

    # ------------------------------------------------------------------ lifecycle
    def reset(self, pose: NDArray[np.float64] | tuple[float, float, float] | None = None) -> None:
        """Rebuild the simulation with the robot at rest at ``pose`` (x, y, yaw) or the start.

        Simulated time and odometry restart (odometry = the reset pose).
        """
        c = self.client
        # BulletClient makes a new functools.partial on every attribute access; the hot
        # calls are bound once (the client id survives resetSimulation).
        self._step = c.stepSimulation
        self._get_base = c.getBasePositionAndOrientation
        self._get_velocity = c.getBaseVelocity
        self._quaternion_matrix = c.getMatrixFromQuaternion
        c.resetSimulation()
        c.setGravity(0.0, 0.0, -9.81)
        c.setPhysicsEngineParameter(
            fixedTimeStep=self.dt,
            numSolverIterations=self.solver_iterations,
            numSubSteps=1,
            deterministicOverlappingPairs=1,
        )
        if self.gui:
            c.configureDebugVisualizer(pybullet.COV_ENABLE_GUI, 0)
        self._build_arena()
        pose = np.asarray(self.arena.start if pose is None else pose, dtype=float)
        if pose.shape != (3,) or not np.all(np.isfinite(pose)):
            raise ValueError(f"reset pose must be 3 finite numbers (x, y, yaw), got {pose}")
        # Friction comes from the URDF <contact> elements (frictionless caster/chassis,
        # rubber wheels). The LIDAR housing is folded into the base by our own merge
        # (see urdf_merge.py for why not PyBullet's URDF_MERGE_FIXED_LINKS).
        with quiet_stdout():
            self.body = c.loadURDF(
                str(merged_urdf_path(self.robot_spec.urdf_path)),
                basePosition=[0.0, 0.0, 0.0],
                flags=pybullet.URDF_USE_INERTIA_FROM_FILE,
            )
        # The base's reported position is its centre of mass; keep the inertial offset to
        # convert between the link frame (our pose) and the COM frame.
        threshold = self.settings.contact_threshold
        if threshold is not None:  # the manifold's separated points stay out of the solver
            for link in range(-1, c.getNumJoints(self.body)):
                c.changeDynamics(self.body, link, contactProcessingThreshold=threshold)
        info = c.getDynamicsInfo(self.body, -1)
        self._inertial_pos = np.asarray(info[3], dtype=float)
        self._inertial_xyz = tuple(float(v) for v in info[3])
        self.set_pose(pose)
        self.drive = DiffDrive(c, self.body, self.robot_spec, pose)
        self.lidar = Lidar(c, self.body, self.robot_spec.lidar_offset, self.lidar_spec)
        self._steps = 0
        # What the scan shortcut knows of: any body added or removed afterwards turns it off.
        self._num_bodies = c.getNumBodies
        self._built_bodies = (c.getNumBodies(), list(self.static_bodies))
        self._shortcut = rays_clear_robot(self.robot_spec, self.lidar_spec)
        self._sensor_from_com = tuple(float(o) - i for o, i in
                                      zip(self.robot_spec.lidar_offset, self._inertial_xyz,
                                          strict=True))

    def _build_arena(self) -> None:
        c, a = self.client, self.arena
        plane = c.createCollisionShape(pybullet.GEOM_PLANE)
        self.floor = c.createMultiBody(0, plane)
        c.changeDynamics(self.floor, -1, lateralFriction=FLOOR_FRICTION)
        h = a.wall_height
        self.static_bodies = [self.floor]
        for x, y, ex, ey in _boundary_walls(a):
            shape = c.createCollisionShape(pybullet.GEOM_BOX, halfExtents=[ex, ey, h / 2])
            vis = c.createVisualShape(pybullet.GEOM_BOX, halfExtents=[ex, ey, h / 2],
                                      rgbaColor=[0.8, 0.7, 0.55, 1]) if self.gui else -1
            body = c.createMultiBody(0, shape, vis, basePosition=[x, y, h / 2])
            c.changeDynamics(body, -1, lateralFriction=WALL_FRICTION)
            self.static_bodies.append(body)
        if a.map_walls is not None:
            self._build_map_walls()
        for ob in a.obstacles:
            if ob.kind == "box":
                ext = [ob.size[0] / 2, ob.size[1] / 2, ob.height / 2]
                shape = c.createCollisionShape(pybullet.GEOM_BOX, halfExtents=ext)
                vis = c.createVisualShape(pybullet.GEOM_BOX, halfExtents=ext,
                                          rgbaColor=[0.5, 0.5, 0.6, 1]) if self.gui else -1
            else:
                shape = c.createCollisionShape(pybullet.GEOM_CYLINDER, radius=ob.radius,
                                               height=ob.height)
                vis = c.createVisualShape(pybullet.GEOM_CYLINDER, radius=ob.radius,
                                          length=ob.height,
                                          rgbaColor=[0.5, 0.5, 0.6, 1]) if self.gui else -1
            body = c.createMultiBody(
                0, shape, vis, basePosition=[ob.x, ob.y, ob.height / 2],
                baseOrientation=c.getQuaternionFromEuler([0, 0, ob.yaw]),
            )
            c.changeDynamics(body, -1, lateralFriction=WALL_FRICTION)
            self.static_bodies.append(body)

    def _build_map_walls(self) -> None:
        """The merged wall boxes of a map-built arena, as static compound bodies of up to
        16 boxes (PyBullet's limit per compound shape): ~5x faster to build at every
        reset than one body per box, same ray and contact results. In the GUI each box is
        its own body (compounds carry no visual shapes here)."""
        c, a = self.client, self.arena
        h = a.wall_height
        boxes = [((x0 + x1) / 2, (y0 + y1) / 2, (x1 - x0) / 2, (y1 - y0) / 2)
                 for x0, y0, x1, y1 in a.map_walls.boxes]  # type: ignore[union-attr]
        chunk = 1 if self.gui else MAX_COMPOUND_CHILDREN
        for k in range(0, len(boxes), chunk):
            part = boxes[k:k + chunk]
            shape = c.createCollisionShapeArray(
                [pybullet.GEOM_BOX] * len(part),
                halfExtents=[[ex, ey, h / 2] for _x, _y, ex, ey in part],
                collisionFramePositions=[[x, y, h / 2] for x, y, _ex, _ey in part],
            )
            vis = -1
            if self.gui:
                x, y, ex, ey = part[0]
                vis = c.createVisualShape(pybullet.GEOM_BOX, halfExtents=[ex, ey, h / 2],
                                          visualFramePosition=[x, y, h / 2],
                                          rgbaColor=[0.8, 0.7, 0.55, 1])
            body = c.createMultiBody(0, shape, vis, basePosition=[0.0, 0.0, 0.0])
            c.changeDynamics(body, -1, lateralFriction=WALL_FRICTION)
            self.static_bodies.append(body)

    def close(self) -> None:
        """Disconnect the physics client (idempotent)."""
        if getattr(self, "client", None) is not None:
            try:
                self.client.disconnect()
            except pybullet.error:
                pass
            self.client = None

    def __enter__(self) -> World:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        self.close()

    # ------------------------------------------------------------------ stepping
    @property
    def time(self) -> float:
        """Simulated seconds stepped since the last reset."""
        return self._steps * self.dt

    def step(self, n: int = 1) -> None:
        """Advance the physics by ``n`` fixed steps.

        (Odometry is integrated by the drive at every command change and query: between
        commands the wheel speeds are constant, so sampling faster - the OpenCR board's
        30 Hz - was measured to change the error by < 2 mm per metre, the rest being real
        slip, while costing ~5 % of the step rate.)
        """
        step = self._step
        for _ in range(n):
            step()
        self._steps += n

    # ------------------------------------------------------------------ state
    def _link_frame(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        com, orn = self._get_base(self.body)
        rot = np.array(self._quaternion_matrix(orn)).reshape(3, 3)
        return np.array(com) - rot @ self._inertial_pos, rot

    def pose(self) -> NDArray[np.float64]:
        """True pose ``(x, y, yaw)`` (m, m, rad) of the base frame (floor under the axle)."""
        # Called many times per primitive by the controllers: plain floats from the
        # quaternion are several times cheaper than building the rotation matrix in numpy.
        (cx, cy, _), (qx, qy, qz, qw) = self._get_base(self.body)
        ox, oy, oz = self._inertial_xyz
        r00 = 1.0 - 2.0 * (qy * qy + qz * qz)
        r10 = 2.0 * (qx * qy + qz * qw)
        x = cx - (r00 * ox + 2.0 * (qx * qy - qz * qw) * oy + 2.0 * (qx * qz + qy * qw) * oz)
        y = cy - (r10 * ox + (1.0 - 2.0 * (qx * qx + qz * qz)) * oy
                  + 2.0 * (qy * qz - qx * qw) * oz)
        return np.array([x, y, math.atan2(r10, r00)])

    def yaw(self) -> float:
        """True heading (rad) of the base: ``pose()[2]`` without the position (the heading
        controllers read it at every control tick)."""
        _, (qx, qy, qz, qw) = self._get_base(self.body)
        return math.atan2(2.0 * (qx * qy + qz * qw), 1.0 - 2.0 * (qy * qy + qz * qz))

    def tilt(self) -> float:
        """Angle (rad) between the robot's up axis and the vertical (0 when upright)."""
        _, rot = self._link_frame()
        return math.acos(min(1.0, max(-1.0, rot[2, 2])))

    def height(self) -> float:
        """Height (m) of the base frame origin above the floor (0 when resting on it)."""
        return float(self._link_frame()[0][2])

    def velocity(self) -> tuple[float, float]:
        """Forward speed (m/s, along the heading) and yaw rate (rad/s) of the base."""
        lin, ang = self._get_velocity(self.body)
        yaw = self.yaw()
        return lin[0] * math.cos(yaw) + lin[1] * math.sin(yaw), ang[2]

    def set_pose(self, pose: NDArray[np.float64] | tuple[float, float, float]) -> None:
        """Place the robot upright and at rest at ``pose`` on the floor."""
        x, y, yaw = (float(v) for v in pose)
        orn = self.client.getQuaternionFromEuler([0.0, 0.0, yaw])
        rot = np.asarray(self.client.getMatrixFromQuaternion(orn), dtype=float).reshape(3, 3)
        com = np.array([x, y, 0.0]) + rot @ self._inertial_pos
        self.client.resetBasePositionAndOrientation(self.body, com.tolist(), orn)
        self.client.resetBaseVelocity(self.body, [0, 0, 0], [0, 0, 0])

    def odometry(self) -> NDArray[np.float64]:
        """Wheel-odometry pose estimate ``(x, y, yaw)`` (drifts from the truth)."""
        return self.drive.odometry()

    def scan(self, rng: np.random.Generator | None,
             beams: NDArray[np.int64] | None = None, reach: float | None = None) -> LidarScan:
        """One LIDAR scan at the current state (noise from ``rng``; none if ``rng`` is None).

        ``beams`` restricts the cast to a subset of beam indices and ``reach`` shortens the
        rays (see :meth:`Lidar.scan`). A scan whose rays provably hit nothing
        (:meth:`rays_miss`) is not cast: :meth:`Lidar.missed_scan` gives the same scan and
        the same noise draws.
        """
        pos, rot = self._link_frame()
        pose = np.array([pos[0], pos[1], math.atan2(rot[1, 0], rot[0, 0])])
        if self.rays_miss(reach, beams):
            return self.lidar.missed_scan(pose, rng, stamp=self.time, beams=beams, reach=reach)
        return self.lidar.scan(pos, rot, pose, rng, stamp=self.time, beams=beams, reach=reach)

    def rays_miss(self, reach: float | None, beams: NDArray[np.int64] | None = None) -> bool:
        """Whether every ray of a scan of ``reach`` (m from the sensor; None: the full
        range) and ``beams`` (None: all) provably hits nothing now, so its ray test can be
        left out (the obstacle detector's short scans, re-run at every control tick, are
        mostly far from everything).

        A ray of the scan runs from ``range_min`` to ``far`` along a unit direction
        ``R (cos a, sin a, 0)`` of the sensor's tilted plane (``R`` the base's rotation).
        Horizontally it is the image of the beam's segment in the sensor frame under the
        top-left 2 x 2 block of ``R``, whose norm is at most 1: so the discs of
        :meth:`Lidar.ray_cover` (scaled by ``far``), carried by that block, cover it, and it
        can hit a static body only if one's footprint reaches into a disc
        (:class:`StaticClearance` at the disc's centre). Vertically it stays within ``far *
        sin(tilt)`` of the sensor's height, so it reaches the floor only if that drop does;
        and it never hits the robot itself while the tilt is below ``MAX_TILT_SIN``
        (:func:`rays_clear_robot`; a robot for which that does not hold never takes the
        shortcut). Bodies added to or removed from the client after the
        last :meth:`reset` (a human's robot, a box of :mod:`simlab.physics.obstacles`) are
        unknown to the bound: the answer is then False. Plain floats: this runs at every
        control tick.
        """
        far = self.lidar.far(reach)
        n_bodies, static = self._built_bodies
        if (not self._shortcut or self._num_bodies() != n_bodies
                or self.static_bodies != static):
            return False
        (cx, cy, cz), (qx, qy, qz, qw) = self._get_base(self.body)
        dx, dy, dz = self._sensor_from_com
        # rows of the base's rotation matrix (the sensor is at com + R @ (dx, dy, dz))
        r20, r21 = 2.0 * (qx * qz - qy * qw), 2.0 * (qy * qz + qx * qw)
        tilt = math.hypot(r20, r21)
        sz = cz + r20 * dx + r21 * dy + (1.0 - 2.0 * (qx * qx + qy * qy)) * dz
        if tilt >= MAX_TILT_SIN or sz - far * tilt <= FLOOR_MARGIN:
            return False
        r00, r01 = 1.0 - 2.0 * (qy * qy + qz * qz), 2.0 * (qx * qy - qz * qw)
        r10, r11 = 2.0 * (qx * qy + qz * qw), 1.0 - 2.0 * (qx * qx + qz * qz)
        sx = cx + r00 * dx + r01 * dy + 2.0 * (qx * qz + qy * qw) * dz
        sy = cy + r10 * dx + r11 * dy + 2.0 * (qy * qz - qx * qw) * dz
        if self._clearance is None:
            self._clearance = StaticClearance.of(self.arena)
        at = self._clearance.at
        for ux, uy, radius in self.lidar.ray_cover(beams):
            px, py = far * ux, far * uy
            if at(sx + r00 * px + r01 * py, sy + r10 * px + r11 * py) <= far * radius + CLEAR_MARGIN:
                return False
        return True
