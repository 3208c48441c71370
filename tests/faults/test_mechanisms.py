"""The one output transaction, the one lock, the one memory guard, the one manifest
schema: their contracts, tested directly."""

from __future__ import annotations

import errno
import json
from pathlib import Path

import pytest

from simlab.base.errors import ConfigError, DataError
from simlab.base.io import (
    STAGING_PREFIX,
    atomic_write_text,
    exclusive_directory,
    output_transaction,
)


def test_transaction_renames_every_file_at_the_end(tmp_path: Path) -> None:
    out = tmp_path / "o"
    with output_transaction(out, [out / "a.txt", out / "sub" / "b.txt"]) as txn:
        atomic_write_text(txn.path(out / "a.txt"), "A")
        atomic_write_text(txn.path("sub/b.txt"), "B")
        assert not (out / "a.txt").exists()  # nothing visible before the commit
    assert (out / "a.txt").read_text() == "A" and (out / "sub" / "b.txt").read_text() == "B"
    assert not list(out.glob(f"{STAGING_PREFIX}*"))


def test_a_failed_transaction_keeps_the_old_outputs_and_removes_a_new_directory(
        tmp_path: Path) -> None:
    out = tmp_path / "o"
    out.mkdir()
    (out / "a.txt").write_text("old")
    with pytest.raises(OSError), output_transaction(out, [out / "a.txt"],
                                                    overwrite=True) as txn:
        atomic_write_text(txn.path("a.txt"), "new")
        raise OSError(errno.ENOSPC, "No space left on device")
    assert (out / "a.txt").read_text() == "old"
    assert [p.name for p in out.iterdir()] == ["a.txt"]
    fresh = tmp_path / "fresh"
    with pytest.raises(KeyboardInterrupt), output_transaction(fresh, []) as txn:
        atomic_write_text(txn.path("x"), "x")
        raise KeyboardInterrupt
    assert not fresh.exists()  # a failed first run does not block the rerun


def test_transaction_refuses_before_any_work(tmp_path: Path) -> None:
    (tmp_path / "f").write_text("mine")
    with pytest.raises(ConfigError, match="not a directory"), output_transaction(tmp_path / "f"):
        raise AssertionError("not reached")
    (tmp_path / "o").mkdir()
    (tmp_path / "o" / "a").write_text("mine")
    with pytest.raises(ConfigError, match="--overwrite"), \
            output_transaction(tmp_path / "o", [tmp_path / "o" / "a"]):
        raise AssertionError("not reached")
    with exclusive_directory(tmp_path / "o"), pytest.raises(ConfigError, match="another"), \
            output_transaction(tmp_path / "o", []):
        raise AssertionError("not reached")
    assert (tmp_path / "o" / "a").read_text() == "mine"


def test_a_killed_transaction_leaves_staging_that_the_next_one_removes(tmp_path: Path) -> None:
    out = tmp_path / "o"
    stale = out / f"{STAGING_PREFIX}dead"
    stale.mkdir(parents=True)
    (stale / "half.npz").write_bytes(b"\0" * 10)
    with output_transaction(out, [out / "a"]) as txn:
        atomic_write_text(txn.path("a"), "A")
    assert sorted(p.name for p in out.iterdir()) == ["a"]


def test_transaction_paths_stay_inside(tmp_path: Path) -> None:
    with output_transaction(tmp_path / "o") as txn, pytest.raises(ValueError):
        txn.path("../escape")


def test_memory_guard_names_the_field_and_the_figure(monkeypatch) -> None:
    from simlab.base.guards import array_bytes, check_memory, memory_budget

    monkeypatch.setenv("SIMLAB_MEMORY_LIMIT", "1G")
    assert memory_budget() == 1 << 30
    check_memory(array_bytes((1000, 1000)), what="a small table")  # 8 MB: fine
    with pytest.raises(ConfigError, match=r"grid: a 1e\+05 grid needs about 74\.5 GiB"):
        check_memory(array_bytes((1e5, 1e5)), what="a 1e+05 grid", key="grid")
    with pytest.raises(ConfigError, match="needs about"):
        check_memory(float("inf"), what="an infinite request")
    monkeypatch.setenv("SIMLAB_MEMORY_LIMIT", "lots")
    with pytest.raises(ConfigError, match="SIMLAB_MEMORY_LIMIT"):
        memory_budget()


def test_memory_guard_protects_the_occupancy_grid(monkeypatch) -> None:
    from discretize.occupancy import OccupancyGrid

    monkeypatch.setenv("SIMLAB_MEMORY_LIMIT", "100M")
    OccupancyGrid.covering((-0.75, -0.75, 0.75, 0.75), 0.01)  # the table: ~0.1 MB
    with pytest.raises(ConfigError, match="resolution: a 200050 x 200050 occupancy grid"):
        OccupancyGrid.covering((-1000, -1000, 1000, 1000), 0.01)


def test_manifest_schema_catches_duplicates_and_types(tmp_path: Path, inputs) -> None:
    from simlab.data.manifest import read_manifest, validate_manifest

    m = read_manifest(inputs.dataset)
    validate_manifest(m, "x")
    dup = json.loads(json.dumps(m))
    dup["parts"].append({**dup["parts"][0], "file": "other.parquet"})  # same worker, part
    with pytest.raises(DataError, match=r"parts\[3\]: .* listed twice"):
        validate_manifest(dup, "x")
    bad = json.loads(json.dumps(m))
    bad["parts"][0]["t_end"] = "late"
    with pytest.raises(DataError, match=r"parts\[0\]\.t_end: expected a whole number or a"):
        validate_manifest(bad, "x")


def test_states_fingerprint_and_arena_checks(inputs) -> None:
    from discretize.voronoi import Discretizer
    from simlab.base.statecheck import check_centres_in_arena, check_states_hash, npz_states_hash
    from simlab.physics.arena import load_arena

    table = load_arena("table")
    disc = Discretizer.load(inputs.states)
    assert check_centres_in_arena(disc.centres, table) == 0
    with pytest.raises(ConfigError, match="24 of 25 state centres"):
        check_centres_in_arena(Discretizer.load(inputs.other_states).centres, table)
    few = disc.centres.copy()
    few[0] = (5.0, 5.0)  # 1 of 25 off the table: a warning only
    with pytest.warns(UserWarning, match="1 of 25"):
        assert check_centres_in_arena(few, table) == 1
    assert npz_states_hash(inputs.mdp) == disc.content_hash()
    q_file = next(inputs.qtables.glob("q_*.npz"))
    from simlab.agents.storage import load_q_table

    assert load_q_table(q_file)[1]["states_hash"] == disc.content_hash()
    check_states_hash(None, "abc", what="old file")  # files without one are not checked
    with pytest.raises(ConfigError, match="states_hash"):
        check_states_hash("abc", "abd", what="the MDP")


def test_same_seed_same_outputs(tmp_path: Path, inputs, capsys) -> None:
    import numpy as np

    from .conftest import run_cli

    arrays = []
    for name in ("a", "b"):
        res = run_cli(f"train --mdp {inputs.mdp} --episodes 3 --runs 2 --seed 4 --no-plots "
                      f"--out {tmp_path / name} --no-progress".split(), capsys)
        assert res.code == 0, res.stderr
        with np.load(tmp_path / name / "curves.npz", allow_pickle=False) as z:
            arrays.append({k: z[k].copy() for k in ("rewards", "curve_mean")})
        q_files = sorted((tmp_path / name).glob("q_*.npz"))
        with np.load(q_files[0], allow_pickle=False) as z:
            arrays[-1]["Q"] = z["Q"].copy()
    for key in arrays[0]:
        np.testing.assert_array_equal(arrays[0][key], arrays[1][key])
