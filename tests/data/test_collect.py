"""The collection driver on the kinematic simulator: determinism, budgets, invariants,
exact resume, refusals. (Physics-backed checks live in test_physics_collect.py.)"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from simlab.base.errors import ConfigError, DataError
from simlab.base.io import exclusive_directory
from simlab.data.collect import CollectResult
from simlab.data.dataset import open_dataset, read_dataset
from simlab.data.manifest import read_manifest, write_manifest
from simlab.data.schema import MANIFEST_NAME, TRUTH_COLUMNS, part_file, part_name
from simlab.data.walkers import KinematicParams

Collect = Callable[..., CollectResult]


def _columns(directory: Path) -> dict[str, np.ndarray]:
    table = read_dataset(directory)
    return {name: table.column(name).to_numpy() for name in table.column_names
            if name != "pose_source"}


def _files(directory: Path) -> list[str]:
    """Every file and folder under ``directory``, as sorted relative paths."""
    return sorted(p.relative_to(directory).as_posix() for p in directory.rglob("*"))


def _snapshot(directory: Path) -> dict[str, tuple[bytes, int]]:
    return {p.relative_to(directory).as_posix(): (p.read_bytes(), p.stat().st_mtime_ns)
            for p in sorted(directory.rglob("*")) if p.is_file()}


def test_same_seed_same_table_other_seed_other_table(tmp_path: Path,
                                                     collect_kinematic: Collect) -> None:
    collect_kinematic(tmp_path / "a", seed=3)
    collect_kinematic(tmp_path / "b", seed=3)
    collect_kinematic(tmp_path / "c", seed=4)
    a, b, c = (read_dataset(tmp_path / n) for n in "abc")
    assert a.num_rows == 600
    assert a.equals(b)
    assert not a.column("a").equals(c.column("a"))


def test_process_pool_is_deterministic(tmp_path: Path, collect_kinematic: Collect) -> None:
    r1 = collect_kinematic(tmp_path / "a", workers=2, transitions=401)
    collect_kinematic(tmp_path / "b", workers=2, transitions=401)
    assert read_dataset(tmp_path / "a").equals(read_dataset(tmp_path / "b"))
    assert r1.transitions == 401 and r1.complete
    assert r1.peak_worker_rss_mb > 0


def test_transitions_budget_is_split_exactly(tmp_path: Path, collect_kinematic: Collect) -> None:
    result = collect_kinematic(tmp_path / "d", workers=3, transitions=1001, part_size=150)
    cols = _columns(tmp_path / "d")
    assert np.bincount(cols["worker"]).tolist() == [334, 334, 333]
    assert result.transitions == 1001 and result.complete
    manifest = read_manifest(tmp_path / "d")
    # 334 rows in parts of 150 -> 150, 150, 34
    assert [e["rows"] for e in manifest["parts"] if e["worker"] == 0] == [150, 150, 34]
    assert [e["final"] for e in manifest["parts"] if e["worker"] == 2] == [False, False, True]


def test_hours_budget_stops_each_worker_clock_at_its_share(tmp_path: Path,
                                                          collect_kinematic: Collect) -> None:
    hours, workers = 0.5, 2
    collect_kinematic(tmp_path / "h", transitions=None, hours=hours, workers=workers,
                      part_size=64)
    cols = _columns(tmp_path / "h")
    budget = hours * 3600 / workers
    latency = KinematicParams().decision_latency
    manifest = read_manifest(tmp_path / "h")
    for w in range(workers):
        m = cols["worker"] == w
        t, d = cols["t"][m], cols["duration"][m]
        assert t.max() < budget  # every primitive started within the budget
        t_end = t[-1] + d[-1] + latency
        assert t_end >= budget  # and the walk stopped only once it was spent
        last = [e for e in manifest["parts"] if e["worker"] == w][-1]
        assert last["final"] and last["t_end"] == pytest.approx(t_end, abs=0)


def test_rows_are_consistent_walks(tmp_path: Path, collect_kinematic: Collect,
                                   grid_discretizer) -> None:
    collect_kinematic(tmp_path / "w", workers=2, transitions=500, part_size=60)
    cols = _columns(tmp_path / "w")
    latency = KinematicParams().decision_latency
    xy = np.stack([cols["x"], cols["y"]], axis=1)
    xy_next = np.stack([cols["x_next"], cols["y_next"]], axis=1)
    np.testing.assert_array_equal(cols["s"], grid_discretizer.state_of(xy))
    np.testing.assert_array_equal(cols["s_next"], grid_discretizer.state_of(xy_next))
    assert cols["a"].min() >= 0 and cols["a"].max() <= 15
    for w in (0, 1):
        m = cols["worker"] == w
        np.testing.assert_array_equal(cols["step"][m], np.arange(m.sum()))
        # the clock advances by the stepped duration plus the idle decision latency
        np.testing.assert_allclose(cols["t"][m][1:],
                                   cols["t"][m][:-1] + cols["duration"][m][:-1] + latency,
                                   rtol=0, atol=1e-9)
        # each transition starts where the previous one ended, across part boundaries too
        np.testing.assert_array_equal(cols["x"][m][1:], cols["x_next"][m][:-1])
        np.testing.assert_array_equal(cols["s"][m][1:], cols["s_next"][m][:-1])
    # blocked primitives do not translate
    moved = np.hypot(cols["x_next"] - cols["x"], cols["y_next"] - cols["y"])
    assert cols["blocked"].any() and np.all(moved[cols["blocked"]] == 0)


def test_odometry_source_records_truth_columns(tmp_path: Path, collect_kinematic: Collect) -> None:
    collect_kinematic(tmp_path / "o", pose_source="odometry", transitions=300)
    table = read_dataset(tmp_path / "o")
    assert set(TRUTH_COLUMNS) <= set(table.column_names)
    assert set(table.column("pose_source").to_pylist()) == {"odometry"}
    cols = _columns(tmp_path / "o")
    drift = np.hypot(cols["x_next"] - cols["x_next_true"], cols["y_next"] - cols["y_next_true"])
    assert drift.max() > 0  # odometry is not the truth ...
    first = np.r_[True, cols["part"][1:] != cols["part"][:-1]]
    # ... but restarts from it at every part boundary
    np.testing.assert_array_equal(cols["x"][first], cols["x_true"][first])


def test_resume_after_a_crash_equals_the_uninterrupted_run(tmp_path: Path,
                                                           collect_kinematic: Collect) -> None:
    options = dict(workers=2, transitions=700, part_size=90, seed=5)
    collect_kinematic(tmp_path / "full", **options)
    crashed = tmp_path / "crashed"
    collect_kinematic(crashed, **options)
    # Simulate a run killed at different points: worker 0 lost its last three parts,
    # worker 1 wrote part 2 but died before the manifest listed it; plus stray temp files.
    manifest = read_manifest(crashed)
    keep = [e for e in manifest["parts"]
            if (e["worker"] == 0 and e["part"] < 1) or (e["worker"] == 1 and e["part"] < 2)]
    for e in manifest["parts"]:
        if e not in keep and not (e["worker"] == 1 and e["part"] == 2):
            (crashed / e["file"]).unlink()
    manifest["parts"], manifest["complete"] = keep, False
    write_manifest(crashed, manifest)
    (crashed / f".{part_name(0, 1)}.abc123.tmp").write_bytes(b"half a part")
    (crashed / f".{MANIFEST_NAME}.xyz.tmp").write_text("{")

    result = collect_kinematic(crashed, resume=True, **options)
    assert result.parts_written == result.parts - 3
    assert read_dataset(crashed).equals(read_dataset(tmp_path / "full"))
    assert _files(crashed) == _files(tmp_path / "full")
    assert read_manifest(crashed)["complete"]


def test_resume_of_a_complete_dataset_changes_nothing(tmp_path: Path,
                                                      collect_kinematic: Collect) -> None:
    collect_kinematic(tmp_path / "done")
    before = _snapshot(tmp_path / "done")
    result = collect_kinematic(tmp_path / "done", resume=True)
    assert result.parts_written == 0 and result.transitions == 600
    assert _snapshot(tmp_path / "done") == before


def test_resume_into_an_empty_directory_starts_fresh(tmp_path: Path,
                                                     collect_kinematic: Collect) -> None:
    collect_kinematic(tmp_path / "ref")
    (tmp_path / "new").mkdir()
    collect_kinematic(tmp_path / "new", resume=True)
    assert read_dataset(tmp_path / "new").equals(read_dataset(tmp_path / "ref"))


def test_resume_after_a_kill_during_the_first_manifest_write(
        tmp_path: Path, collect_kinematic: Collect) -> None:
    collect_kinematic(tmp_path / "ref")
    out = tmp_path / "new"
    out.mkdir()
    (out / f".{MANIFEST_NAME}.q1w2e3.tmp").write_text('{"format": ')
    with pytest.raises(ConfigError, match="not empty"):
        collect_kinematic(out)
    collect_kinematic(out, resume=True)
    assert read_dataset(out).equals(read_dataset(tmp_path / "ref"))
    assert _files(out) == _files(tmp_path / "ref")


def test_non_empty_directory_without_resume_is_refused(tmp_path: Path,
                                                       collect_kinematic: Collect) -> None:
    out = tmp_path / "ds"
    collect_kinematic(out)
    before = _snapshot(out)
    with pytest.raises(ConfigError) as exc:
        collect_kinematic(out, seed=99)
    assert "not empty" in str(exc.value) and "--resume" in str(exc.value)
    assert _snapshot(out) == before
    # a foreign file makes a directory non-empty too
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    with pytest.raises(ConfigError):
        collect_kinematic(other)
    assert (other / "notes.txt").read_text() == "mine"


def test_an_output_that_is_a_file_is_refused_and_kept(tmp_path: Path,
                                                     collect_kinematic: Collect) -> None:
    out = tmp_path / "ds"
    out.write_text("mine")
    with pytest.raises(ConfigError, match="not a directory") as exc:
        collect_kinematic(out)
    assert str(out) in str(exc.value)
    assert out.read_text() == "mine"


def test_a_second_collect_into_a_directory_in_use_is_refused(
        tmp_path: Path, collect_kinematic: Collect) -> None:
    out = tmp_path / "busy"
    with exclusive_directory(out):  # stands in for another collect still running there
        with pytest.raises(ConfigError, match="another process is writing") as exc:
            collect_kinematic(out)
        assert str(out) in str(exc.value)
        with pytest.raises(ConfigError, match="another process is writing"):
            collect_kinematic(out, resume=True)
        assert os.listdir(out) == []  # nothing written by the refused runs
    collect_kinematic(out)  # free again once the first run has ended
    assert read_manifest(out)["complete"]


@pytest.mark.parametrize(("change", "field"), [
    ({"seed": 8}, "seed"),
    ({"workers": 2}, "workers"),
    ({"part_size": 50}, "parameters.part_size"),
    ({"transitions": 601}, "parameters.transitions"),
    ({"pose_source": "odometry"}, "pose_source"),
])
def test_resume_with_other_options_names_the_field(tmp_path: Path, collect_kinematic: Collect,
                                                   change: dict, field: str) -> None:
    out = tmp_path / "ds"
    collect_kinematic(out, transitions=600)
    manifest = read_manifest(out)
    manifest["parts"] = manifest["parts"][:1]
    manifest["complete"] = False
    write_manifest(out, manifest)
    before = _snapshot(out)
    with pytest.raises(ConfigError) as exc:
        collect_kinematic(out, resume=True, **change)
    assert field in str(exc.value) and str(out / MANIFEST_NAME) in str(exc.value)
    assert _snapshot(out) == before


def test_resume_with_another_discretizer_is_refused(tmp_path: Path, collect_kinematic: Collect,
                                                    table_states_file: Path) -> None:
    out = tmp_path / "ds"
    collect_kinematic(out)
    with pytest.raises(ConfigError) as exc:
        collect_kinematic(out, resume=True, states=table_states_file)
    assert "discretizer" in str(exc.value) and MANIFEST_NAME in str(exc.value)


def test_resume_over_a_corrupted_part_names_it(tmp_path: Path, collect_kinematic: Collect) -> None:
    out = tmp_path / "ds"
    collect_kinematic(out)
    part = out / part_file(0, 2)
    part.write_bytes(part.read_bytes()[:100])
    before = _snapshot(out)
    with pytest.raises(DataError) as exc:
        collect_kinematic(out, resume=True)
    assert str(part) in str(exc.value)
    assert _snapshot(out) == before


@pytest.mark.parametrize(("kwargs", "key"), [
    ({"transitions": None}, "budget"),
    ({"hours": 1.0}, "budget"),
    ({"transitions": 0}, "transitions"),
    ({"transitions": None, "hours": -1.0}, "hours"),
    ({"workers": 0}, "workers"),
    ({"transitions": 3, "workers": 4}, "workers"),
    ({"seed": -1}, "seed"),
    ({"part_size": 0}, "part_size"),
    ({"backend": "slurm"}, "backend"),
    ({"simulator": "mujoco"}, "simulator"),
    ({"pose_source": "gps"}, "pose_source"),
    ({"pose_source": "mcl"}, "pose_source"),
    ({"address": "auto"}, "address"),
])
def test_bad_options_are_config_errors(tmp_path: Path, collect_kinematic: Collect,
                                       kwargs: dict, key: str) -> None:
    with pytest.raises(ConfigError) as exc:
        collect_kinematic(tmp_path / "x", **kwargs)
    assert exc.value.key == key
    assert not (tmp_path / "x").exists()  # checked before anything is written


def test_missing_states_is_explained(tmp_path: Path) -> None:
    from simlab.data.collect import collect

    with pytest.raises(ConfigError, match="states file"):
        collect("table", None, out=tmp_path / "x", transitions=10, simulator="kinematic",
                progress=False)


def test_manifest_is_self_contained(tmp_path: Path, collect_kinematic: Collect,
                                    grid_discretizer) -> None:
    collect_kinematic(tmp_path / "m", workers=2, seed=21)
    m = read_manifest(tmp_path / "m")
    assert m["discretizer"]["hash"] == grid_discretizer.content_hash()
    np.testing.assert_array_equal(np.array(m["discretizer"]["centres"]),
                                  grid_discretizer.centres)
    assert m["seed"] == 21 and m["workers"] == 2
    assert m["worker_seeds"] == [{"entropy": 21, "spawn_key": [0]},
                                 {"entropy": 21, "spawn_key": [1]}]
    assert m["arena"]["name"] == "table" and len(m["arena"]["goals"]) == 9
    assert len(m["arena"]["sha256"]) == 64
    assert m["parameters"]["primitive"]["decision_latency"] == KinematicParams().decision_latency
    assert m["simlab_version"]
    assert sum(e["rows"] for e in m["parts"]) == 600
    assert [f["name"] for f in m["schema"]] == open_dataset(tmp_path / "m").table.column_names


@pytest.mark.parametrize("value", ["fast", -0.1, float("nan")])
def test_kinematic_params_name_the_field_of_a_bad_value(value) -> None:
    """A speed that is text, negative or NaN is refused naming the field, not with a
    comparison error from Python ('>' not supported between 'str' and 'int')."""
    with pytest.raises(ConfigError, match=r"params\.fast_speed.*finite number > 0"):
        KinematicParams(fast_speed=value)
