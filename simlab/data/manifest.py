"""The dataset manifest: what was collected, how, and the checksum of every part.

The manifest is a JSON object (see :func:`new_manifest` for the fields). It is
rewritten atomically after every finished part, so that on disk it always lists
exactly the parts that are complete. Its ``discretizer`` entry holds the Voronoi
centres, which makes a dataset self-contained for the estimator.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from simlab.base.errors import ConfigError, DataError
from simlab.base.io import atomic_write_json
from simlab.data.schema import FORMAT_NAME, FORMAT_VERSION, MANIFEST_NAME

#: Manifest fields that must agree between a dataset on disk and a run resuming it.
RESUME_KEYS = (
    "format_version",
    "simlab_version",
    "arena",
    "robot",
    "simulator",
    "pose_source",
    "discretizer",
    "seed",
    "workers",
    "parameters",
)

#: Fields every manifest has (checked on read).
REQUIRED_KEYS = (
    "format",
    "format_version",
    "arena",
    "discretizer",
    "pose_source",
    "seed",
    "workers",
    "parameters",
    "schema",
    "parts",
)


_NUM = (int, float)

#: The ONE declared manifest schema: field -> accepted JSON types (checked on read).
#: ``bool`` is never accepted where a number is expected.
MANIFEST_SCHEMA: dict[str, tuple[type, ...]] = {
    "format": (str,),
    "format_version": (int,),
    "arena": (dict,),
    "discretizer": (dict,),
    "pose_source": (str,),
    "seed": (int,),
    "workers": (int,),
    "parameters": (dict,),
    "schema": (list,),
    "parts": (list,),
}
#: Optional manifest fields and their types, checked when present.
OPTIONAL_SCHEMA: dict[str, tuple[type, ...]] = {
    "simlab_version": (str,),
    "robot": (dict,),
    "simulator": (str,),
    "complete": (bool,),
    "worker_seeds": (list,),
    "action_set": (dict, type(None)),
}
#: Sub-fields: ``discretizer`` and ``arena`` entries the readers use.
DISCRETIZER_SCHEMA: dict[str, tuple[type, ...]] = {
    "hash": (str,), "n_states": (int,), "centres": (list,),
}
ARENA_SCHEMA: dict[str, tuple[type, ...]] = {"name": (str,)}
#: Every entry of ``parts``.
PART_SCHEMA: dict[str, tuple[type, ...]] = {
    "file": (str,), "worker": (int,), "part": (int,), "rows": (int,), "sha256": (str,),
    "t_end": _NUM,
}
#: ``schema`` entries (Arrow columns).
COLUMN_SCHEMA: dict[str, tuple[type, ...]] = {"name": (str,), "type": (str,)}


def _type_names(types: tuple[type, ...]) -> str:
    names = {int: "a whole number", float: "a number", str: "a string", dict: "an object",
             list: "a list", bool: "true or false", type(None): "null"}
    return " or ".join(dict.fromkeys(names[t] for t in types))


def _check_fields(path: Path, obj: Any, schema: Mapping[str, tuple[type, ...]], where: str,
                  *, required: bool = True) -> None:
    """Raise :class:`DataError` naming ``where.field`` for a missing or wrong-typed field."""
    if not isinstance(obj, dict):
        raise DataError(f"{path}: {where or 'manifest'}: expected an object, "
                        f"got {type(obj).__name__}")
    for key, types in schema.items():
        field = f"{where}.{key}" if where else key
        if key not in obj:
            if required:
                raise DataError(f"{path}: {field}: missing field (the manifest was edited or "
                                "damaged; collect into a new --out)")
            continue
        value = obj[key]
        wrong_bool = isinstance(value, bool) and bool not in types
        if wrong_bool or not isinstance(value, types):
            raise DataError(f"{path}: {field}: expected {_type_names(types)}, "
                            f"got {json.dumps(value)[:40]}")


def validate_manifest(manifest: Any, path: str | os.PathLike[str]) -> dict[str, Any]:
    """Check ``manifest`` against :data:`MANIFEST_SCHEMA` and its sub-schemas.

    Raises :class:`DataError` naming the file and the field: a missing or wrong-typed
    field, a part listed twice (same file, or same worker and part number: it would be
    counted twice), negative counts. Returns the manifest.
    """
    path = Path(path)
    _check_fields(path, manifest, MANIFEST_SCHEMA, "")
    _check_fields(path, manifest, OPTIONAL_SCHEMA, "", required=False)
    _check_fields(path, manifest["discretizer"], DISCRETIZER_SCHEMA, "discretizer")
    _check_fields(path, manifest["arena"], ARENA_SCHEMA, "arena")
    if manifest["workers"] < 1:
        raise DataError(f"{path}: workers: expected a whole number >= 1, "
                        f"got {manifest['workers']}")
    for i, column in enumerate(manifest["schema"]):
        _check_fields(path, column, COLUMN_SCHEMA, f"schema[{i}]")
    files: set[str] = set()
    slots: set[tuple[int, int]] = set()
    for i, entry in enumerate(manifest["parts"]):
        _check_fields(path, entry, PART_SCHEMA, f"parts[{i}]")
        for key in ("worker", "part", "rows"):
            if entry[key] < 0:
                raise DataError(f"{path}: parts[{i}].{key}: expected >= 0, got {entry[key]}")
        if entry["worker"] >= manifest["workers"]:
            raise DataError(f"{path}: parts[{i}].worker: {entry['worker']} but the dataset has "
                            f"{manifest['workers']} worker(s)")
        slot = (entry["worker"], entry["part"])
        if entry["file"] in files or slot in slots:
            raise DataError(f"{path}: parts[{i}]: part {entry['file']!r} (worker {slot[0]}, "
                            f"part {slot[1]}) is listed twice (it would be counted twice; "
                            "remove the duplicate entry)")
        files.add(entry["file"])
        slots.add(slot)
    return manifest


def file_sha256(path: str | os.PathLike[str]) -> str:
    """Hex SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def manifest_path(directory: str | os.PathLike[str]) -> Path:
    """Path of the manifest inside a dataset directory."""
    return Path(directory) / MANIFEST_NAME


def read_manifest(directory: str | os.PathLike[str]) -> dict[str, Any]:
    """Load and sanity-check ``DIR/_manifest.json``.

    Raises :class:`DataError` naming the file when it is missing, not JSON, not a
    simlab transition manifest, of another format version, or lacks a field.
    """
    path = manifest_path(directory)
    if not path.is_file():
        raise DataError(
            f"{path}: no manifest; {Path(directory)} is not a simlab transition dataset "
            "(make one with `simlab collect`)"
        )
    try:
        manifest = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise DataError(f"{path}: manifest is not valid JSON ({exc})") from None
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT_NAME:
        raise DataError(f"{path}: not a simlab transition manifest (format != {FORMAT_NAME!r})")
    if manifest.get("format_version") != FORMAT_VERSION:
        raise DataError(
            f"{path}: format_version {manifest.get('format_version')!r} is not supported "
            f"(this simlab reads version {FORMAT_VERSION})"
        )
    missing = [key for key in REQUIRED_KEYS if key not in manifest]
    if missing:
        raise DataError(f"{path}: manifest lacks the field(s) {', '.join(missing)}")
    return validate_manifest(manifest, path)


def physics_rate(manifest: Mapping[str, Any]) -> float | None:
    """The physics rate (Hz) a dataset was collected at: ``parameters.physics.hz``; for a
    physics dataset whose manifest predates that record, the rate every walk stepped at
    then (:data:`simlab.physics.rate.RECORDLESS_HZ`); None for a kinematic dataset."""
    if manifest.get("simulator", "physics") != "physics":
        return None
    record = (manifest.get("parameters") or {}).get("physics")
    if isinstance(record, Mapping) and isinstance(record.get("hz"), int | float) \
            and not isinstance(record.get("hz"), bool):
        return float(record["hz"])
    from simlab.physics.rate import RECORDLESS_HZ

    return RECORDLESS_HZ


def write_manifest(directory: str | os.PathLike[str], manifest: Mapping[str, Any]) -> None:
    """Write the manifest atomically (temporary file, fsync, rename)."""
    atomic_write_json(manifest_path(directory), manifest)


def _walk_differences(
    old: Any, new: Any, prefix: str
) -> Iterator[tuple[str, Any, Any]]:
    if isinstance(old, Mapping) and isinstance(new, Mapping):
        for key in list(old) + [k for k in new if k not in old]:
            yield from _walk_differences(old.get(key), new.get(key), f"{prefix}.{key}")
    elif isinstance(old, list) and isinstance(new, list) and len(old) == len(new):
        for i, (o, n) in enumerate(zip(old, new, strict=True)):
            yield from _walk_differences(o, n, f"{prefix}[{i}]")
    elif old != new:
        yield prefix, old, new


def _short(value: Any) -> str:
    text = json.dumps(value)
    return text if len(text) <= 60 else text[:57] + "..."


def check_resumable(
    existing: Mapping[str, Any], requested: Mapping[str, Any], directory: str | os.PathLike[str]
) -> None:
    """Raise :class:`ConfigError` naming the first field where a resume would differ.

    ``existing`` is the manifest on disk, ``requested`` the one the current run would
    write. Only the :data:`RESUME_KEYS` are compared; ``parts`` and timestamps are not.
    """
    for key in RESUME_KEYS:
        for field, old, new in _walk_differences(existing.get(key), requested.get(key), key):
            raise ConfigError(
                f"cannot resume: the dataset has {_short(old)}, this run asks for {_short(new)}",
                path=manifest_path(directory),
                key=field,
                fix="resume with the options of the original run, or collect into a new --out",
            )


def new_manifest(
    *,
    simlab_version: str,
    arena: Mapping[str, Any],
    robot: Mapping[str, Any],
    simulator: str,
    pose_source: str,
    discretizer: Mapping[str, Any],
    seed: int,
    workers: int,
    parameters: Mapping[str, Any],
    schema: list[dict[str, str]],
) -> dict[str, Any]:
    """A manifest with no parts yet.

    Fields: ``format``, ``format_version``, ``simlab_version``; ``arena`` (name, file,
    sha256, bounds, start, goals); ``robot``; ``simulator`` (``physics`` or
    ``kinematic``); ``pose_source``; ``discretizer`` (hash, n_states, centres (S, 2) in
    metres); ``seed``, ``workers``, ``worker_seeds`` (the spawned SeedSequences as
    ``{"entropy", "spawn_key"}``) and ``seed_rule`` (how part streams derive from them);
    ``parameters`` (budget, part size, primitive parameters, the physics rate and its solver
    iterations, see :func:`physics_rate`); ``schema`` (column names
    and Arrow types); ``parts`` (file, worker, part, rows, sha256, t_end, pose_end,
    final); ``complete``.
    """
    return {
        "format": FORMAT_NAME,
        "format_version": FORMAT_VERSION,
        "simlab_version": simlab_version,
        "arena": dict(arena),
        "robot": dict(robot),
        "simulator": simulator,
        "pose_source": pose_source,
        "discretizer": dict(discretizer),
        "seed": int(seed),
        "workers": int(workers),
        "worker_seeds": [{"entropy": int(seed), "spawn_key": [w]} for w in range(workers)],
        "seed_rule": (
            "part p of worker w draws from np.random.SeedSequence(seed, spawn_key=(w, p))"
            ".spawn(3) -> (actions, motion noise, pose source); this equals "
            "SeedSequence(seed).spawn(workers)[w].spawn(p + 1)[p]"
        ),
        "parameters": dict(parameters),
        "schema": schema,
        "parts": [],
        "complete": False,
    }
