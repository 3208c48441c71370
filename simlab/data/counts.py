"""Import external transition-count tables (e.g. a real robot's logs).

Accepted files (one row per observed (s, a, s') triple):

* CSV with a header naming exactly the columns ``s, a, s_next, count`` (any order)::

      s,a,s_next,count
      0,3,1,12
      0,3,2,4

* JSON, either a list of objects ``[{"s": 0, "a": 3, "s_next": 1, "count": 12}, ...]``
  or an object of equal-length columns ``{"s": [...], "a": [...], "s_next": [...],
  "count": [...]}``.

Validation (a :class:`~simlab.errors.DataError` naming the file and the row): every
value a whole number (``12`` or ``12.0``, not ``12.5``, not ``true``); counts >= 0;
``s`` and ``s_next`` in ``0..S-1``, ``a`` in ``0..A-1``; unknown or missing columns.
``S`` comes from the caller (``--states`` or ``--n-states``) or, when not given, is
the largest state index + 1 (states never seen at all are then invisible).
Duplicate (s, a, s') rows are **summed** — a table concatenated from several logging
sessions naturally repeats triples — and their number is reported.
"""

from __future__ import annotations

import csv
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.data.schema import N_ACTIONS
from simlab.errors import ConfigError, DataError

COLUMNS = ("s", "a", "s_next", "count")


@dataclass(frozen=True)
class CountTable:
    """Counts n(s, a, s') read from a file.

    Attributes:
        counts: ``(S, A, S)`` int64 array.
        rows: number of data rows read.
        duplicates: rows whose (s, a, s') repeated an earlier row (summed into it).
        path: the file.
    """

    counts: NDArray[np.int64]
    rows: int
    duplicates: int
    path: Path


def _whole(value: Any, path: Path, where: str, column: str) -> int:
    if isinstance(value, bool):
        raise DataError(f"{path}: {where}: {column}: expected a whole number, got {value!r}")
    if isinstance(value, str):
        text = value.strip()
        try:
            return int(text)
        except ValueError:
            try:
                value = float(text)
            except ValueError:
                raise DataError(
                    f"{path}: {where}: {column}: expected a whole number, got {value!r}"
                ) from None
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float) and math.isfinite(value) and value.is_integer():
        return int(value)
    raise DataError(f"{path}: {where}: {column}: expected a whole number, got {value!r}")


def _check_columns(path: Path, names: list[str] | set[str], where: str) -> None:
    unknown = sorted(set(names) - set(COLUMNS))
    missing = [c for c in COLUMNS if c not in names]
    if unknown:
        raise DataError(f"{path}: {where}: unknown column(s) {unknown} (expected s, a, s_next, "
                        "count)")
    if missing:
        raise DataError(f"{path}: {where}: missing column(s) {missing}")


def _read_csv(path: Path) -> list[tuple[str, dict[str, Any]]]:
    with open(path, newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        if reader.fieldnames is None:
            raise DataError(f"{path}: empty file (expected a header s,a,s_next,count)")
        _check_columns(path, [n.strip() for n in reader.fieldnames], "header")
        rows = []
        for row in reader:
            clean = {k.strip(): v for k, v in row.items() if k is not None}
            if None in row or any(v is None for v in clean.values()):
                raise DataError(f"{path}: line {reader.line_num}: expected 4 values")
            rows.append((f"line {reader.line_num}", clean))
    return rows


def _read_json(path: Path) -> list[tuple[str, dict[str, Any]]]:
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DataError(f"{path}: not valid JSON ({exc})") from None
    rows: list[tuple[str, dict[str, Any]]] = []
    if isinstance(doc, list):
        for i, item in enumerate(doc):
            if not isinstance(item, dict):
                raise DataError(f"{path}: row {i}: expected an object with s, a, s_next, count")
            _check_columns(path, set(item), f"row {i}")
            rows.append((f"row {i}", item))
    elif isinstance(doc, dict):
        _check_columns(path, set(doc), "(top level)")
        cols = [doc[c] for c in COLUMNS]
        if not all(isinstance(c, list) for c in cols) or len({len(c) for c in cols}) != 1:
            raise DataError(f"{path}: s, a, s_next and count must be lists of equal length")
        for i in range(len(cols[0])):
            rows.append((f"row {i}", {c: doc[c][i] for c in COLUMNS}))
    else:
        raise DataError(f"{path}: expected a list of objects or an object of columns")
    return rows


def load_counts(
    path: str | os.PathLike[str],
    *,
    n_states: int | None = None,
    n_actions: int = N_ACTIONS,
) -> CountTable:
    """Read a count table (CSV or JSON, by suffix) into an ``(S, A, S)`` int64 array.

    See the module docstring for the format and the checks.
    """
    path = Path(path)
    if not path.is_file():
        raise ConfigError("counts file not found", path=path)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        raw = _read_csv(path)
    elif suffix == ".json":
        raw = _read_json(path)
    else:
        raise ConfigError(f"unknown counts file type {suffix!r}", path=path,
                          fix="use a .csv or .json file")
    if not raw:
        raise DataError(f"{path}: no rows")
    values = np.empty((len(raw), 4), dtype=np.int64)
    for i, (where, row) in enumerate(raw):
        for j, col in enumerate(COLUMNS):
            values[i, j] = _whole(row[col], path, where, col)
    s, a, s_next, count = values.T
    bad = np.flatnonzero(count < 0)
    if bad.size:
        raise DataError(f"{path}: {raw[bad[0]][0]}: count: negative count {count[bad[0]]}")
    for name, col in (("s", s), ("s_next", s_next), ("a", a)):
        neg = np.flatnonzero(col < 0)
        if neg.size:
            raise DataError(f"{path}: {raw[neg[0]][0]}: {name}: negative index {col[neg[0]]}")
    S = int(max(s.max(), s_next.max()) + 1) if n_states is None else int(n_states)
    for name, col, upper in (("s", s, S), ("s_next", s_next, S), ("a", a, n_actions)):
        over = np.flatnonzero(col >= upper)
        if over.size:
            raise DataError(
                f"{path}: {raw[over[0]][0]}: {name}: index {col[over[0]]} out of range "
                f"0..{upper - 1}"
            )
    counts = np.zeros((S, n_actions, S), dtype=np.int64)
    np.add.at(counts, (s, a, s_next), count)
    triples = s * (n_actions * S) + a * S + s_next
    duplicates = len(triples) - len(np.unique(triples))
    return CountTable(counts=counts, rows=len(raw), duplicates=int(duplicates), path=path)
