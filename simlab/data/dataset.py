"""Write dataset parts atomically; read and validate a dataset directory.

Reading goes through the manifest: only the parts it lists are read, in (worker,
part) order, and with ``validate=True`` each one is checked against it (SHA-256,
row count, column names and types, discretizer hash, index ranges). Any problem is a
:class:`~simlab.base.errors.DataError` that names the file.

Other tools read the parts directory ``DIR/parts`` (:func:`parts_path`): pyarrow, pandas,
Polars, DuckDB (``read_parquet``) and Ray Data all take that one path; see
:mod:`simlab.data.schema` for the layout and the exact calls. Datasets written before the
``parts/`` directory existed (parts directly in ``DIR``) are still read here.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from simlab.base.actions import SIMLAB16, ActionSet, action_set_from_metadata
from simlab.base.errors import DataError, warn
from simlab.base.io import atomic_write
from simlab.data.manifest import file_sha256, manifest_path, read_manifest
from simlab.data.schema import N_ACTIONS, PARTS_DIR, parse_part_name, part_file, part_name

#: Key of the Parquet schema metadata holding the discretizer hash of a part.
DISCRETIZER_META_KEY = b"simlab.discretizer"


#: Key of the Parquet schema metadata holding the columns' units and meanings (JSON).
COLUMNS_META_KEY = b"simlab.columns"


def encode_part(table: pa.Table, discretizer_hash: str) -> bytes:
    """Parquet bytes of one part (zstd), tagged with the discretizer hash and the columns'
    units and meanings (:data:`simlab.data.schema.COLUMN_DOCS`, JSON)."""
    import json

    from simlab.data.schema import COLUMN_DOCS

    docs = {n: {"unit": COLUMN_DOCS[n][0], "description": COLUMN_DOCS[n][1]}
            for n in table.column_names if n in COLUMN_DOCS}
    table = table.replace_schema_metadata({DISCRETIZER_META_KEY: discretizer_hash.encode(),
                                           COLUMNS_META_KEY: json.dumps(docs).encode()})
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink, compression="zstd")
    return sink.getvalue().to_pybytes()


def _old_layout(directory: Path) -> bool:
    """The dataset keeps its parts directly in ``directory`` (the first layout)."""
    try:
        return any(parse_part_name(name) is not None for name in os.listdir(directory))
    except FileNotFoundError:
        return False


def write_part(
    directory: str | os.PathLike[str],
    worker: int,
    part: int,
    table: pa.Table,
    discretizer_hash: str,
) -> dict[str, Any]:
    """Write one part atomically; return its manifest entry (file, worker, part, rows, sha256).

    The part goes to ``DIR/parts/`` (``file`` is the path relative to ``DIR``). Its bytes
    go to a ``.``-prefixed temporary file in ``DIR`` itself, are fsynced and renamed into
    ``parts/``, so a crash leaves either no part or a complete one and ``parts/`` never
    holds a partial file (Polars and DuckDB read every file of it). A dataset started in
    the first layout (parts directly in ``DIR``, e.g. resumed by ``collect --resume``)
    keeps it, so that its parts stay in one directory.
    """
    directory = Path(directory)
    data = encode_part(table, discretizer_hash)
    name = part_name(worker, part)
    rel = name if _old_layout(directory) else part_file(worker, part)
    with atomic_write(directory / rel, "wb", tmp_dir=directory) as fh:
        fh.write(data)
    return {
        "file": rel,
        "worker": int(worker),
        "part": int(part),
        "rows": int(table.num_rows),
        "sha256": hashlib.sha256(data).hexdigest(),
    }


def parquet_files(directory: str | os.PathLike[str]) -> list[Path]:
    """The part files of a dataset in (worker, part) order, as its manifest lists them
    (for readers that take a list of files)."""
    directory = Path(directory)
    manifest = read_manifest(directory)
    parts = sorted(manifest["parts"], key=lambda e: (int(e["worker"]), int(e["part"])))
    return [directory / str(e["file"]) for e in parts]


def parts_path(directory: str | os.PathLike[str]) -> Path:
    """The path to give pyarrow, pandas, Polars, DuckDB (``read_parquet``) and Ray Data.

    ``DIR/parts`` for datasets written by this simlab; ``DIR`` for a dataset of the first
    layout (parts directly beside the manifest: Arrow, pandas and Ray read ``DIR``, DuckDB
    and Polars need the glob ``DIR/part-*.parquet`` there). Decided from the manifest's
    ``file`` entries; a dataset with no part yet gets ``DIR/parts``.
    """
    directory = Path(directory)
    files = [str(e["file"]) for e in read_manifest(directory)["parts"]]
    if files and all("/" not in f for f in files):
        return directory
    return directory / PARTS_DIR


def unlisted_parts(directory: str | os.PathLike[str], manifest: Mapping[str, Any]) -> list[str]:
    """Part files on disk (in ``DIR`` or ``DIR/parts``) that the manifest does not list,
    as paths relative to ``DIR`` (the manifest's ``file`` spelling), sorted."""
    directory = Path(directory)
    listed = {str(e["file"]) for e in manifest["parts"]}
    found = []
    for sub in ("", PARTS_DIR):
        folder = directory / sub if sub else directory
        if not folder.is_dir():
            continue
        for name in os.listdir(folder):
            rel = f"{sub}/{name}" if sub else name
            if parse_part_name(name) is not None and rel not in listed:
                found.append(rel)
    return sorted(found)


class IncompleteDatasetWarning(UserWarning):
    """The dataset's manifest says its collect run did not finish."""


@dataclass(frozen=True)
class TransitionDataset:
    """A dataset read from disk: its manifest and all transitions as one table.

    Attributes:
        directory: the dataset directory.
        manifest: the parsed ``_manifest.json``.
        table: every transition, ordered by (worker, step); see :mod:`simlab.data.schema`.
    """

    directory: Path
    manifest: Mapping[str, Any]
    table: pa.Table

    @property
    def n_states(self) -> int:
        """Number of Markov states S of the discretizer used."""
        return int(self.manifest["discretizer"]["n_states"])

    @property
    def action_set(self) -> ActionSet | None:
        """What action ``a`` means: the manifest's ``action_set`` (:data:`SIMLAB16` if absent);
        None for a dataset of named non-primitive actions (:attr:`action_names`)."""
        if self.action_names is not None:
            return None
        return manifest_action_set(self.manifest, where=str(manifest_path(self.directory)))

    @property
    def action_names(self) -> tuple[str, ...] | None:
        """Names of the actions when they are not motion primitives (the manifest's
        ``parameters.action_names`` with ``action_set: null``), else None."""
        return manifest_action_names(self.manifest)

    @property
    def n_actions(self) -> int:
        """Number of actions A (8 or 16, or the number of :attr:`action_names`)."""
        return manifest_n_actions(self.manifest, where=str(manifest_path(self.directory)))

    @property
    def centres(self) -> np.ndarray:
        """Voronoi centres (S, 2) in metres."""
        return np.asarray(self.manifest["discretizer"]["centres"], dtype=np.float64).reshape(-1, 2)

    def warn_if_incomplete(self, use: str) -> None:
        """Warn (:class:`IncompleteDatasetWarning`) when the collect run did not finish;
        ``use`` says what is built from the finished parts only (``"the model"``)."""
        if not self.manifest.get("complete", False):
            warn(f"{self.directory}: the dataset is incomplete (a collect run was stopped); "
                 f"{use} covers only its finished parts (finish it with `simlab collect "
                 "--resume`)", IncompleteDatasetWarning)

    @property
    def discretizer_hash(self) -> str:
        """Content hash of the discretizer the states come from."""
        return str(self.manifest["discretizer"]["hash"])

    def column(self, name: str) -> np.ndarray:
        """One column as a numpy array."""
        return self.table.column(name).to_numpy()


def manifest_action_set(manifest: Mapping[str, Any], *, where: str = "manifest") -> ActionSet:
    """The action set of a dataset manifest.

    The top-level ``action_set`` record wins; manifests written before it existed are
    :data:`SIMLAB16` (their ``parameters.n_actions`` is 16), and an ``n_actions`` other
    than 16 without a record is refused (its numbering is unknown).
    """
    if manifest.get("action_set") is None:
        n = int(manifest.get("parameters", {}).get("n_actions", N_ACTIONS))
        return SIMLAB16 if n == 16 else action_set_from_metadata(None, n, where=where)
    record = manifest["action_set"]
    n = record.get("n_actions", N_ACTIONS) if isinstance(record, Mapping) else N_ACTIONS
    return action_set_from_metadata(manifest, int(n), where=where)


def manifest_action_names(manifest: Mapping[str, Any]) -> tuple[str, ...] | None:
    """``parameters.action_names`` of a manifest without an ``action_set`` record (datasets
    of non-primitive actions, e.g. the social task's 22), else None."""
    names = manifest.get("parameters", {}).get("action_names")
    if manifest.get("action_set") is not None or not isinstance(names, list) or not names:
        return None
    return tuple(str(n) for n in names)


def manifest_n_actions(manifest: Mapping[str, Any], *, where: str = "manifest") -> int:
    """Number of actions of a dataset manifest (named actions, else its action set)."""
    names = manifest_action_names(manifest)
    if names is not None:
        return len(names)
    return manifest_action_set(manifest, where=where).n_actions


def _expected_fields(manifest: Mapping[str, Any]) -> dict[str, str]:
    return {f["name"]: f["type"] for f in manifest["schema"]}


def _check_schema(path: Path, schema: pa.Schema, expected: Mapping[str, str]) -> None:
    names = schema.names
    unknown = [n for n in names if n not in expected]
    if unknown:
        raise DataError(
            f"{path}: unknown column(s) {', '.join(map(repr, unknown))} "
            f"(the manifest's schema has {', '.join(expected)})"
        )
    missing = [n for n in expected if n not in names]
    if missing:
        raise DataError(f"{path}: missing column(s) {', '.join(map(repr, missing))}")
    for field in schema:
        if str(field.type) != expected[field.name]:
            raise DataError(
                f"{path}: column {field.name!r} has type {field.type}, "
                f"the manifest says {expected[field.name]}"
            )


def _read_part(path: Path) -> pa.Table:
    try:
        return pq.read_table(path)
    except (OSError, pa.ArrowException) as exc:
        raise DataError(f"{path}: cannot read the Parquet part ({exc})") from None


def _check_values(path: Path, table: pa.Table, entry: Mapping[str, Any], n_states: int,
                  n_actions: int) -> None:
    worker = table.column("worker").to_numpy()
    part = table.column("part").to_numpy()
    if np.any(worker != entry["worker"]) or np.any(part != entry["part"]):
        raise DataError(
            f"{path}: rows belong to another worker/part than the manifest's "
            f"(worker {entry['worker']}, part {entry['part']})"
        )
    for name, upper in (("s", n_states), ("s_next", n_states), ("a", n_actions)):
        values = table.column(name).to_numpy()
        if values.size and (values.min() < 0 or values.max() >= upper):
            raise DataError(
                f"{path}: column {name!r} has values outside 0..{upper - 1} "
                f"(min {values.min()}, max {values.max()})"
            )


def validate_part(
    directory: Path, entry: Mapping[str, Any], manifest: Mapping[str, Any]
) -> pa.Table:
    """Check one listed part against the manifest and return its table (no metadata)."""
    path = directory / str(entry["file"])
    if not path.is_file():
        raise DataError(f"{path}: part listed in {manifest_path(directory).name} is missing")
    digest = file_sha256(path)
    if digest != entry["sha256"]:
        raise DataError(
            f"{path}: checksum mismatch (sha256 {digest[:12]}..., manifest "
            f"{str(entry['sha256'])[:12]}...): the part is truncated or was modified"
        )
    try:
        schema = pq.read_schema(path)
    except (OSError, pa.ArrowException) as exc:
        raise DataError(f"{path}: cannot read the Parquet part ({exc})") from None
    _check_schema(path, schema, _expected_fields(manifest))
    tag = (schema.metadata or {}).get(DISCRETIZER_META_KEY, b"").decode()
    if tag != manifest["discretizer"]["hash"]:
        raise DataError(
            f"{path}: part made with discretizer {tag[:12] or '(none)'}..., the manifest's "
            f"is {str(manifest['discretizer']['hash'])[:12]}... (a part from another dataset?)"
        )
    table = _read_part(path)
    if table.num_rows != entry["rows"]:
        raise DataError(f"{path}: {table.num_rows} rows, the manifest says {entry['rows']}")
    n_actions = manifest_n_actions(manifest, where=str(manifest_path(directory)))
    _check_values(path, table, entry, int(manifest["discretizer"]["n_states"]), n_actions)
    return table.replace_schema_metadata(None)


def _sorted_entries(manifest: Mapping[str, Any]) -> list[Mapping[str, Any]]:
    return sorted(manifest["parts"], key=lambda e: (int(e["worker"]), int(e["part"])))


def open_dataset(
    directory: str | os.PathLike[str],
    *,
    validate: bool = True,
    expected_discretizer: str | None = None,
) -> TransitionDataset:
    """Read a dataset directory: its manifest and all listed parts as one table.

    Both layouts are read: parts in ``DIR/parts/`` (current) or directly in ``DIR``
    (datasets written before it); the manifest's ``file`` entries say where.

    Args:
        directory: a directory written by :func:`simlab.data.collect.collect` or
            :func:`simlab.data.writer.write_dataset` (e.g. ``simlab import-log``).
        validate: check every part (SHA-256, rows, schema, discretizer tag, index
            ranges) and refuse ``part-*.parquet`` files (in ``DIR`` or ``DIR/parts``) the
            manifest does not list.
        expected_discretizer: if given, the content hash the dataset's discretizer must
            have (e.g. ``Discretizer.content_hash()`` of the states file in use).

    Raises:
        DataError: naming the offending file.
    """
    directory = Path(directory)
    manifest = read_manifest(directory)
    disc_hash = str(manifest["discretizer"].get("hash"))
    if expected_discretizer is not None and disc_hash != expected_discretizer:
        raise DataError(
            f"{manifest_path(directory)}: dataset made with discretizer {disc_hash[:12]}..., "
            f"expected {expected_discretizer[:12]}... (states from another map or discretizer)"
        )
    entries = _sorted_entries(manifest)
    if validate:
        stray = unlisted_parts(directory, manifest)
        if stray:
            raise DataError(
                f"{directory / stray[0]}: part not listed in the manifest (left by an interrupted "
                "run? `simlab collect --resume` finishes it)"
            )
        tables = [validate_part(directory, e, manifest) for e in entries]
    else:
        tables = [_read_part(directory / str(e["file"])).replace_schema_metadata(None)
                  for e in entries]
    if tables:
        table = pa.concat_tables(tables)
    else:
        from simlab.data.schema import transition_schema

        table = transition_schema(str(manifest["pose_source"]), twin_member=bool(
            manifest["parameters"].get("ensemble"))).empty_table()
    return TransitionDataset(directory=directory, manifest=manifest, table=table)


def read_dataset(
    directory: str | os.PathLike[str],
    validate: bool = True,
    *,
    expected_discretizer: str | None = None,
) -> pa.Table:
    """All transitions of a dataset directory as one :class:`pyarrow.Table`.

    Rows are ordered by (worker, step). See :func:`open_dataset` for the checks.
    """
    return open_dataset(
        directory, validate=validate, expected_discretizer=expected_discretizer
    ).table
