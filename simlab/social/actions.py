"""The robot's social actions in physics (thesis Table 2.1-2.3, 2.1.2).

Action space of the physics social task, :class:`SocialAction` (22 actions):

* ``0-15`` the 16 motion primitives as everywhere in simlab (``speed * 8 + direction``,
  :mod:`simlab.physics.motion`);
* ``16 STAY`` — the robot idles one decision (``signal_time`` s);
* ``17 LOOK_H`` — rotates in place to face the human (:func:`turn_to`, the same
  open-loop bulk + square-root closed-loop profile as the primitives' rotation, re-stated
  here because that one is private to the motion layer);
* ``18 HELLO``, ``19 COME``, ``20 POINTING`` — signals: the robot stands still for
  ``signal_time`` s (its decision time) and the human's attention changes by the social
  module's rules (:mod:`simlab.social.task`);
* ``21 GO_TO_HUMAN`` — an option: drives with the motion primitives to a point in the
  human's facing field (:func:`go_to_point`), then turns to face the human.

Grid Q-tables (30 actions, :mod:`simlab.visitlab.actions`) are read through
:data:`GRID_ACTION`: the grid action each physics action stands for. Decision: a slow
primitive (0.05 m) is the grid's speed-1 move and a fast one (0.11 m) the speed-2 move
(order-preserving; both are under one 0.15 m cell, so no physics action stands for speed 3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.base.actions import HEADINGS
from simlab.physics.motion import N_ACTIONS, PrimitiveParams, ScanStepper, action_index
from simlab.physics.robot import wrap_angle
from simlab.social.perception import bearing, quantise_direction
from simlab.social.planning import plan_path


class SocialAction(IntEnum):
    """Non-motion actions of the physics social task (0-15 are the primitives)."""

    STAY = N_ACTIONS
    LOOK_H = N_ACTIONS + 1
    HELLO = N_ACTIONS + 2
    COME = N_ACTIONS + 3
    POINTING = N_ACTIONS + 4
    GO_TO_HUMAN = N_ACTIONS + 5


N_SOCIAL_ACTIONS = N_ACTIONS + 6
SIGNALS = (SocialAction.HELLO, SocialAction.COME, SocialAction.POINTING)


def _grid_move(direction: int, speed: int) -> int:
    # the grid's action numbering (thesis Table 2.1; simlab.visitlab.actions.move_action)
    base = direction if direction < 4 else 12 + direction - 4
    return base + 4 * (speed - 1)


#: Grid action (0-29) each physics social action stands for, int64 shape (22,).
GRID_ACTION: NDArray[np.int64] = np.array(
    [_grid_move(a % 8, 1 + a // 8) for a in range(N_ACTIONS)] + [24, 25, 26, 27, 28, 29],
    dtype=np.int64,
)
GRID_ACTION.flags.writeable = False


def grid_q_to_physics(q_grid: NDArray[np.float64]) -> NDArray[np.float64]:
    """Columns of a grid social Q-table ``(2560, 30)`` for the physics actions:
    ``(2560, 22)`` (the states are the same index, :mod:`simlab.social.perception`)."""
    q = np.asarray(q_grid)
    if q.ndim != 2 or q.shape[1] != 30:
        raise ValueError(f"expected a (S, 30) grid Q-table, got shape {q.shape}")
    return q[:, GRID_ACTION]


def turn_to(world: Any, target: float, params: PrimitiveParams,
            stepper: ScanStepper) -> float:
    """Rotate in place to the map-frame heading ``target`` (rad); returns the time
    stepped (s). Bulk at ``w_max`` open loop, then closed loop at ``fine_hz`` with a
    square-root profile to ``heading_tolerance``, then a brake of ``settle_time``."""
    p, drive = params, world.drive
    t0 = world.time
    w_max = world.robot_spec.w_max
    err = float(wrap_angle(target - world.yaw()))
    bulk = abs(err) - 0.25
    if bulk > 0:
        drive.command(0.0, math.copysign(w_max, err))
        stepper.advance(bulk / w_max)
        err = float(wrap_angle(target - world.yaw()))
    fine_dt = 1.0 / p.fine_hz
    deadline = world.time + p.turn_timeout
    while abs(err) > p.heading_tolerance and world.time < deadline:
        rate = max(p.min_turn_rate, math.sqrt(2.0 * p.turn_decel * abs(err)))
        rate = min(rate, w_max, abs(err) / fine_dt)
        drive.command(0.0, math.copysign(rate, err))
        stepper.advance(fine_dt)
        err = float(wrap_angle(target - world.yaw()))
    drive.command(0.0, 0.0)
    stepper.advance(p.settle_time)
    return world.time - t0


def human_in_corridor(robot_xy: NDArray[np.float64], heading: float, action: int,
                      human_xy: NDArray[np.float64], human_radius: float, spec: Any,
                      params: PrimitiveParams) -> bool:
    """Whether the human's disc meets the obstacle detector's corridor of ``action``
    driven along ``heading`` (rad) from ``robot_xy``: the rectangle, in the robot frame,
    from the robot's origin to ``x_max + distance + detector_margin`` ahead and
    ``detector_side_margin`` wider than the footprint (:mod:`simlab.physics.motion`).
    The human has no PyBullet body, so this stands in for the LIDAR returns of its legs."""
    c, s = math.cos(heading), math.sin(heading)
    dx, dy = float(human_xy[0]) - float(robot_xy[0]), float(human_xy[1]) - float(robot_xy[1])
    lx, ly = c * dx + s * dy, -s * dx + c * dy
    _, x_max, y_min, y_max = spec.footprint
    x1 = x_max + params.nominal_distance(action) + params.detector_margin
    y0, y1 = y_min - params.detector_side_margin, y_max + params.detector_side_margin
    qx, qy = min(max(lx, 0.0), x1), min(max(ly, y0), y1)
    return math.hypot(lx - qx, ly - qy) <= human_radius


def execute_social_primitive(driver: Any, action: int, rng: np.random.Generator,
                             human_xy: NDArray[np.float64] | None = None,
                             human_radius: float = 0.0) -> tuple[float, bool]:
    """Run motion primitive ``action`` with ``driver``; returns (seconds stepped, blocked).

    If the human's disc is in the detector's corridor of the primitive's heading
    (:func:`human_in_corridor`) the robot only turns to the heading and the primitive is
    blocked, as the real detector would be by a person in front of the robot.
    """
    world = driver.world
    if human_xy is not None:
        heading = float(HEADINGS[action % 8])
        if human_in_corridor(world.pose()[:2], heading, action, human_xy, human_radius,
                             world.robot_spec, driver.params):
            stepper = ScanStepper(world, rng, getattr(driver, "on_scan", None),
                                  getattr(driver, "scan_beams", None))
            t = turn_to(world, heading, driver.params, stepper)
            driver.observe()
            return t, True
    res = driver.execute(action, rng).result
    return float(res.duration), bool(res.blocked)


@dataclass(frozen=True)
class OptionResult:
    """Outcome of GO_TO_HUMAN's drive: ``primitives`` executed, ``duration`` stepped (s),
    ``blocked`` (the obstacle detector stopped it), ``reached`` (within tolerance)."""

    primitives: int
    duration: float
    blocked: bool
    reached: bool


def go_to_point(driver: Any, target_xy: NDArray[np.float64], rng: np.random.Generator,
                tolerance: float, max_primitives: int,
                human_xy: NDArray[np.float64] | None = None,
                human_radius: float = 0.0) -> OptionResult:
    """Drive the robot of ``driver`` (a :class:`~simlab.physics.driver.DecisionDriver`) to
    within ``tolerance`` m of ``target_xy`` with motion primitives.

    Each primitive heads along the direction (of the 8) nearest the bearing to the target,
    fast while the target is farther than the fast primitive's distance, else slow (each
    such move shortens the distance, the direction being at most 22.5 deg off). Stops when
    reached, blocked or after ``max_primitives``. Decision: the primitives of an option do
    not pay the decision latency (the option is one decision of the social module).

    The path is planned (:func:`simlab.social.planning.plan_path`) around the arena's
    obstacles, kept ``clearance`` m away: the front of the footprint plus a slow
    primitive's detector corridor (so the obstacle detector does not stop the robot at a
    waypoint near an obstacle). With ``human_xy`` the human's disc is an obstacle too, and
    it blocks primitives like one (:func:`execute_social_primitive`). Without a path the
    robot heads straight for the target.
    """
    world, p = driver.world, driver.params
    fast_dist = p.nominal_distance(action_index(1, 0))
    spec = world.robot_spec
    clearance = spec.footprint[1] + p.nominal_distance(action_index(0, 0)) \
        + p.detector_margin + 0.01
    discs = [] if human_xy is None else [(np.asarray(human_xy, dtype=float)[:2],
                                          human_radius)]
    target = np.asarray(target_xy, dtype=float)
    goals = plan_path(world.arena, world.pose()[:2], target, clearance, discs=discs)
    if goals is None:
        goals = [target]
    n, duration, blocked = 0, 0.0, False
    while n < max_primitives and goals:
        xy = world.pose()[:2]
        d = math.hypot(goals[0][0] - xy[0], goals[0][1] - xy[1])
        if d <= tolerance:
            goals.pop(0)
            continue
        direction = quantise_direction(bearing(xy, goals[0]))
        action = action_index(1 if d > fast_dist else 0, direction)
        t, blocked = execute_social_primitive(driver, action, rng, human_xy, human_radius)
        n += 1
        duration += t
        if blocked:
            break
    xy = world.pose()[:2]
    reached = math.hypot(target_xy[0] - xy[0], target_xy[1] - xy[1]) <= tolerance
    return OptionResult(primitives=n, duration=duration, blocked=blocked, reached=reached)

