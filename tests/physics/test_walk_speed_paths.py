"""The shortcuts of the calibration walk give the results of the long way, bit for bit.

* :class:`~simlab.physics.world.StaticClearance` is a lower bound of the distance to every
  static footprint (walls, map walls, rotated boxes, cylinders);
* a scan that :meth:`World.rays_miss` leaves out equals the cast scan (ranges, hit ids,
  pose) and leaves the Generator where the cast leaves it; the shortcut is off for a tilted
  robot whose rays reach the floor and while a body the world did not build is present;
* the detector's per-tick answer (:meth:`_Detector.blocked`) equals the full check.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from discretize.gridmap import OccupancyMap
from discretize.mapio import write_map
from simlab.physics.arena import load_arena
from simlab.physics.map_arena import arena_from_map
from simlab.physics.motion import PrimitiveParams, _Detector
from simlab.physics.obstacles import add_box, arena_with_box, remove_box
from simlab.physics.world import StaticClearance, World


def _map_arena(tmp_path: Path):
    """A 3 x 2 m map-built room with a desk and a pillar (5 cm pixels, unknown outside)."""
    occ = np.full((50, 70), -1, dtype=np.int8)
    occ[4:46, 4:66] = 100
    occ[6:44, 6:64] = 0
    occ[6:14, 20:40] = 100   # a desk against the top wall
    occ[28:32, 48:52] = 100  # a pillar
    grid = OccupancyMap(occ, 0.05, (-0.5, 0.2, 0.0))
    yaml_path, _ = write_map(tmp_path / "room.yaml", grid)
    return load_arena(arena_from_map(yaml_path, tmp_path / "room.toml"))


@pytest.fixture
def arenas(tmp_path: Path):
    rotated = arena_with_box(load_arena("table_obstacles"), 0.35, 0.4, (0.3, 0.08), yaw=0.6)
    return {"rotated box and cylinder": rotated, "map": _map_arena(tmp_path)}


def _free_poses(arena, n: int, rng: np.random.Generator, clearance: float = 0.12):
    """``n`` poses (n, 3) whose centre is at least ``clearance`` m from anything."""
    x0, y0, x1, y1 = arena.bounds
    out = []
    angles = np.linspace(0.0, 2 * math.pi, 16, endpoint=False)
    ring = clearance * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    while len(out) < n:
        xy = rng.uniform((x0, y0), (x1, y1))
        if not arena.occupied(xy + ring).any() and not arena.occupied(xy):
            out.append((xy[0], xy[1], rng.uniform(-math.pi, math.pi)))
    return np.array(out)


def test_clearance_is_a_lower_bound_of_the_distance_to_every_footprint(arenas) -> None:
    rng = np.random.default_rng(0)
    for name, arena in arenas.items():
        bound = StaticClearance(arena)
        x0, y0, x1, y1 = arena.bounds
        pts = rng.uniform((x0, y0), (x1, y1), size=(400, 2))
        positive = 0
        for p in pts:
            b = bound.at(float(p[0]), float(p[1]))
            if b <= 0:
                continue
            positive += 1
            # no point of the disc of radius b is in a wall or an obstacle
            r = b * np.sqrt(rng.random(200))
            t = rng.uniform(0, 2 * math.pi, 200)
            disc = p + np.stack([r * np.cos(t), r * np.sin(t)], axis=1)
            rim = p + b * np.stack([np.cos(t), np.sin(t)], axis=1)
            assert not arena.occupied(np.concatenate([disc, rim])).any(), (name, p, b)
        assert positive > 100, name
        assert bound.at(x1 + 0.1, y0) == 0.0  # outside the grid: no bound


def test_clearance_is_tight_within_a_cell() -> None:
    """At the table's centre the nearest wall is 0.75 m away: the bound is at most one
    cell's half-diagonal (2 cm grid) below it."""
    bound = StaticClearance(load_arena("table"))
    b = bound.at(0.0, 0.0)
    assert 0.75 - 0.02 * math.sqrt(0.5) - 1e-6 <= b <= 0.75
    assert bound.at(0.7, 0.0) == pytest.approx(0.05, abs=0.02)


def _scan_both_ways(world: World, seed: int, beams, reach):
    """The scan of World.scan and the cast of the same beams, each from its own copy of
    one Generator; returns them and the next draw of each Generator."""
    rng_a, rng_b = np.random.default_rng(seed), np.random.default_rng(seed)
    pos, rot = world._link_frame()
    pose = np.array([pos[0], pos[1], math.atan2(rot[1, 0], rot[0, 0])])
    cast = world.lidar.scan(pos, rot, pose, rng_a, stamp=world.time, beams=beams, reach=reach)
    scan = world.scan(rng_b, beams=beams, reach=reach)
    return cast, scan, rng_a.random(), rng_b.random()


def test_a_scan_left_out_equals_the_cast(arenas) -> None:
    detector_beams = _Detector.of(World("table"), PrimitiveParams()).beams
    rng = np.random.default_rng(1)
    missed = cast_needed = 0
    for arena in arenas.values():
        with World(arena) as world:
            for i, pose in enumerate(_free_poses(arena, 60, rng)):
                world.reset(pose=pose)
                world.step(2)
                for beams, reach in ((detector_beams, 0.37), (None, 0.3), (None, 1.0)):
                    miss = world.rays_miss(reach, beams)
                    cast, scan, next_a, next_b = _scan_both_ways(world, i, beams, reach)
                    np.testing.assert_array_equal(scan.ranges, cast.ranges)
                    np.testing.assert_array_equal(scan.hit_ids, cast.hit_ids)
                    np.testing.assert_array_equal(scan.angles, cast.angles)
                    np.testing.assert_array_equal(scan.pose, cast.pose)
                    assert scan.stamp == cast.stamp and next_a == next_b
                    if miss:
                        missed += 1
                        assert (cast.hit_ids == -1).all()  # nothing, not even the robot
                    else:
                        cast_needed += 1
    assert missed > 30 and cast_needed > 30, (missed, cast_needed)


def test_a_wall_behind_the_detector_s_cone_does_not_count() -> None:
    """The detector casts a +-67 degree cone of 0.37 m: backing onto a wall (0.2 m behind
    the sensor) it still sees nothing, and the shortcut knows it; facing the wall it casts."""
    detector_beams = _Detector.of(World("table"), PrimitiveParams()).beams
    with World("table") as world:
        world.reset(pose=(0.55, 0.0, math.pi))  # the wall x = 0.75 is behind
        assert not world.rays_miss(0.37)      # all beams: the wall is within reach
        assert world.rays_miss(0.37, detector_beams)
        cast, scan, next_a, next_b = _scan_both_ways(world, 0, detector_beams, 0.37)
        assert (cast.hit_ids == -1).all() and next_a == next_b
        np.testing.assert_array_equal(scan.ranges, cast.ranges)
        world.reset(pose=(0.55, 0.0, 0.0))    # facing it: it is seen
        assert not world.rays_miss(0.37, detector_beams)
        assert (world.scan(None, beams=detector_beams, reach=0.37).hit_ids >= 0).any()


def test_a_tilted_robot_whose_rays_reach_the_floor_is_cast() -> None:
    with World("table") as world:
        assert world.rays_miss(0.37)
        body = world.body
        pos, _ = world.client.getBasePositionAndOrientation(body)
        world.client.resetBasePositionAndOrientation(
            body, [pos[0], pos[1], pos[2] + 0.02],
            world.client.getQuaternionFromEuler([0.0, math.radians(40), 0.0]))
        assert not world.rays_miss(0.37)
        cast, scan, next_a, next_b = _scan_both_ways(world, 3, None, 0.37)
        assert (cast.hit_ids == world.floor).any()  # the rays do reach the floor
        np.testing.assert_array_equal(scan.ranges, cast.ranges)
        assert next_a == next_b


def test_the_shortcut_needs_a_robot_inside_the_rays_start() -> None:
    """The Burger's outline lies within 0.117 m of its LIDAR, inside the rays' 0.12 m
    start; a robot twice as wide does not, and its world never leaves a scan out."""
    import dataclasses

    from simlab.physics.lidar import LidarSpec
    from simlab.physics.world import rays_clear_robot

    with World("table") as world:
        spec = world.robot_spec
        assert rays_clear_robot(spec, world.lidar_spec) and world.rays_miss(0.37)
        x0, x1, y0, y1 = spec.footprint
        wide = dataclasses.replace(spec, footprint=(x0, x1, 2 * y0, 2 * y1))
        assert not rays_clear_robot(wide, world.lidar_spec)
        assert not rays_clear_robot(spec, LidarSpec(range_min=0.1))
    with World("table", robot=wide) as world:
        assert not world.rays_miss(0.37)


def test_a_body_the_world_did_not_build_turns_the_shortcut_off() -> None:
    with World("table") as world:
        assert world.rays_miss(0.37)
        box = add_box(world, 0.6, 0.6, (0.05, 0.05))  # far from the robot at the centre
        assert not world.rays_miss(0.37)
        remove_box(world, box)
        assert world.rays_miss(0.37)
        world.reset()  # a reset rebuilds the arena it knows: the shortcut is back
        assert world.rays_miss(0.37)


def test_the_per_tick_detector_answers_as_the_full_check(arenas) -> None:
    rng = np.random.default_rng(2)
    params = PrimitiveParams(detector_margin=0.1)
    for arena in arenas.values():
        with World(arena) as world:
            detector = _Detector.of(world, params)
            answers = set()
            for i, pose in enumerate(_free_poses(arena, 60, rng)):
                world.reset(pose=pose)
                rng_a, rng_b = np.random.default_rng(i), np.random.default_rng(i)
                blocked = detector.blocked(world, rng_a, 0.11)
                assert blocked == detector.check(world, rng_b, 0.11)[0]
                assert rng_a.random() == rng_b.random()
                answers.add(blocked)
            assert answers == {True, False}


def test_the_ray_cover_holds_every_point_of_every_ray() -> None:
    """Points at any distance <= 1 along any beam of a subset lie in one of its discs, and
    the detector's discs are smaller than the unit disc (else the cover buys nothing)."""
    with World("table") as world:
        lidar = world.lidar
        detector = _Detector.of(world, PrimitiveParams()).beams
        rng = np.random.default_rng(8)
        subsets = [detector, np.arange(10, 50), np.arange(100, 300), (detector + 90) % 360,
                   np.arange(0, 360, 9), None]
        for beams in subsets:
            cover = np.array(lidar.ray_cover(beams))
            angles = lidar.spec.angles if beams is None else lidar.spec.angles[beams]
            r = rng.random((len(angles), 50))
            r[:, 0] = 1.0  # the tips
            px, py = r * np.cos(angles)[:, None], r * np.sin(angles)[:, None]
            inside = np.zeros(px.shape, dtype=bool)
            for ux, uy, radius in cover:
                inside |= np.hypot(px - ux, py - uy) <= radius + 1e-12
            assert inside.all()
        assert max(c[2] for c in lidar.ray_cover(detector)) < 0.65
        assert lidar.ray_cover(np.arange(0, 360, 9)) == ((0.0, 0.0, 1.0),)
