"""The mapping run's exploration through the DecisionDriver (issue 17) is the loop it
replaced, bit for bit, and the LIDAR's result reading is the reference one."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from discretize.occupancy import OccupancyGrid
from simlab.localization.sources import SCANLESS_POSE_SOURCES
from simlab.orchestration import mapping
from simlab.physics.arena import load_arena
from simlab.physics.motion import N_ACTIONS, PrimitiveParams, execute_primitive
from simlab.physics.world import World


def _reference_grid(minutes: float, seed: int, pose_source: str) -> tuple[OccupancyGrid, int]:
    """The exploration loop as it was before the driver: draw, execute, integrate."""
    arena = load_arena("table")
    params = PrimitiveParams()
    grid = OccupancyGrid.covering(arena.bounds, 0.01, 0.25)
    action_seq, noise_seq = np.random.SeedSequence(seed).spawn(2)
    action_rng, noise_rng = np.random.default_rng(action_seq), np.random.default_rng(noise_seq)

    def integrate(scan, odom) -> None:
        base = scan.pose if pose_source == "truth" else odom
        grid.integrate(scan.ranges, scan.angles, mapping.sensor_pose(base, scan.sensor_offset),
                       scan.range_min, scan.range_max, 0.0)

    n = 0
    with World(arena) as world:
        integrate(world.scan(noise_rng), world.odometry())
        robot_time = 0.0
        while robot_time < minutes * 60.0:
            action = int(action_rng.integers(0, N_ACTIONS))
            execute_primitive(world, action, noise_rng, params, on_scan=integrate)
            n += 1
            robot_time = world.time + n * params.decision_latency
    return grid, n


def test_exploration_matches_the_loop_it_replaced(tmp_path: Path) -> None:
    for pose_source in SCANLESS_POSE_SOURCES:
        ref, n_ref = _reference_grid(0.3, 5, pose_source)
        run = mapping.build_map("table", minutes=0.3, seed=5, out=tmp_path / pose_source,
                                pose_source=pose_source, progress=False)
        assert run.n_actions == n_ref
        assert run.n_scans == ref.n_scans
        assert run.map.content_hash() == ref.to_map().content_hash()


def test_mapping_pose_sources_are_the_shared_scanless_ones() -> None:
    assert mapping.POSE_SOURCES == SCANLESS_POSE_SOURCES


def test_lidar_reads_ray_results_as_the_reference() -> None:
    with World("table") as world:
        world.reset((0.0, -0.3, 0.3))
        rng_a, rng_b = np.random.default_rng(1), np.random.default_rng(1)
        scan = world.scan(rng_a)
        lidar = world.lidar
        pos, rot = world._link_frame()
        spec = lidar.spec
        origin = pos + rot @ lidar.offset
        dirs = lidar._dirs @ rot.T
        results = lidar._ray_batch(origin + spec.range_min * dirs, origin + spec.range_max * dirs)
        ids = np.array([h[0] for h in results], dtype=np.int64)
        ranges = spec.range_min + np.array([h[2] for h in results]) * (
            spec.range_max - spec.range_min)
        ranges = ranges + rng_b.normal(0.0, spec.noise_sigma, size=ranges.shape)
        ranges[(ids < 0) | (ranges < spec.range_min) | (ranges > spec.range_max)] = np.inf
        assert np.array_equal(scan.hit_ids, ids)
        assert np.array_equal(scan.ranges, ranges)
        assert np.isfinite(scan.ranges).sum() > 300  # a closed table: most beams return
