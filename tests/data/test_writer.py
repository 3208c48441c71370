"""The public dataset writer: what it writes is what open_dataset reads back."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from discretize.voronoi import Discretizer
from simlab.base.actions import SIMLAB16, parse_action_set
from simlab.base.errors import ConfigError, DataError
from simlab.data.dataset import open_dataset
from simlab.data.manifest import manifest_path
from simlab.data.writer import DatasetInfo, TransitionArrays, write_dataset

CENTRES = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])


def _walk(n: int, rng: np.random.Generator, **extra) -> TransitionArrays:
    pose = np.column_stack([rng.uniform(-0.4, 1.4, n), rng.uniform(-0.4, 1.4, n),
                            rng.uniform(-3, 3, n)])
    pose_next = np.roll(pose, -1, axis=0)
    return TransitionArrays(t=np.arange(n) * 2.0, a=rng.integers(0, 8, n), pose=pose,
                            pose_next=pose_next, blocked=rng.random(n) < 0.2,
                            duration=np.full(n, 1.5), **extra)


def test_round_trip_with_states_from_centres(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    disc = Discretizer(centres=CENTRES, method="file")
    walks = [_walk(23, rng), _walk(5, rng)]
    aset = parse_action_set(8, "ccw-east")
    info = DatasetInfo(discretizer=disc, action_set=aset, pose_source="log",
                       provenance={"log": "run.txt", "note": "test"})
    res = write_dataset(tmp_path / "ds", walks, info, part_size=10)
    assert res.rows == 28
    ds = open_dataset(tmp_path / "ds")
    assert ds.action_set == aset and ds.n_actions == 8 and ds.n_states == 3
    assert ds.manifest["pose_source"] == "log" and ds.manifest["complete"] is True
    assert ds.manifest["provenance"] == {"log": "run.txt", "note": "test"}
    assert [(e["worker"], e["part"], e["rows"]) for e in ds.manifest["parts"]] == [
        (0, 0, 10), (0, 1, 10), (0, 2, 3), (1, 0, 5)]
    assert "x_true" not in ds.table.column_names
    pose = np.concatenate([w.pose for w in walks])
    np.testing.assert_array_equal(ds.column("x"), pose[:, 0])
    np.testing.assert_array_equal(ds.column("s"), disc.state_of(pose))
    np.testing.assert_array_equal(ds.column("a"), np.concatenate([w.a for w in walks]))
    np.testing.assert_array_equal(ds.column("blocked"),
                                  np.concatenate([w.blocked for w in walks]))
    np.testing.assert_array_equal(ds.column("step")[:23], np.arange(23))
    assert ds.manifest["parts"][2]["t_end"] == pytest.approx(44.0 + 1.5)


def test_given_states_are_kept_and_checked(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    base = _walk(4, rng)
    walk = TransitionArrays(t=base.t, a=base.a, pose=base.pose, pose_next=base.pose_next,
                            blocked=base.blocked, duration=base.duration,
                            s=[2, 2, 1, 0], s_next=[2, 1, 0, 0])
    info = DatasetInfo(discretizer=Discretizer(centres=CENTRES), action_set=SIMLAB16)
    write_dataset(tmp_path / "a", walk, info)
    ds = open_dataset(tmp_path / "a")
    assert ds.column("s").tolist() == [2, 2, 1, 0] and ds.action_set == SIMLAB16
    bad = TransitionArrays(t=base.t, a=base.a, pose=base.pose, pose_next=base.pose_next,
                           blocked=base.blocked, duration=base.duration, s=[0, 3, 0, 0],
                           s_next=[0, 0, 0, 0])
    with pytest.raises(ConfigError, match=r"walk 0: s: values outside 0\.\.2"):
        write_dataset(tmp_path / "b", bad, info)
    assert not (tmp_path / "b").exists() or not any((tmp_path / "b").iterdir())


def test_actions_beyond_the_action_set_are_refused(tmp_path: Path) -> None:
    walk = _walk(6, np.random.default_rng(2))
    walk = TransitionArrays(t=walk.t, a=[0, 1, 2, 9, 3, 4], pose=walk.pose,
                            pose_next=walk.pose_next, blocked=walk.blocked,
                            duration=walk.duration)
    info = DatasetInfo(discretizer=Discretizer(centres=CENTRES),
                       action_set=parse_action_set(8, "simlab"))
    with pytest.raises(ConfigError, match=r"a: values outside 0\.\.7"):
        write_dataset(tmp_path / "ds", walk, info)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"t": [0.0, 1.0, 0.5]}, "times must not decrease"),
    ({"duration": [1.0, -1.0, 1.0]}, "durations must be >= 0"),
    ({"pose": np.zeros((3, 2))}, r"transitions.pose: expected shape \(3, 3\)"),
    ({"a": [0, 1]}, r"transitions.a: expected shape \(3,\)"),
    ({"pose_next": np.full((3, 3), np.nan)}, "pose_next: values must be finite"),
])
def test_bad_arrays_name_the_field(kwargs, message: str) -> None:
    args = {"t": [0.0, 1.0, 2.0], "a": [0, 1, 2], "pose": np.zeros((3, 3)),
            "pose_next": np.zeros((3, 3)), "blocked": [False] * 3, "duration": [1.0] * 3}
    args.update(kwargs)
    with pytest.raises(ConfigError, match=message):
        TransitionArrays(**args)


def test_pose_source_rules() -> None:
    disc = Discretizer(centres=CENTRES)
    with pytest.raises(ConfigError, match="unknown pose source 'gps'"):
        DatasetInfo(discretizer=disc, pose_source="gps")


def test_simulated_pose_source_needs_truth(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    walk = _walk(5, rng)
    info = DatasetInfo(discretizer=Discretizer(centres=CENTRES), pose_source="odometry",
                       simulator="kinematic")
    with pytest.raises(ConfigError, match="needs truth poses"):
        write_dataset(tmp_path / "a", walk, info)
    truth = walk.pose + 0.01
    walk = _walk(5, np.random.default_rng(3), truth=truth, truth_next=truth[::-1])
    write_dataset(tmp_path / "b", walk, info)
    ds = open_dataset(tmp_path / "b")
    np.testing.assert_allclose(ds.column("x_true"), truth[:, 0])
    np.testing.assert_allclose(ds.column("yaw_next_true"), truth[::-1, 2])


def test_existing_output_needs_overwrite_and_is_replaced_whole(tmp_path: Path) -> None:
    rng = np.random.default_rng(4)
    info = DatasetInfo(discretizer=Discretizer(centres=CENTRES),
                       action_set=parse_action_set(8, "ccw-east"))
    write_dataset(tmp_path / "ds", [_walk(12, rng), _walk(12, rng)], info, part_size=5)
    before = manifest_path(tmp_path / "ds").read_bytes()
    with pytest.raises(ConfigError, match="not empty"):
        write_dataset(tmp_path / "ds", _walk(3, rng), info)
    assert manifest_path(tmp_path / "ds").read_bytes() == before
    write_dataset(tmp_path / "ds", _walk(3, rng), info, overwrite=True)
    ds = open_dataset(tmp_path / "ds")  # validates: no stray parts of the old dataset
    assert ds.table.num_rows == 3 and len(list((tmp_path / "ds").glob("parts/part-*"))) == 1
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("mine")
    with pytest.raises(ConfigError, match="not a dataset's"):
        write_dataset(tmp_path / "other", _walk(3, rng), info, overwrite=True)
    assert (tmp_path / "other" / "notes.txt").read_text() == "mine"


def test_manifest_without_action_set_is_simlab16_and_8_without_record_refused(
        tmp_path: Path) -> None:
    rng = np.random.default_rng(5)
    info = DatasetInfo(discretizer=Discretizer(centres=CENTRES), action_set=SIMLAB16)
    write_dataset(tmp_path / "ds", _walk(4, rng), info)
    path = manifest_path(tmp_path / "ds")
    doc = json.loads(path.read_text())
    del doc["action_set"]
    path.write_text(json.dumps(doc))
    assert open_dataset(tmp_path / "ds").action_set == SIMLAB16
    doc["parameters"]["n_actions"] = 8
    path.write_text(json.dumps(doc))
    with pytest.raises((ConfigError, DataError), match="no action_set record"):
        open_dataset(tmp_path / "ds")


def _hashes(root: Path) -> dict[str, str]:
    import hashlib

    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*"))
            if p.is_file() and ".simlab" not in str(p.relative_to(root))}


def _staging_left(root: Path) -> list[Path]:
    from simlab.base.io import STAGING_PREFIX

    return list(root.glob(f"{STAGING_PREFIX}*"))


@pytest.fixture()
def old_dataset(tmp_path: Path) -> tuple[Path, DatasetInfo, dict[str, str]]:
    info = DatasetInfo(discretizer=Discretizer(centres=CENTRES), action_set=SIMLAB16)
    write_dataset(tmp_path / "ds", _walk(7, np.random.default_rng(3)), info, part_size=3)
    return tmp_path / "ds", info, _hashes(tmp_path / "ds")


def test_an_interrupt_before_the_new_manifest_puts_the_old_dataset_back(
        old_dataset, monkeypatch) -> None:
    """Ctrl-C after the old dataset was set aside and the new parts moved in, before the new
    manifest: the old dataset is back, byte for byte, with no staging folder."""
    import simlab.data.writer as writer

    out, info, before = old_dataset
    real = writer.os.replace

    def replace(src, dst):
        if Path(dst) == manifest_path(out) and "previous" not in str(src):
            raise KeyboardInterrupt  # the new manifest's rename, the write's last step
        real(src, dst)

    monkeypatch.setattr(writer.os, "replace", replace)
    with pytest.raises(KeyboardInterrupt):
        write_dataset(out, _walk(11, np.random.default_rng(4)), info, overwrite=True)
    monkeypatch.undo()
    assert _hashes(out) == before and not _staging_left(out)
    assert open_dataset(out).column("a").size == 7


def test_a_write_killed_after_setting_the_old_dataset_aside_loses_nothing(
        old_dataset) -> None:
    """What a kill there leaves (the old dataset only in a staging folder, the new write's
    parts in ``out``): the next write puts the old one back first, so without ``overwrite``
    it is refused as any dataset is, and the dataset is whole."""
    import os

    from simlab.base.io import STAGING_PREFIX
    from simlab.data.schema import PARTS_DIR

    out, info, before = old_dataset
    stale = out / f"{STAGING_PREFIX}dead"
    (stale / "previous").mkdir(parents=True)
    os.replace(manifest_path(out), manifest_path(stale / "previous"))
    os.replace(out / PARTS_DIR, stale / "previous" / PARTS_DIR)
    (out / PARTS_DIR).mkdir()                           # the killed write's new parts
    (out / PARTS_DIR / "w000-p00000.parquet").write_bytes(b"PAR1 half")
    with pytest.raises(ConfigError, match="holds a dataset"):
        write_dataset(out, _walk(5, np.random.default_rng(5)), info)
    assert _hashes(out) == before and not _staging_left(out)


def test_an_interrupt_as_the_staging_folder_is_made_leaves_none(old_dataset,
                                                               monkeypatch) -> None:
    import simlab.data.writer as writer

    out, info, before = old_dataset
    real, made = writer.tempfile.mkdtemp, []

    def mkdtemp(*args, **kwargs):
        made.append(real(*args, **kwargs))
        raise KeyboardInterrupt

    monkeypatch.setattr(writer.tempfile, "mkdtemp", mkdtemp)
    with pytest.raises(KeyboardInterrupt):
        write_dataset(out, _walk(5, np.random.default_rng(6)), info, overwrite=True)
    assert made and not _staging_left(out) and _hashes(out) == before


def test_a_set_aside_dataset_is_never_removed_to_make_room(old_dataset) -> None:
    """A killed write's set-aside dataset, and a file of the user's in ``out`` since: the
    next write refuses the folder (not a dataset's) and the set-aside dataset stays whole
    where it waits, for the user to take back."""
    import os

    from simlab.base.io import STAGING_PREFIX
    from simlab.data.schema import PARTS_DIR

    out, info, before = old_dataset
    stale = out / f"{STAGING_PREFIX}dead"
    (stale / "previous").mkdir(parents=True)
    os.replace(manifest_path(out), manifest_path(stale / "previous"))
    os.replace(out / PARTS_DIR, stale / "previous" / PARTS_DIR)
    (out / "notes.txt").write_text("mine")
    with pytest.raises(ConfigError, match="not a dataset's"):
        write_dataset(out, _walk(5, np.random.default_rng(7)), info, overwrite=True)
    assert (out / "notes.txt").read_text() == "mine"
    assert _hashes(stale / "previous") == before
