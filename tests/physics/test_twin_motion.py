"""The twin's moves like a real robot's: a stop that waits for the localization's update, a
minimum drive, a slower rotation, the reaction at a wall, and a localization error that
persists between decisions (checked against analytic bounds on the table arena)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.data.walkers import PhysicsWalker
from simlab.physics.motion import PrimitiveParams, execute_primitive, noisy_pose
from simlab.physics.world import World

FAST_RIGHT = 11  # simlab: speed 1 * 8 + RIGHT (3): +x at 0.22 m/s
BOUNDARY = -0.2  # the cells below are 0.2 m wide: x in [-0.4, -0.2) is one cell


def _cell(xy: np.ndarray) -> int:
    return math.floor(xy[0] / 0.2)


def _overshoots(params: PrimitiveParams, start_x: float, n: int, seed: int = 5
                ) -> tuple[np.ndarray, np.ndarray]:
    """(x past the boundary at rest, x driven) of ``n`` fast RIGHT drives from ``start_x``."""
    rng = np.random.default_rng(seed)
    past, driven = [], []
    with World("table") as world:
        for _ in range(n):
            world.reset((start_x, 0.0, 0.0))
            r = execute_primitive(world, FAST_RIGHT, rng, params, state_of=_cell)
            assert r.stop_reason == "state_change"
            assert _cell(r.pose_after[:2]) != _cell(r.pose_before[:2])
            past.append(r.pose_after[0] - BOUNDARY)
            driven.append(r.pose_after[0] - r.pose_turned[0])
    return np.array(past), np.array(driven)


def test_a_stop_that_waits_for_the_localization_update_comes_later_but_within_one() -> None:
    base = PrimitiveParams(mode="until_state_change", max_drive_time=3.0)
    every_tick, _ = _overshoots(base, -0.3, 6)
    rate = 2.0
    updated, _ = _overshoots(base.replace(localization_hz=rate), -0.3, 6)
    v, tick = base.fast_speed, 1.0 / base.hold_hz
    # at every tick the robot brakes within one tick of the crossing (+ a few cm braking)
    assert every_tick.max() < v * tick + 0.03
    # at 2 Hz it waits for the next update, at a random phase: later, by about v / (2 f),
    # never more than one update and one tick (+ the same braking)
    assert updated.max() < v * (1.0 / rate + tick) + 0.03
    assert updated.mean() - every_tick.mean() > 0.5 * v / (2 * rate)
    assert np.ptp(updated) > 0.02  # the phase is drawn: not one stop point


def test_a_stop_delay_adds_its_distance_at_speed() -> None:
    base = PrimitiveParams(mode="until_state_change", max_drive_time=3.0)
    now, _ = _overshoots(base, -0.3, 1)
    late, _ = _overshoots(base.replace(stop_delay=0.3), -0.3, 1)
    assert late[0] - now[0] == pytest.approx(0.3 * base.fast_speed, abs=0.025)


def test_a_minimum_drive_carries_the_robot_past_a_boundary_it_starts_at() -> None:
    base = PrimitiveParams(mode="until_state_change", max_drive_time=3.0)
    _, short = _overshoots(base, BOUNDARY - 0.01, 1)
    _, long = _overshoots(base.replace(min_drive=0.15), BOUNDARY - 0.01, 1)
    assert short[0] < 0.06
    assert long[0] >= 0.15 - 0.01


def _at_the_wall(params: PrimitiveParams) -> tuple[object, np.ndarray]:
    """A fast RIGHT move 0.15 m from the table's east wall (x = 0.75): refused."""
    with World("table") as world:
        world.reset((0.60, 0.0, 0.0))
        r = execute_primitive(world, FAST_RIGHT, np.random.default_rng(2), params)
    return r, r.pose_after - r.pose_turned


def test_a_refused_move_stays_slides_along_the_wall_or_backs_off() -> None:
    stays, d = _at_the_wall(PrimitiveParams())
    assert stays.blocked and stays.reaction == "" and np.hypot(*d[:2]) < 0.01
    slides, d = _at_the_wall(PrimitiveParams(wall_slide=1.0))
    reach = PrimitiveParams().fast_speed * PrimitiveParams().drive_time  # 0.11 m
    # +-45 degrees still hit the wall: it turns a right angle and drives along it
    assert not slides.blocked and slides.reaction == "slide"
    assert abs(d[1]) == pytest.approx(reach, abs=0.03) and abs(d[0]) < 0.03
    backs, d = _at_the_wall(PrimitiveParams(wall_back=1.0))
    assert not backs.blocked and backs.reaction == "back"
    assert d[0] == pytest.approx(-reach, abs=0.03) and abs(d[1]) < 0.02
    assert abs(backs.pose_after[2]) < 0.05  # it reverses: no turn


def test_a_slower_rotation_takes_its_time() -> None:
    rate = 0.5
    with World("table") as world:
        world.reset((0.0, 0.0, 0.0))
        quick = execute_primitive(world, 0, np.random.default_rng(1), PrimitiveParams())
        world.reset((0.0, 0.0, 0.0))
        slow = execute_primitive(world, 0, np.random.default_rng(1),
                                 PrimitiveParams(turn_rate=rate))
    # UP is a quarter turn: at 0.5 rad/s at least pi/2 / 0.5 s (minus the fine approach)
    assert slow.duration - quick.duration > (math.pi / 2 - 0.25) / rate - 0.5
    assert abs(slow.heading_error) < math.radians(2)


def _directions(params: PrimitiveParams, n: int, seed: int = 3) -> np.ndarray:
    """Direction (rad) of the drive of ``n`` fast RIGHT primitives from the table's centre."""
    rng = np.random.default_rng(seed)
    out = []
    with World("table") as world:
        for _ in range(n):
            world.reset((0.0, 0.0, 0.0))
            r = execute_primitive(world, FAST_RIGHT, rng, params)
            d = r.pose_after[:2] - r.pose_turned[:2]
            out.append(math.atan2(d[1], d[0]))
    return np.array(out)


def test_a_heading_error_spreads_the_drives_by_its_deviation() -> None:
    sd, n = 0.15, 40
    exact = _directions(PrimitiveParams(), 5)
    noisy = _directions(PrimitiveParams(heading_noise=sd), n)
    # without it the robot drives along its action (within the rotation's tolerance)
    assert np.abs(exact).max() < PrimitiveParams().heading_tolerance + 0.01
    # with it the drives spread about the action's heading as N(0, sd): the sample's
    # deviation within 35 % (three standard errors of n = 40), its mean within 3 sd/sqrt(n)
    assert abs(noisy.std(ddof=1) / sd - 1.0) < 0.35
    assert abs(noisy.mean()) < 3 * sd / math.sqrt(n)
    # drawn from the primitive's rng: the same seed, the same drives
    np.testing.assert_array_equal(noisy[:5], _directions(PrimitiveParams(heading_noise=sd), 5))


@pytest.mark.parametrize(("changes", "field"), [
    ({"pose_noise_persistence": 1.0}, "pose_noise_persistence"),
    ({"wall_slide": 1.2}, "wall_slide"),
    ({"wall_slide": 0.7, "wall_back": 0.4}, "wall_back"),
    ({"localization_hz": -1.0}, "localization_hz"),
    ({"heading_noise": 1.0}, "heading_noise"),
])
def test_the_new_fields_are_checked(changes: dict, field: str) -> None:
    with pytest.raises(ConfigError, match=field):
        PrimitiveParams(**changes)


def _errors(rho: float, n: int, seed: int = 0) -> np.ndarray:
    p = PrimitiveParams(pose_noise_xy=0.03, pose_noise_persistence=rho)
    walker = SimpleNamespace(params=p, _noise_rng=np.random.default_rng(seed),
                             _noisy_pose=noisy_pose, _error=np.zeros(3))
    walker._error = noisy_pose(np.zeros(3), p, walker._noise_rng)
    return np.array([PhysicsWalker._next_error(walker) for _ in range(n)])


def test_the_localization_error_persists_as_an_ar1_process_of_the_same_spread() -> None:
    e = _errors(0.9, 20_000)[:, 0]
    assert np.std(e) == pytest.approx(0.03, rel=0.05)
    assert np.corrcoef(e[:-1], e[1:])[0, 1] == pytest.approx(0.9, abs=0.02)
    fresh = _errors(0.0, 2_000)[:, 0]
    assert abs(np.corrcoef(fresh[:-1], fresh[1:])[0, 1]) < 0.06


def test_no_persistence_draws_the_errors_of_before() -> None:
    rng = np.random.default_rng(0)
    noisy_pose(np.zeros(3), PrimitiveParams(pose_noise_xy=0.03), rng)  # the first reading
    before = [noisy_pose(np.zeros(3), PrimitiveParams(pose_noise_xy=0.03), rng)
              for _ in range(5)]
    np.testing.assert_array_equal(_errors(0.0, 5), np.array(before))
