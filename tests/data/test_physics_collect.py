"""Physics-backed collection (PyBullet): short walks, SIGKILL + resume, Ray vs local.

Kept to a few hundred transitions each; the 10-hour table check is a shared fixture of
the lead's suite (and is measured by benchmarks/collect_speed.py).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from discretize.voronoi import Discretizer
from simlab.data.collect import collect
from simlab.data.dataset import read_dataset
from simlab.data.manifest import read_manifest
from simlab.physics.motion import PrimitiveParams


def _columns(directory: Path) -> dict[str, np.ndarray]:
    table = read_dataset(directory)
    return {n: table.column(n).to_numpy() for n in table.column_names if n != "pose_source"}


@pytest.fixture(scope="module")
def physics_walk(tmp_path_factory: pytest.TempPathFactory, table_states_file: Path) -> Path:
    out = tmp_path_factory.mktemp("phys") / "walk"
    collect("table", table_states_file, out=out, transitions=240, seed=3, workers=1,
            part_size=80, progress=False)
    return out


def test_physics_walk_rows_are_consistent(physics_walk: Path, table_states_file: Path) -> None:
    cols = _columns(physics_walk)
    disc = Discretizer.load(table_states_file)
    assert len(cols["a"]) == 240
    np.testing.assert_array_equal(cols["s"], disc.state_of(np.c_[cols["x"], cols["y"]]))
    np.testing.assert_array_equal(cols["s_next"],
                                  disc.state_of(np.c_[cols["x_next"], cols["y_next"]]))
    # continuity, also across the part boundaries where the world is rebuilt at the pose
    np.testing.assert_allclose(cols["x"][1:], cols["x_next"][:-1], rtol=0, atol=1e-9)
    np.testing.assert_allclose(cols["y"][1:], cols["y_next"][:-1], rtol=0, atol=1e-9)
    latency = PrimitiveParams().decision_latency
    np.testing.assert_allclose(cols["t"][1:], cols["t"][:-1] + cols["duration"][:-1] + latency,
                               rtol=0, atol=1e-9)
    assert np.all(cols["duration"] > 0)
    # the robot stays on the table
    assert np.all(np.abs(cols["x_next"]) < 0.75) and np.all(np.abs(cols["y_next"]) < 0.75)


def test_physics_primitives_move_as_commanded(physics_walk: Path) -> None:
    cols = _columns(physics_walk)
    moved = np.hypot(cols["x_next"] - cols["x"], cols["y_next"] - cols["y"])
    blocked, fast = cols["blocked"], cols["a"] >= 8
    assert blocked.any() and not blocked.all()
    assert np.all(moved[blocked] < 0.01)  # a blocked primitive only turns in place
    p = PrimitiveParams()
    # unblocked primitives travel speed * drive_time (within 10 %)
    np.testing.assert_allclose(moved[~blocked & ~fast].mean(), p.slow_speed * p.drive_time,
                               rtol=0.1)
    np.testing.assert_allclose(moved[~blocked & fast].mean(), p.fast_speed * p.drive_time,
                               rtol=0.1)


def test_physics_walk_is_reproducible(tmp_path: Path, physics_walk: Path,
                                      table_states_file: Path) -> None:
    collect("table", table_states_file, out=tmp_path / "again", transitions=240, seed=3,
            workers=1, part_size=80, progress=False)
    assert read_dataset(tmp_path / "again").equals(read_dataset(physics_walk))


def _cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "simlab", *args]


@pytest.mark.slow
def test_sigkill_then_resume_equals_uninterrupted_run(tmp_path: Path,
                                                      table_states_file: Path) -> None:
    common = ["--arena", "table", "--states", str(table_states_file), "--transitions", "400",
              "--seed", "9", "--workers", "2", "--part-size", "20", "--no-progress"]
    out = tmp_path / "killed"
    proc = subprocess.Popen(_cli("collect", *common, "--out", str(out)),
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            start_new_session=True)
    try:
        # Wait (bounded, so a broken run cannot hang the suite) for the first parts.
        deadline = time.monotonic() + 300
        while len(list(out.glob("parts/part-*.parquet"))) < 3:
            if proc.poll() is not None:
                pytest.fail(f"collect ended before it could be killed: {proc.stderr.read()!r}")
            if time.monotonic() > deadline:
                pytest.fail("no parts appeared")
            time.sleep(0.05)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # the driver and its pool processes, no cleanup
        proc.wait()
        proc.stderr.close()
    manifest = read_manifest(out)
    assert not manifest["complete"] and 0 < len(manifest["parts"]) < 20

    resumed = subprocess.run(_cli("collect", *common, "--out", str(out), "--resume"),
                             capture_output=True, text=True)
    assert resumed.returncode == 0, resumed.stderr
    assert "already there" in resumed.stdout

    collect("table", table_states_file, out=tmp_path / "full", transitions=400, seed=9,
            workers=2, part_size=20, progress=False)
    assert read_dataset(out).equals(read_dataset(tmp_path / "full"))
    assert sorted(p.relative_to(out) for p in out.rglob("*")) == sorted(
        p.relative_to(tmp_path / "full") for p in (tmp_path / "full").rglob("*"))


@pytest.mark.slow
def test_ray_backend_gives_the_local_data(tmp_path: Path, table_states_file: Path) -> None:
    ray = pytest.importorskip("ray")
    options = dict(transitions=80, seed=4, workers=2, part_size=20, progress=False)
    collect("table", table_states_file, out=tmp_path / "local", backend="local", **options)
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        result = collect("table", table_states_file, out=tmp_path / "ray", backend="ray",
                         **options)
    finally:
        ray.shutdown()
    assert result.transitions == 80 and result.complete
    assert read_dataset(tmp_path / "ray").equals(read_dataset(tmp_path / "local"))
    m_local, m_ray = (json.loads((tmp_path / d / "_manifest.json").read_text())
                      for d in ("local", "ray"))
    assert [e["sha256"] for e in m_local["parts"]] == [e["sha256"] for e in m_ray["parts"]]


def _room_arena(tmp_path: Path) -> Path:
    """A 2 x 1.5 m room as a map_server map (origin (5, -2): the map frame is not centred)
    with a 0.3 m box in it, and its arena TOML."""
    from discretize.gridmap import OccupancyMap
    from discretize.mapio import write_map

    res = 0.05
    occ = np.full((40, 50), -1, dtype=np.int8)  # 2.5 x 2 m canvas
    occ[3:37, 3:47] = 100
    occ[5:35, 5:45] = 0  # free x in [5.25, 7.25), y in [-1.75, -0.25)
    occ[12:18, 30:36] = 100
    write_map(tmp_path / "room.yaml", OccupancyMap(occ, res, (5.0, -2.0, 0.0)))
    toml = tmp_path / "room.toml"
    toml.write_text('name = "room"\n[map]\nyaml = "room.yaml"\n[walls]\nheight = 0.25\n'
                    'thickness = 0.05\n[start]\npose = [5.7, -1.2, 90.0]\n'
                    '[[goals]]\nname = "g"\ncenter = [6.8, -0.6]\nradius = 0.15\n')
    return toml


def test_collect_on_a_map_arena_keeps_the_robot_in_free_space(tmp_path: Path) -> None:
    from simlab.physics.arena import load_arena

    arena = load_arena(_room_arena(tmp_path))
    xs, ys = np.meshgrid(np.linspace(5.5, 7.0, 4), np.linspace(-1.5, -0.5, 3))
    disc = Discretizer(centres=np.c_[xs.ravel(), ys.ravel()])
    out = tmp_path / "walk"
    collect(arena, disc, out=out, transitions=60, seed=2, part_size=30, progress=False)
    cols = _columns(out)
    assert len(cols["a"]) == 60
    assert (cols["x"][0], cols["y"][0]) == pytest.approx((5.7, -1.2), abs=1e-3)  # map frame
    ends = np.c_[cols["x_next"], cols["y_next"]]
    assert not arena.occupied(ends).any()
    np.testing.assert_array_equal(cols["s_next"], disc.state_of(ends))
    assert np.hypot(*(ends - [5.7, -1.2]).T).max() > 0.1  # it did move
    assert read_manifest(out)["arena"]["bounds"] == pytest.approx([5.1, -1.9, 7.4, -0.1])


def test_collect_with_candidate_parameters_is_deterministic_and_recorded(
        tmp_path: Path, table_states_file: Path) -> None:
    """The calibration engineer's call: noise fields and the until-state-change mode."""
    from simlab.physics.motion import primitive_params_from_record

    params = PrimitiveParams(mode="until_state_change", max_drive_time=2.0, wheel_noise=0.1,
                             wheel_noise_tick=0.05, slip=0.2, pose_noise_xy=0.01,
                             pose_noise_yaw=0.02, decision_latency=1.0)
    runs = []
    for name in ("a", "b"):
        collect("table", table_states_file, out=tmp_path / name, transitions=40,
                params=params, seed=5, workers=1, part_size=20, progress=False)
        runs.append(_columns(tmp_path / name))
    for key in runs[0]:
        np.testing.assert_array_equal(runs[0][key], runs[1][key])
    manifest = read_manifest(tmp_path / "a")
    assert primitive_params_from_record(manifest) == params
    assert PrimitiveParams.from_json(manifest["parameters"]["primitive"]) == params
    cols = runs[0]
    # one pose reading per pose: a transition starts where the previous reading ended
    # (within a part; a part starts with a fresh reading, from its own Generator)
    inner = cols["part"][1:] == cols["part"][:-1]
    np.testing.assert_array_equal(cols["x"][1:][inner], cols["x_next"][:-1][inner])
    assert np.any(cols["x"][1:][~inner] != cols["x_next"][:-1][~inner])
    moved = ~cols["blocked"]
    assert np.mean(cols["s"][moved] != cols["s_next"][moved]) > 0.5
