"""Dataset format: names, seeds, manifest checks, and the reader's refusals."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.dataset as pads
import pyarrow.parquet as pq
import pytest

from simlab.base.errors import ConfigError, DataError
from simlab.data.dataset import encode_part, open_dataset, read_dataset
from simlab.data.manifest import check_resumable, file_sha256, read_manifest, write_manifest
from simlab.data.schema import (
    MANIFEST_NAME,
    PARTS_DIR,
    TRUTH_COLUMNS,
    parse_part_name,
    part_name,
    transition_schema,
)
from simlab.data.walkers import part_generators


def test_part_names_sort_by_worker_then_part() -> None:
    pairs = [(w, p) for w in (0, 1, 12) for p in (0, 3, 10, 250)]
    names = [part_name(w, p) for w, p in pairs]
    assert sorted(names) == names
    assert [parse_part_name(n) for n in names] == pairs
    assert parse_part_name("part-w000-00001.parquet.tmp") is None
    assert parse_part_name(MANIFEST_NAME) is None


def test_part_streams_are_the_spawn_tree_of_the_root_seed() -> None:
    # The documented rule: part p of worker w = SeedSequence(seed).spawn(W)[w].spawn(p+1)[p].
    seed, w, p = 1234, 2, 5
    workers = np.random.SeedSequence(seed).spawn(4)
    part_seq = workers[w].spawn(p + 1)[p]
    expected = [np.random.default_rng(c).random(3) for c in part_seq.spawn(3)]
    got = [g.random(3) for g in part_generators(seed, w, p)]
    for e, g in zip(expected, got, strict=True):
        np.testing.assert_array_equal(e, g)
    # and different parts / workers get different streams
    a = part_generators(seed, 0, 0)[0].random(4)
    b = part_generators(seed, 0, 1)[0].random(4)
    c = part_generators(seed, 1, 0)[0].random(4)
    assert not np.array_equal(a, b) and not np.array_equal(a, c)


def test_schema_has_truth_columns_only_for_other_pose_sources() -> None:
    assert not set(TRUTH_COLUMNS) & set(transition_schema("truth").names)
    assert set(TRUTH_COLUMNS) <= set(transition_schema("odometry").names)
    schema = transition_schema("truth")
    for name in ("worker", "s", "a", "s_next"):
        assert schema.field(name).type == pa.int32()
    assert schema.field("blocked").type == pa.bool_()
    assert schema.field("t").type == pa.float64()


def test_directory_reads_as_one_table_with_plain_pyarrow(kinematic_dataset: Path) -> None:
    ours = read_dataset(kinematic_dataset)
    plain = pads.dataset(kinematic_dataset, format="parquet").to_table()
    assert plain.num_rows == ours.num_rows == 1500
    plain = plain.replace_schema_metadata(None).sort_by([("worker", "ascending"),
                                                         ("step", "ascending")])
    assert plain.equals(ours)


def test_check_resumable_names_the_first_differing_field(tmp_path: Path) -> None:
    old = {"seed": 1, "workers": 2, "parameters": {"part_size": 100, "hours": None}}
    new = {"seed": 1, "workers": 2, "parameters": {"part_size": 200, "hours": None}}
    with pytest.raises(ConfigError) as exc:
        check_resumable(old, new, tmp_path)
    msg = str(exc.value)
    assert "parameters.part_size" in msg and MANIFEST_NAME in msg
    assert "100" in msg and "200" in msg
    check_resumable(old, dict(old), tmp_path)  # identical: no error


def test_missing_or_foreign_manifest_is_a_data_error(tmp_path: Path) -> None:
    with pytest.raises(DataError, match="no manifest"):
        read_manifest(tmp_path)
    (tmp_path / MANIFEST_NAME).write_text("{not json")
    with pytest.raises(DataError, match="not valid JSON"):
        read_manifest(tmp_path)
    (tmp_path / MANIFEST_NAME).write_text(json.dumps({"format": "something else"}))
    with pytest.raises(DataError, match="not a simlab transition manifest"):
        read_manifest(tmp_path)


def _first_part(directory: Path) -> Path:
    return sorted((directory / PARTS_DIR).glob("part-*.parquet"))[0]


def _rewrite_part(directory: Path, path: Path, table: pa.Table, tag: str) -> None:
    """Replace a part and fix its checksum in the manifest (a consistent forgery)."""
    path.write_bytes(encode_part(table, tag))
    manifest = read_manifest(directory)
    for entry in manifest["parts"]:
        if entry["file"] == path.relative_to(directory).as_posix():
            entry["sha256"] = file_sha256(path)
            entry["rows"] = table.num_rows
    write_manifest(directory, manifest)


def test_truncated_part_is_named(dataset_copy: Path) -> None:
    part = _first_part(dataset_copy)
    data = part.read_bytes()
    part.write_bytes(data[: len(data) // 2])
    with pytest.raises(DataError) as exc:
        read_dataset(dataset_copy)
    assert str(part) in str(exc.value) and "checksum" in str(exc.value)
    # without validation the reader still names the file it cannot parse
    with pytest.raises(DataError) as exc:
        read_dataset(dataset_copy, validate=False)
    assert str(part) in str(exc.value)


def test_flipped_byte_is_detected(dataset_copy: Path) -> None:
    part = _first_part(dataset_copy)
    data = bytearray(part.read_bytes())
    data[len(data) // 3] ^= 0xFF
    part.write_bytes(bytes(data))
    with pytest.raises(DataError, match="checksum mismatch"):
        read_dataset(dataset_copy)


def test_unknown_and_missing_columns_are_named(dataset_copy: Path) -> None:
    part = _first_part(dataset_copy)
    tag = read_manifest(dataset_copy)["discretizer"]["hash"]
    table = pq.read_table(part).replace_schema_metadata(None)
    extra = table.append_column("mystery", pa.array(np.zeros(table.num_rows)))
    _rewrite_part(dataset_copy, part, extra, tag)
    with pytest.raises(DataError) as exc:
        read_dataset(dataset_copy)
    assert str(part) in str(exc.value) and "unknown column" in str(exc.value)
    assert "mystery" in str(exc.value)
    _rewrite_part(dataset_copy, part, table.drop_columns(["blocked"]), tag)
    with pytest.raises(DataError, match="missing column"):
        read_dataset(dataset_copy)


def test_part_from_another_discretizer_is_named(dataset_copy: Path) -> None:
    part = _first_part(dataset_copy)
    table = pq.read_table(part).replace_schema_metadata(None)
    _rewrite_part(dataset_copy, part, table, "0" * 64)
    with pytest.raises(DataError) as exc:
        read_dataset(dataset_copy)
    assert str(part) in str(exc.value) and "discretizer" in str(exc.value)


def test_manifest_of_another_discretizer_is_refused(kinematic_dataset: Path) -> None:
    with pytest.raises(DataError) as exc:
        read_dataset(kinematic_dataset, expected_discretizer="f" * 64)
    assert MANIFEST_NAME in str(exc.value) and "discretizer" in str(exc.value)
    disc_hash = read_manifest(kinematic_dataset)["discretizer"]["hash"]
    assert read_dataset(kinematic_dataset, expected_discretizer=disc_hash).num_rows == 1500


def test_state_out_of_range_is_named(dataset_copy: Path) -> None:
    part = _first_part(dataset_copy)
    tag = read_manifest(dataset_copy)["discretizer"]["hash"]
    table = pq.read_table(part).replace_schema_metadata(None)
    s = table.column("s").to_numpy().copy()
    s[3] = 99
    bad = table.set_column(table.schema.get_field_index("s"), table.schema.field("s"),
                           pa.array(s, type=pa.int32()))
    _rewrite_part(dataset_copy, part, bad, tag)
    with pytest.raises(DataError) as exc:
        read_dataset(dataset_copy)
    assert str(part) in str(exc.value) and "'s'" in str(exc.value)


def test_unlisted_part_file_is_refused(dataset_copy: Path) -> None:
    stray = dataset_copy / PARTS_DIR / part_name(0, 99)
    stray.write_bytes(_first_part(dataset_copy).read_bytes())
    with pytest.raises(DataError) as exc:
        read_dataset(dataset_copy)
    assert str(stray) in str(exc.value) and "not listed" in str(exc.value)


def test_missing_listed_part_is_named(dataset_copy: Path) -> None:
    part = _first_part(dataset_copy)
    part.unlink()
    with pytest.raises(DataError) as exc:
        read_dataset(dataset_copy)
    assert str(part) in str(exc.value) and "missing" in str(exc.value)


def test_dataset_object_exposes_manifest_facts(kinematic_dataset: Path) -> None:
    ds = open_dataset(kinematic_dataset)
    assert ds.n_states == 25 and ds.n_actions == 16
    assert ds.centres.shape == (25, 2)
    assert ds.discretizer_hash == read_manifest(kinematic_dataset)["discretizer"]["hash"]


# Every reader at the one documented path (DIR/parts): tests/data/test_readers.py.


def test_units_and_meanings_are_in_the_parquet_schema(kinematic_dataset: Path) -> None:
    from simlab.data.schema import COLUMN_DOCS

    path = sorted((kinematic_dataset / PARTS_DIR).glob("part-*.parquet"))[0]
    schema = pq.read_schema(path)
    for f in schema:
        assert f.metadata[b"unit"].decode() == COLUMN_DOCS[f.name][0], f.name
        assert f.metadata[b"description"]
    assert schema.field("x").metadata[b"unit"] == b"m"
    assert schema.field("yaw").metadata[b"unit"] == b"rad"
    assert schema.field("t").metadata[b"unit"] == b"s"
    docs = json.loads(schema.metadata[b"simlab.columns"])
    assert set(docs) == set(schema.names) and docs["duration"]["unit"] == "s"
