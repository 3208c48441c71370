"""The 16 motion primitives of the thesis (section 3.2): 8 map-frame directions x 2 speeds.

Action index = ``speed * 8 + direction``; directions in the thesis order UP, DOWN, LEFT,
RIGHT, UP-LEFT, UP-RIGHT, DOWN-LEFT, DOWN-RIGHT, with UP = +y of the map. A primitive:

1. **rotates in place** to the direction's heading: an open-loop turn at ``w_max`` for the
   bulk of the angle (no Python per physics step), then a closed-loop approach at
   ``fine_hz`` with a square-root velocity profile until the heading error is below
   ``heading_tolerance``;
2. **checks for obstacles** (the thesis ROS node ``detect_obstacles``): one LIDAR scan;
   the primitive is *blocked* if any return lies in the corridor the robot would sweep,
   i.e. from the robot's front edge to ``drive distance + detector_margin`` ahead, as wide
   as the robot plus ``detector_side_margin`` on each side. A blocked primitive skips the
   translation and is logged as such (a drive until the state changes re-runs the check
   at every control tick; a tick whose rays provably reach nothing is answered without a
   ray test, with the same result and noise draws: :meth:`World.rays_miss`);
3. **drives straight** for ``drive_time`` (0.5 s) at the slow (0.10 m/s) or fast speed
   (fast = v_max = 0.22 m/s), holding the heading with a proportional correction at
   ``hold_hz``; so a slow move covers 0.05 m and a fast one 0.11 m;
4. **brakes** and steps until the robot is at rest (or ``settle_timeout``).

Between primitives the robot idles for ``decision_latency`` (the thesis's robot waited on
ROS services and the learner between actions). The idle time is accounted for by callers
but never stepped: a robot at rest on a flat floor stays at rest.

Why these distances. The table's 41 Voronoi cells are about 0.2 m across. The next-state
entropy of a move is governed by its length relative to the cells: it is near 0 for very
short moves (the robot stays in its cell), peaks around half a cell (stay or move on, about
evenly) and dips again near one cell (the move lands in the neighbour). The thesis found
fast actions more uncertain than slow ones (Fig. 4.8) and explained it by the longer
distance travelled; that holds when the slow move is well under half a cell and the fast
one about half a cell, which is what 0.05 m and 0.11 m give. Measured on 10-hour table
walks: slow 0.83-0.90 bits, fast 1.14-1.19 bits with these defaults; with a 1 s drive (0.11 / 0.22 m)
the order reverses (slow 1.17, fast 0.85 bits), because 0.22 m is about one cell.

The default decision latency (3.02 s) makes 10 simulated hours give about the thesis's
8,448 transitions on the table arena: 36,000 s / 8,448 = 4.26 s per transition, of which a
random primitive itself takes 1.24 s on average (rotation, the obstacle check, the drive
unless blocked, and braking; measured over a 10-hour walk: 8,423 transitions with 3.03 s).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
from collections.abc import Callable
from dataclasses import dataclass, fields
from enum import IntEnum
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.base import validation
from simlab.base.actions import HEADINGS
from simlab.base.directions import Direction
from simlab.base.errors import ConfigError
from simlab.physics.lidar import LidarScan
from simlab.physics.robot import wrap_angle
from simlab.physics.world import World


class Speed(IntEnum):
    SLOW = 0
    FAST = 1


N_DIRECTIONS = len(Direction)
N_ACTIONS = N_DIRECTIONS * len(Speed)

def action_index(speed: Speed | int, direction: Direction | int) -> int:
    """Action index of a (speed, direction) pair: ``speed * 8 + direction``."""
    return int(speed) * N_DIRECTIONS + int(direction)


def decode_action(action: int) -> tuple[Speed, Direction]:
    """Inverse of :func:`action_index`; raises ValueError outside 0..15."""
    if not 0 <= int(action) < N_ACTIONS:
        raise ValueError(f"action must be in 0..{N_ACTIONS - 1}, got {action}")
    return Speed(int(action) // N_DIRECTIONS), Direction(int(action) % N_DIRECTIONS)


def action_name(action: int) -> str:
    speed, direction = decode_action(action)
    return f"{direction.name}_{speed.name}"


#: Primitive modes: ``fixed`` drives for ``drive_time``; ``until_state_change`` drives until
#: the discretized state changes, the obstacle detector says blocked, or ``max_drive_time``.
MODES = ("fixed", "until_state_change")

#: Fields that may be 0 (the rest must be > 0, except the strings).
_ZERO_OK = frozenset({
    "decision_latency", "detector_margin", "detector_side_margin", "settle_time",
    "min_turn_rate", "wheel_noise", "wheel_noise_tick", "slip", "pose_noise_xy",
    "pose_noise_yaw", "pose_noise_persistence", "localization_hz", "stop_delay",
    "min_drive", "turn_rate", "wall_slide", "wall_back", "heading_noise",
})
_STRINGS = {"heading_source": ("truth", "odometry"), "mode": MODES}
#: Fields that are probabilities or correlations (``< 1`` for the persistence).
_FRACTIONS = ("pose_noise_persistence", "wall_slide", "wall_back")
#: TurtleBot3 Burger limits (ROBOTIS e-Manual, specifications): v_max 0.22 m/s (the Waffle
#: Pi's 0.26), w_max 2.84 rad/s.
_V_MAX, _W_MAX = 0.22, 2.84
#: ``field: (low, high, unit, why)``: the values a TurtleBot3 can have, each bound well
#: beyond what a real robot shows. A field of :data:`_ZERO_OK` may also be 0 (its "off"
#: or default). Out of range, a primitive never ends (``turn_rate = 1e-9`` never finishes
#: the first turn, ``localization_hz = 1e-9`` never reads the new state) or means nothing
#: (``min_drive = 100`` m on a lab's floor). The calibration's default search
#: (:func:`simlab.calibration.space.default_space`: drive times up to two cells at
#: 0.10 m/s, ``min_drive`` up to half a cell, ``localization_hz`` 1-10 Hz, speeds up to
#: 0.26 m/s...) lies well inside.
_RANGES: dict[str, tuple[float, float, str, str]] = {
    "slow_speed": (0.0, 0.3, "m/s", f"v_max {_V_MAX} m/s, 0.26 for a Waffle Pi"),
    "fast_speed": (0.0, 0.3, "m/s", f"v_max {_V_MAX} m/s, 0.26 for a Waffle Pi"),
    "drive_time": (0.0, 60.0, "s", "a minute of driving crosses any lab"),
    "max_drive_time": (0.0, 60.0, "s", "a minute of driving crosses any lab"),
    "turn_rate": (0.05, _W_MAX, "rad/s", f"w_max {_W_MAX} rad/s; slower, a quarter turn "
                  "takes over 30 s"),
    "min_turn_rate": (0.0, _W_MAX, "rad/s", f"w_max {_W_MAX} rad/s"),
    "heading_tolerance": (0.0, math.pi / 4, "rad", "45 degrees"),
    "heading_noise": (0.0, math.pi / 4, "rad", "45 degrees"),
    "localization_hz": (0.2, 100.0, "Hz", "AMCL updates at 1-10 Hz; slower, a drive "
                        "never reads its new state"),
    "stop_delay": (0.0, 5.0, "s", f"5 s at {_V_MAX} m/s ends a metre past the boundary"),
    "min_drive": (0.0, 2.0, "m", "several cells"),
    "detector_margin": (0.0, 1.0, "m", "the LIDAR's corridor ahead"),
    "detector_side_margin": (0.0, 1.0, "m", "the LIDAR's corridor beside"),
    "pose_noise_xy": (0.0, 1.0, "m", "a localization error of a lab's width"),
    "pose_noise_yaw": (0.0, math.pi, "rad", "half a turn"),
    "wheel_noise": (0.0, 1.0, "", "a relative spread"),
    "wheel_noise_tick": (0.0, 1.0, "", "a relative spread"),
    "fine_hz": (1.0, 2000.0, "Hz", "the physics' own range"),
    "hold_hz": (1.0, 2000.0, "Hz", "the physics' own range"),
    "turn_timeout": (0.0, 60.0, "s", "a minute"),
    "settle_time": (0.0, 60.0, "s", "a minute"),
    "settle_timeout": (0.0, 60.0, "s", "a minute"),
}


@dataclass(frozen=True)
class PrimitiveParams:
    """Parameters of the motion primitives (SI units: m, s, rad, Hz).

    ``heading_source`` is the heading the controller steers by: ``"truth"`` stands in for
    the localized (SLAM/AMCL) heading the thesis robot used to execute map-frame
    directions; ``"odometry"`` uses the wheel encoders alone and drifts over time.

    ``mode``: ``"fixed"`` drives for ``drive_time`` (the thesis primitive);
    ``"until_state_change"`` drives until the discretized state of the robot's true
    position changes (checked at the ``hold_hz`` control ticks), until the obstacle
    detector, re-run at every control tick on the same corridor as the initial check
    (``speed * drive_time + detector_margin`` ahead), says blocked, or until
    ``max_drive_time`` (s) has been driven (the real robot's moves mostly end in a new cell).
    It needs the discretizer's ``state_of`` (see :func:`execute_primitive`).

    Noise (all 0 by default: no random draw is made, trajectories are bit-identical to a
    noise-free build). All draws come from the primitive's ``rng``:

    * ``wheel_noise``: relative standard deviation of each wheel's speed, drawn once per
      primitive per wheel (gain ``1 + wheel_noise * N(0, 1)``, clipped at 0);
    * ``wheel_noise_tick``: the same, redrawn at every control tick (turn and drive);
    * ``slip``: a fraction ``U(0, slip)`` of the commanded translation lost per primitive
      (both wheel speeds of the drive phase scaled by ``1 - fraction``; the encoders see
      it, as they would a soft floor; must be < 1);
    * ``pose_noise_xy`` (m) and ``pose_noise_yaw`` (rad): Gaussian noise added to the
      poses the pose source reports (and so to the recorded poses and states); applied by
      the collection walker (:func:`noisy_pose`), not by the primitive;
    * ``pose_noise_persistence``: the correlation of that error from one decision to the
      next, in [0, 1): 0 draws it afresh at each decision, ``rho`` makes it the AR(1)
      process ``e_k = rho e_(k-1) + sqrt(1 - rho^2) sigma z_k`` (same spread, drifting).
      A robot localized by AMCL carries its estimate's error from one move to the next:
      the filter updates only after the robot moved (``update_min_d`` 0.2 m,
      ``update_min_a`` pi/6 in ROS amcl's defaults) and its cloud moves little per update.
      Redrawn at each decision, a robot resting near a boundary reads the other side at
      random, and a tiny move "back" is recorded as a stay (in the ISIR lab the twin so
      stayed in 15 % of the decisions in the three large open states, the robot in none).

    The stop of ``until_state_change`` (the real robot's, Chartouny et al. 2024, sec. 3)
    reads the *localized* state, which a real robot gets at the localization's rate and
    acts on after a delay:

    * ``localization_hz``: rate (Hz) of the localized pose the stop rule reads, at a random
      phase per primitive (one ``rng`` draw); 0 reads it at every control tick;
    * ``stop_delay``: seconds from the update that shows the new state to the brake;
    * ``min_drive``: metres a drive covers before a state change may end it (the detector
      and the time limit still can). In the ISIR lab the robot stops a median 5.5 cm past a
      cell boundary (75th percentile 16.6 cm: within one update of ~0.5 s at 0.25 m/s) and
      its cell-changing drives are 0.25-0.30 m.

    The rotation and the robot at a wall:

    * ``turn_rate``: rad/s of the rotation in place (0: the robot's ``w_max``); the ISIR
      robot turns a median 71 degrees in 2-4 s before it drives;
    * ``heading_noise`` (rad): the standard deviation of the error of the heading the
      robot turns to and drives along, drawn once per primitive (``N(0, heading_noise)``
      added to the commanded heading; no draw when 0): a robot that steers by its
      localized heading drives off its action's direction by that heading's error. On the
      ISIR lab, calibrate's seed-0 twin walked on four seeds (8,012 transitions each) at
      0.15 rad lowered the TV distance to the real table on every seed, from a mean 0.2165
      to 0.2089 (0.1: no gain; 0.2-0.3: less), but held at 0.15 through calibration it
      did not (see :func:`simlab.calibration.space.default_space`), so it is 0 unless set;
    * ``wall_slide`` and ``wall_back``: what a move the detector refuses does instead
      (before it starts or while it drives): with probability ``wall_slide`` the robot
      turns to the first free heading among the commanded one +-45 and +-90 degrees
      (the side tried first drawn at random) and drives there by the same stop rule; with
      probability ``wall_back`` it backs off, reversing along its heading by the same rule,
      if nothing is behind it; otherwise it stays (the thesis robot's refusal). A real
      robot's local reaction to an obstacle ahead is not a refusal: with a wall within
      0.3 m ahead of its cell centre the ISIR robot ends in a sideways neighbour in 16 % of
      its moves and in one behind in 9 %; refusing, the twin did so in 8.5 % and 2.2 %.
    """

    slow_speed: float = 0.10
    fast_speed: float = 0.22
    drive_time: float = 0.5
    heading_tolerance: float = math.radians(1.0)
    turn_decel: float = 15.0
    min_turn_rate: float = 0.3
    fine_hz: float = 60.0
    hold_hz: float = 10.0
    hold_gain: float = 3.0
    turn_timeout: float = 4.0
    settle_time: float = 0.1
    settle_timeout: float = 0.5
    detector_margin: float = 0.05
    detector_side_margin: float = 0.02
    decision_latency: float = 3.02
    heading_source: str = "truth"
    mode: str = "fixed"
    max_drive_time: float = 3.0
    wheel_noise: float = 0.0
    wheel_noise_tick: float = 0.0
    slip: float = 0.0
    pose_noise_xy: float = 0.0
    pose_noise_yaw: float = 0.0
    pose_noise_persistence: float = 0.0
    localization_hz: float = 0.0
    stop_delay: float = 0.0
    min_drive: float = 0.0
    turn_rate: float = 0.0
    wall_slide: float = 0.0
    wall_back: float = 0.0
    heading_noise: float = 0.0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            key = f"PrimitiveParams.{f.name}"
            if f.name in _STRINGS:
                validation.choice(value, _STRINGS[f.name], key)
            else:
                validation.positive(value, key, allow_zero=f.name in _ZERO_OK)
        for name, (low, high, unit, why) in _RANGES.items():
            value = getattr(self, name)
            if value == 0.0 and name in _ZERO_OK:
                continue
            if not low <= value <= high:
                zero = " (or 0)" if name in _ZERO_OK and low > 0 else ""
                raise ConfigError(
                    f"{value!r} is outside the range a TurtleBot3 can have: {low:g} to "
                    f"{high:g}{' ' + unit if unit else ''}{zero} ({why})",
                    key=f"PrimitiveParams.{name}",
                    fix=f"give {name} from {low:g} to {high:g}{' ' + unit if unit else ''}"
                    f"{zero}")
        if self.slip >= 1.0:
            raise ConfigError(f"must be < 1 (a fraction of the distance), got {self.slip!r}",
                              key="PrimitiveParams.slip")
        for name in _FRACTIONS:
            value = getattr(self, name)
            if value > 1.0 or (value == 1.0 and name == "pose_noise_persistence"):
                raise ConfigError(f"must be {'< 1' if name == 'pose_noise_persistence' else '<= 1'}"
                                  f", got {value!r}", key=f"PrimitiveParams.{name}")
        if self.wall_slide + self.wall_back > 1.0:
            raise ConfigError(f"wall_slide + wall_back = {self.wall_slide + self.wall_back:g} "
                              "is more than 1 (they are probabilities of one move)",
                              key="PrimitiveParams.wall_back")

    @property
    def reacts_at_walls(self) -> bool:
        """Whether a refused move may slide or back off (:attr:`wall_slide`, ``wall_back``)."""
        return bool(self.wall_slide or self.wall_back)

    @property
    def has_motion_noise(self) -> bool:
        """Whether the primitive draws actuation noise (wheel noise or slip)."""
        return bool(self.wheel_noise or self.wheel_noise_tick or self.slip)

    def speed_of(self, action: int) -> float:
        """Forward speed (m/s) of an action."""
        return self.fast_speed if decode_action(action)[0] == Speed.FAST else self.slow_speed

    def nominal_distance(self, action: int) -> float:
        """Distance (m) an unblocked ``fixed``-mode action is meant to travel."""
        return self.speed_of(action) * self.drive_time

    # ------------------------------------------------------------------ records
    def to_json(self) -> dict[str, Any]:
        """All fields as a JSON-ready dict (what dataset manifests record)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_json(cls, data: dict[str, Any], *, path: str | os.PathLike[str] | None = None,
                  where: str = "primitives") -> PrimitiveParams:
        """Inverse of :meth:`to_json`. Missing fields take their defaults (records written
        before a field existed); an unknown key raises ConfigError naming it."""
        if not isinstance(data, dict):
            raise ConfigError(f"expected a table of primitive parameters, got {data!r}",
                              path=path, key=where)
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ConfigError(f"unknown primitive parameter(s) {unknown}", path=path,
                              key=f"{where}.{unknown[0]}", fix=f"allowed: {sorted(known)}")
        try:
            return cls(**data)
        except ConfigError as exc:
            field_name = (exc.key or "").replace("PrimitiveParams.", "")
            raise ConfigError(exc.problem, path=path, key=f"{where}.{field_name}",
                              fix=exc.fix) from None

    @classmethod
    def from_toml(cls, path: str | os.PathLike[str]) -> PrimitiveParams:
        """Load the ``[primitives]`` table of a TOML file (other tables are ignored, so a
        calibration report can carry the table beside its own)."""
        from simlab.base.io import read_toml

        p = Path(path)
        data = read_toml(p, what="primitives file", key="--primitives")
        if "primitives" not in data:
            raise ConfigError("missing table", path=p, key="primitives",
                              fix="put the settings under a [primitives] table")
        return cls.from_json(data["primitives"], path=p)

    @classmethod
    def ensemble_from_toml(cls, path: str | os.PathLike[str]) -> tuple[PrimitiveParams, ...]:
        """The twin ensemble of a ``primitives.toml`` of ``simlab calibrate``: its
        ``[[ensemble]]`` array of tables, one full record per member, the winner first (the
        ``[primitives]`` table is the winner alone). Each member is checked as
        :meth:`from_json` checks a table, an error naming ``ensemble[k].field``; a file
        without ``[[ensemble]]`` is a ConfigError (calibrate writes none when no other
        confirmed candidate is within sampling of the winner)."""
        from simlab.base.io import read_toml

        p = Path(path)
        data = read_toml(p, what="primitives file", key="--primitives")
        members = data.get("ensemble")
        if members is None:
            raise ConfigError(
                "no twin ensemble in this file (no [[ensemble]] tables)", path=p,
                key="ensemble", fix="calibrate writes [[ensemble]] when several confirmed "
                "candidates are within sampling of the winner; use the [primitives] table "
                "alone without --ensemble")
        if not isinstance(members, list) or not members:
            raise ConfigError("expected an array of tables [[ensemble]], got "
                              f"{repr(members)[:80]}", path=p, key="ensemble",
                              fix="write each member as an [[ensemble]] table of primitive "
                              "parameters")
        return tuple(cls.from_json(m, path=p, where=f"ensemble[{k}]")
                     for k, m in enumerate(members))

    def replace(self, **changes: Any) -> PrimitiveParams:
        """A copy with ``changes`` (validated); ``None`` values are ignored (CLI flags)."""
        return dataclasses.replace(self, **{k: v for k, v in changes.items() if v is not None})

    def toml_text(self) -> str:
        """The parameters as a ``[primitives]`` TOML table (round-trips by :meth:`from_toml`)."""
        lines = ["[primitives]"]
        for name, value in self.to_json().items():
            lines.append(f"{name} = " + (f'"{value}"' if isinstance(value, str) else repr(value)))
        return "\n".join(lines) + "\n"


def primitive_params_from_record(record: dict[str, Any] | None) -> PrimitiveParams | None:
    """The :class:`PrimitiveParams` a dataset was collected with, or None if not recorded.

    ``record`` may be a dataset manifest (``record["parameters"]["primitive"]``), its
    ``parameters`` dict, a dict with a ``primitive`` or ``primitives`` key, or the primitive
    dict itself. Returns None when there is no record, or when it was made by the
    kinematic simulator (whose parameters are not primitive parameters).
    """
    if not isinstance(record, dict):
        return None
    if record.get("simulator") == "kinematic":
        return None
    node: Any = record
    if isinstance(node.get("parameters"), dict):
        node = node["parameters"]
    for key in ("primitive", "primitives"):
        if key in node:
            node = node[key]
            break
    if not isinstance(node, dict) or "slow_speed" not in node or "turn_decel" not in node:
        return None  # absent, or KinematicParams (no turn_decel)
    return PrimitiveParams.from_json(node, where="primitive")


def noisy_pose(pose: NDArray[np.float64], params: PrimitiveParams,
               rng: np.random.Generator) -> NDArray[np.float64]:
    """``pose`` (3,) plus the pose-source noise of ``params`` (no draw when it is 0)."""
    if not (params.pose_noise_xy or params.pose_noise_yaw):
        return pose
    z = rng.standard_normal(3)
    out = np.array(pose, dtype=np.float64)
    out[0] += params.pose_noise_xy * z[0]
    out[1] += params.pose_noise_xy * z[1]
    out[2] = float(wrap_angle(out[2] + params.pose_noise_yaw * z[2]))
    return out


@dataclass(frozen=True)
class PrimitiveResult:
    """Outcome of one primitive. Poses are ``(x, y, yaw)`` (m, m, rad).

    ``duration`` is the simulated time stepped (s), without the decision latency;
    ``heading_error`` the final heading error (rad) after the rotation, from the heading
    it turned to (the commanded one plus the draw of ``heading_noise``); ``scan`` the scan
    the obstacle detector used (its cone of beams, cast only as far as the corridor:
    farther surfaces read ``inf``). ``stop_reason`` says why the translation ended:
    ``"blocked"`` (never started), ``"fixed"`` (``drive_time`` elapsed), or in
    ``until_state_change`` mode ``"state_change"``, ``"detector"`` (blocked while driving)
    or ``"timeout"``; ``drive_duration`` is the time driven (s). ``pose_turned`` is the
    true pose after the rotation (before the check and the drive): the turn in place moves
    the centre by a few mm, which is the turn's error, not the drive's. ``reaction`` says
    what a refused move did instead (``"slide"``, ``"back"``; empty when it did not react,
    see ``wall_slide``): ``blocked`` is then False, the robot moved.
    """

    action: int
    blocked: bool
    pose_before: NDArray[np.float64]
    pose_after: NDArray[np.float64]
    odom_before: NDArray[np.float64]
    odom_after: NDArray[np.float64]
    duration: float
    heading_error: float
    scan: LidarScan
    stop_reason: str = "fixed"
    drive_duration: float = 0.0
    pose_turned: NDArray[np.float64] | None = None
    reaction: str = ""


#: Speeds below which the robot counts as at rest (m/s, rad/s).
REST_SPEED = 5e-3
REST_YAW_RATE = 2e-2

ScanCallback = Callable[[LidarScan, NDArray[np.float64]], None]


def corridor_blocked(scan: LidarScan, distance: float, footprint: tuple[float, float, float, float],
                     margin: float, side_margin: float) -> bool:
    """Whether any LIDAR return lies in the corridor a straight drive of ``distance`` sweeps.

    ``footprint`` is the robot outline ``(x_min, x_max, y_min, y_max)`` in the base frame.
    Two detector scans in three see nothing within their short reach: they are answered
    before any point is computed.
    """
    if not np.isfinite(scan.ranges).any():
        return False
    pts = scan.points_base()
    _, x_max, y_min, y_max = footprint
    inside = (
        (pts[:, 0] > 0.0)
        & (pts[:, 0] <= x_max + distance + margin)
        & (pts[:, 1] >= y_min - side_margin)
        & (pts[:, 1] <= y_max + side_margin)
    )
    return bool(inside.any())


@functools.lru_cache(maxsize=32)
def detector_beams(n_beams: int, range_min: float, sensor_x: float,
                   footprint: tuple[float, float, float, float], reach: float,
                   side_margin: float) -> NDArray[np.int64]:
    """Indices of the beams that can return a point of the detector's corridor.

    The corridor (base frame) is ``0 < x <= x_max + reach``, ``|y| <= y_max + side_margin``;
    a return needs a range of at least ``range_min`` from the sensor at ``(sensor_x, 0)``.
    The widest such bearing is found on a fine grid of the corridor, plus one beam of slack
    (for the Burger: +-66 degrees, 133 of 360 beams).
    """
    _, x_max, y_min, y_max = footprint
    xs = np.linspace(1e-4, x_max + reach, 400)
    ys = np.linspace(y_min - side_margin, y_max + side_margin, 200)
    gx, gy = np.meshgrid(xs - sensor_x, ys)
    visible = np.hypot(gx, gy) >= range_min
    half = float(np.abs(np.arctan2(gy, gx))[visible].max()) + 2 * math.pi / n_beams
    angles = np.arange(n_beams) * (2 * math.pi / n_beams)
    beams = np.flatnonzero(np.abs(wrap_angle(angles)) <= half + 1e-9)
    beams.setflags(write=False)
    return beams


class ScanStepper:
    """Steps a world, calling ``on_scan(scan, odometry_pose)`` at the LIDAR rate.

    Scans are due every ``1 / rate_hz`` seconds of simulated time from the stepper's
    creation; ``beams`` restricts each cast to those beam indices (None: all), for
    consumers that read only a few (a particle filter's 40 beams). Used by the primitives
    and by any other controlled motion that must keep a localizer fed (the replay's
    return to the start pose).
    """

    def __init__(self, world: World, rng: np.random.Generator, on_scan: ScanCallback | None,
                 beams: NDArray[np.int64] | None = None):
        self.world = world
        self.rng = rng
        self.on_scan = on_scan
        self.beams = beams
        self.period = 1.0 / world.lidar_spec.rate_hz
        self.next_scan = world.time + self.period
        self._hz = world.physics_hz  # advance() runs at every control tick

    def advance(self, seconds: float) -> None:
        """Step ``seconds`` (rounded to whole physics steps, at least one)."""
        w = self.world
        n = round(seconds * self._hz)
        if n < 1:
            n = 1
        if self.on_scan is None:
            w.step(n)
            return
        while n > 0:
            due = max(1, math.ceil((self.next_scan - w.time) * w.physics_hz - 1e-9))
            k = min(n, due)
            w.step(k)
            n -= k
            if w.time >= self.next_scan - 1e-9:
                self.on_scan(w.scan(self.rng, beams=self.beams), w.odometry())
                self.next_scan += self.period


StateOf = Callable[[NDArray[np.float64]], int]


class _ActuationNoise:
    """Wheel-speed gains of one primitive (see :class:`PrimitiveParams`); no draw when the
    noise parameters are 0, so a noise-free primitive consumes nothing from ``rng``."""

    def __init__(self, p: PrimitiveParams, rng: np.random.Generator, drive: Any) -> None:
        self.p, self.rng, self.drive = p, rng, drive
        self.active = p.has_motion_noise  # read once: tick() runs at every control tick
        self.base = (1.0, 1.0)
        self.slip = 1.0
        if p.wheel_noise:
            z = rng.standard_normal(2)
            self.base = (1.0 + p.wheel_noise * z[0], 1.0 + p.wheel_noise * z[1])
        if p.slip:
            self.slip = 1.0 - p.slip * float(rng.random())
        self.driving = False

    def tick(self) -> None:
        """Apply the gains for the next control period (redrawing the per-tick part)."""
        if not self.active:
            return
        gl, gr = self.base
        if self.p.wheel_noise_tick:
            z = self.rng.standard_normal(2)
            gl, gr = gl * (1.0 + self.p.wheel_noise_tick * z[0]), gr * (
                1.0 + self.p.wheel_noise_tick * z[1])
        k = self.slip if self.driving else 1.0
        self.drive.set_wheel_gains(gl * k, gr * k)

    def clear(self) -> None:
        if self.active:
            self.drive.set_wheel_gains(1.0, 1.0)


@dataclass(frozen=True)
class _Run:
    """What the phases of one primitive share: the world and its stepper, the parameters,
    the heading the controller steers by (rad, true or odometry), the actuation noise and
    the target heading (rad)."""

    world: World
    stepper: ScanStepper
    p: PrimitiveParams
    heading: Callable[[], float]
    noise: _ActuationNoise
    target: float


def _rotate(run: _Run) -> float:
    """Turn in place to ``run.target`` (rad); returns the final true heading error (rad).

    ``heading`` returns a float, so the errors stay plain floats. The fine loop runs ~15
    times per primitive: its lookups are hoisted and ``max``/``min`` written as compares
    (same values: no NaN can occur here)."""
    world, p, target, heading = run.world, run.p, run.target, run.heading
    command, advance, tick = world.drive.command, run.stepper.advance, run.noise.tick
    w_max = world.robot_spec.w_max
    if p.turn_rate and p.turn_rate < w_max:
        w_max = p.turn_rate
    err = wrap_angle(target - heading())
    bulk = abs(err) - 0.25
    if bulk > 0:  # open loop at w_max for the bulk, then a closed-loop approach
        tick()
        command(0.0, math.copysign(w_max, err))
        advance(bulk / w_max)
        err = wrap_angle(target - heading())
    fine_dt = 1.0 / p.fine_hz
    tolerance, min_rate, two_decel = p.heading_tolerance, p.min_turn_rate, 2.0 * p.turn_decel
    deadline = world.time + p.turn_timeout
    while abs(err) > tolerance and world.time < deadline:
        size = abs(err)
        rate = math.sqrt(two_decel * size)
        if rate < min_rate:
            rate = min_rate
        # Never command more than the remaining angle over one control period.
        if w_max < rate:
            rate = w_max
        if size / fine_dt < rate:
            rate = size / fine_dt
        tick()
        command(0.0, math.copysign(rate, err))
        advance(fine_dt)
        err = wrap_angle(target - heading())
    command(0.0, 0.0)
    advance(p.settle_time / 2)
    return wrap_angle(target - world.yaw())


@dataclass(frozen=True)
class _Detector:
    """The obstacle check of one robot and parameter set, on a fresh scan of the cone ahead.

    Only the beams that can see the swept corridor are cast (``beams``; the others cannot
    block: this cuts the check's cost by 2/3), and only as far as the corridor's farthest
    corner plus ten noise sigmas (``reach``, m; a shorter ray test is ~3x cheaper; anything
    beyond cannot read as inside the corridor). The corridor is that of the longer nominal
    drive (``max(slow, fast) * drive_time + detector_margin``). ``behind``: the same check
    for a drive in reverse (the cone behind the robot, the footprint mirrored).
    """

    beams: NDArray[np.int64]
    reach: float
    footprint: tuple[float, float, float, float]
    margin: float
    side_margin: float
    behind: bool = False

    @classmethod
    def of(cls, world: World, p: PrimitiveParams, *, behind: bool = False) -> _Detector:
        spec, lidar = world.robot_spec, world.lidar_spec
        corridor = max(p.slow_speed, p.fast_speed) * p.drive_time + p.detector_margin
        sensor_x, footprint = spec.lidar_offset[0], spec.footprint
        if behind:  # the reverse drive seen in a frame turned by 180 degrees
            x_min, x_max, y_min, y_max = footprint
            sensor_x, footprint = -sensor_x, (-x_max, -x_min, -y_max, -y_min)
        beams = detector_beams(lidar.n_beams, lidar.range_min, sensor_x, footprint,
                               corridor, p.detector_side_margin)
        if behind:
            beams = np.sort((beams + lidar.n_beams // 2) % lidar.n_beams)
            beams.setflags(write=False)
        _, x_max, _, y_max = footprint
        reach = (math.hypot(x_max + corridor - sensor_x, y_max + p.detector_side_margin)
                 + 10.0 * lidar.noise_sigma + 0.01)
        return cls(beams, max(reach, lidar.range_min + 0.01), footprint,
                   p.detector_margin, p.detector_side_margin, behind)

    def check(self, world: World, rng: np.random.Generator,
              distance: float) -> tuple[bool, LidarScan]:
        """(blocked, the scan) for a drive of ``distance`` (m); the noise comes from ``rng``."""
        scan = world.scan(rng, beams=self.beams, reach=self.reach)
        seen = scan if not self.behind else dataclasses.replace(
            scan, angles=scan.angles + math.pi, sensor_offset=-scan.sensor_offset)
        return corridor_blocked(seen, distance, self.footprint, self.margin,
                                self.side_margin), scan

    def blocked(self, world: World, rng: np.random.Generator, distance: float) -> bool:
        """:meth:`check`'s answer alone (the re-check at every control tick): when no ray
        can hit anything (:meth:`World.rays_miss`) the scan, all ``inf``, is not even built;
        its noise is drawn all the same, so ``rng`` goes on as after a cast."""
        if world.rays_miss(self.reach, self.beams):
            world.lidar.skip_noise(rng, self.beams.shape[0])
            return False
        return self.check(world, rng, distance)[0]


class _StopRule:
    """The stop rule of ``until_state_change`` mode, asked after every control tick.

    The drive ends when the localized state has left the state of ``start`` (3,) for
    ``stop_delay`` seconds, counted from the localization update that showed it, an update
    counting only once the drive has covered ``min_drive``; or when the detector, re-run on
    the nominal drive's corridor (``distance``, m), says blocked. Updates come at
    ``localization_hz`` from a random phase (one ``rng`` draw), each reading the position
    of its instant (interpolated between the two control ticks around it); with
    ``localization_hz`` 0 every tick is an update. ``state_of`` is the localized state of
    a true position (the walker adds the localization error).
    """

    def __init__(self, world: World, rng: np.random.Generator, detector: _Detector,
                 distance: float, state_of: StateOf, start: NDArray[np.float64],
                 p: PrimitiveParams) -> None:
        self.world, self.rng, self.detector, self.distance = world, rng, detector, distance
        self.state_of, self.s0 = state_of, int(state_of(start[:2]))
        self.delay, self.min_drive = p.stop_delay, p.min_drive
        self.period = 1.0 / p.localization_hz if p.localization_hz else 0.0
        self.last = (world.time, world.pose()[:2])
        self.origin = self.last[1]
        self.next_update = world.time + (self.period * float(rng.random()) if self.period
                                         else 0.0)
        self.seen: float | None = None

    def _changed(self, xy: NDArray[np.float64]) -> bool:
        if self.min_drive and self.origin is not None and float(
                np.hypot(*(xy - self.origin))) < self.min_drive:
            return False
        return int(self.state_of(xy)) != self.s0

    def _look(self, now: float, xy: NDArray[np.float64]) -> None:
        """Read the updates since the last tick; note the first that shows a change."""
        if not self.period:
            if self._changed(xy):
                self.seen = now
            return
        t0, xy0 = self.last
        while self.next_update <= now + 1e-9:
            u = self.next_update
            f = (u - t0) / (now - t0) if now > t0 else 1.0
            self.next_update += self.period
            if self._changed(xy0 + f * (xy - xy0)):
                self.seen = u
                return

    def __call__(self) -> str | None:
        world = self.world
        now, xy = world.time, world.pose()[:2]
        if self.seen is None:
            self._look(now, xy)
        self.last = (now, xy)
        if self.seen is not None and now >= self.seen + self.delay - 1e-9:
            return "state_change"
        if self.detector.blocked(world, self.rng, self.distance):
            return "detector"
        return None


def _drive(run: _Run, v: float, until: Callable[[], str | None] | None) -> tuple[str, float]:
    """Drive straight at ``v`` (m/s) holding ``run.target`` with control ticks at ``hold_hz``.

    ``until`` (until_state_change mode) is asked after every tick and returns a stop reason
    or None; the drive then lasts at most ``max_drive_time``, else ``drive_time``.
    Returns (stop reason, time driven in s).
    """
    p, target, heading, noise = run.p, run.target, run.heading, run.noise
    command, advance, tick = run.world.drive.command, run.stepper.advance, noise.tick
    hold_dt, gain = 1.0 / p.hold_hz, p.hold_gain
    noise.driving = True
    total = p.drive_time if until is None else p.max_drive_time
    remaining = total
    reason = "fixed" if until is None else "timeout"
    while remaining > 1e-9:
        dt = min(hold_dt, remaining)
        tick()
        command(v, gain * wrap_angle(target - heading()))
        advance(dt)
        remaining -= dt
        if until is not None:
            stop = until()
            if stop is not None:
                reason = stop
                break
    noise.driving = False
    return reason, total - max(remaining, 0.0)


def _brake(run: _Run) -> None:
    """Brake until at rest. "At rest" allows the few mm/s of creep that PyBullet's iterative
    solver leaves on velocity motors held at zero with 5 iterations (it shrinks with more
    iterations, at 2-4x the cost per step); over a settle it moves < 1 mm."""
    world, p, advance = run.world, run.p, run.stepper.advance
    run.noise.clear()
    world.drive.command(0.0, 0.0)
    advance(p.settle_time)
    deadline = world.time + p.settle_timeout
    while world.time < deadline:
        lin, ang = world.velocity()
        if abs(lin) < REST_SPEED and abs(ang) < REST_YAW_RATE:
            break
        advance(0.02)


def _start(world: World, action: int, rng: np.random.Generator, p: PrimitiveParams,
           stepper: ScanStepper) -> _Run:
    """The shared state of a primitive: its target heading (the action's, plus the draw of
    ``heading_noise``), the heading it steers by and its actuation noise (all drawn here, so
    before the rotation)."""
    _speed, direction = decode_action(action)
    noise = _ActuationNoise(p, rng, world.drive)
    heading: Callable[[], float] = world.yaw
    if p.heading_source != "truth":
        def heading() -> float:
            return float(world.odometry()[2])
    target = float(HEADINGS[direction])
    if p.heading_noise:
        target = float(wrap_angle(target + p.heading_noise * float(rng.standard_normal())))
    return _Run(world, stepper, p, heading, noise, target)


def execute_primitive(
    world: World,
    action: int,
    rng: np.random.Generator,
    params: PrimitiveParams | None = None,
    on_scan: ScanCallback | None = None,
    scan_beams: NDArray[np.int64] | None = None,
    *,
    state_of: StateOf | None = None,
) -> PrimitiveResult:
    """Run one primitive (rotate, check, drive, brake) in ``world``; see the module doc.

    ``rng`` draws the LIDAR noise and the actuation noise of ``params``.
    ``on_scan(scan, odometry_pose)`` is called at the LIDAR rate while the primitive runs,
    if given, with scans of the ``scan_beams`` beam indices (None: all 360).
    ``state_of(xy (2,)) -> int`` (the discretizer's state of a position, m) is required by
    ``mode = "until_state_change"``; it is applied to the true position at the control
    ticks (a stand-in for the localized pose the real robot checks).
    """
    p = params or PrimitiveParams()
    if p.mode == "until_state_change" and state_of is None:
        raise ConfigError("mode 'until_state_change' needs the discretizer's state_of",
                          key="PrimitiveParams.mode",
                          fix="pass state_of=... (collect passes its states' discretizer)")
    decode_action(action)  # a bad action fails before anything moves
    stepper = ScanStepper(world, rng, on_scan, scan_beams)
    t0, pose_before, odom_before = world.time, world.pose(), world.odometry()
    run = _start(world, action, rng, p, stepper)
    heading_error = _rotate(run)                                  # 1. rotate
    pose_turned = world.pose()
    v = p.speed_of(action)
    distance = v * p.drive_time                                   # 2. check the corridor
    detector = _Detector.of(world, p)
    blocked, scan = detector.check(world, rng, distance)
    reason, driven, reaction = "blocked", 0.0, ""
    drive = _DriveOf(run, rng, distance, state_of, pose_before)
    if not blocked:                                               # 3. drive
        reason, driven = drive(v, detector)
    if p.reacts_at_walls and reason in ("blocked", "detector"):   # 3b. react at the wall
        reason, moved, reaction = _react(drive, v)
        driven += moved
        blocked = blocked and not reaction
    _brake(run)                                                   # 4. brake
    return PrimitiveResult(
        action=int(action), blocked=blocked, pose_before=pose_before,
        pose_after=world.pose(), odom_before=odom_before, odom_after=world.odometry(),
        duration=world.time - t0, heading_error=heading_error, scan=scan,
        stop_reason=reason, drive_duration=driven, pose_turned=pose_turned,
        reaction=reaction,
    )


@dataclass(frozen=True)
class _DriveOf:
    """A straight drive of one primitive in either sense, with its stop rule: ``run`` and
    ``rng`` of the primitive, the nominal ``distance`` (m) of the detector's corridor, the
    discretizer's ``state_of`` (None in fixed mode) and the primitive's ``start`` pose."""

    run: _Run
    rng: np.random.Generator
    distance: float
    state_of: StateOf | None
    start: NDArray[np.float64]

    def __call__(self, v: float, detector: _Detector) -> tuple[str, float]:
        """Drive at ``v`` (m/s, < 0 in reverse) watched by ``detector``: (reason, s)."""
        p = self.run.p
        until = None
        if p.mode == "until_state_change" and self.state_of is not None:
            until = _StopRule(self.run.world, self.rng, detector, self.distance,
                              self.state_of, self.start, p)
        return _drive(self.run, v, until)


#: Headings a sliding robot tries, relative to the commanded one (rad; the sign of each
#: pair drawn once): the nearest first.
_SLIDE_TURNS = (math.pi / 4, math.pi / 2)


def _react(drive: _DriveOf, v: float) -> tuple[str, float, str]:
    """A refused move's reaction (``wall_slide`` / ``wall_back``, :class:`PrimitiveParams`):
    (stop reason, time driven in s, ``"slide"``/``"back"`` or ``""`` when it stayed)."""
    run, rng = drive.run, drive.rng
    p, world = run.p, run.world
    u = float(rng.random())
    if u < p.wall_slide:
        side = 1.0 if rng.random() < 0.5 else -1.0
        for turn in _SLIDE_TURNS:
            for sign in (side, -side):
                aside = dataclasses.replace(run, target=float(wrap_angle(run.target
                                                                         + sign * turn)))
                _rotate(aside)
                detector = _Detector.of(world, p)
                if not detector.check(world, rng, drive.distance)[0]:
                    reason, driven = dataclasses.replace(drive, run=aside)(v, detector)
                    return reason, driven, "slide"
        return "blocked", 0.0, ""
    if u < p.wall_slide + p.wall_back:
        behind = _Detector.of(world, p, behind=True)
        if not behind.check(world, rng, drive.distance)[0]:
            reason, driven = drive(-v, behind)
            return reason, driven, "back"
    return "blocked", 0.0, ""
