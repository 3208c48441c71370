"""The npz file of simlab's agent layer: plain numeric arrays plus one ``meta_json``.

``meta_json`` is a 0-d numpy unicode string holding JSON (with ``"format"``:
:data:`FORMAT`). Files are written atomically (:func:`simlab.base.io.atomic_write`: temporary
sibling, then rename) and read with ``allow_pickle=False``. What the arrays mean (a
Q-table, a count model, an agent) is :mod:`simlab.agents.storage`'s; the greedy policy of
a Q-table file (:mod:`simlab.agents.policy`) reads it through :func:`load_npz` too.
"""

from __future__ import annotations

import json
import os
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base import validation
from simlab.base.errors import ConfigError, DataError
from simlab.base.io import atomic_write, ensure_new, npz_problem

#: The ``format`` every file's metadata records.
FORMAT = "simlab-agents-1"


def write_npz(
    path: str | os.PathLike[str], arrays: dict[str, Any], meta: dict[str, Any], overwrite: bool
) -> Path:
    """Write ``arrays`` and ``meta`` (JSON, :data:`FORMAT` added) to ``path``, atomically;
    an existing file only with ``overwrite``."""
    path = ensure_new(path, overwrite=overwrite)
    meta = {"format": FORMAT, **meta}
    payload = {k: np.asarray(v) for k, v in arrays.items()}
    payload["meta_json"] = np.array(json.dumps(meta))
    with atomic_write(path, "wb") as fh:
        np.savez_compressed(fh, **payload)
    return path


def load_npz(
    path: str | os.PathLike[str], required: tuple[str, ...] = ()
) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Read an npz without pickle: ``(arrays, meta)``; missing ``required`` arrays raise.

    ``meta`` is the decoded ``meta_json`` (empty if absent). Raises
    :class:`DataError` for unreadable files, :class:`ConfigError` naming the
    missing arrays.
    """
    path = Path(path)
    validation.existing_file(path)
    if not zipfile.is_zipfile(path):  # numpy would say "pickled data ... load it unsafely"
        raise DataError(f"{path}: {npz_problem(path, ValueError('not a zip file'))}")
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise DataError(f"{path}: {npz_problem(path, exc)}") from exc
    missing = [k for k in required if k not in arrays]
    if missing:
        raise ConfigError(
            f"missing array(s) {', '.join(missing)}; found: {', '.join(sorted(arrays)) or 'none'}",
            path=path,
        )
    meta: dict[str, Any] = {}
    if "meta_json" in arrays:
        try:
            meta = json.loads(str(arrays.pop("meta_json")))
        except json.JSONDecodeError as exc:
            raise DataError(f"{path}: meta_json is not valid JSON ({exc})") from exc
    return arrays, meta
