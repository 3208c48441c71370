"""Import external transition-count tables (e.g. a real robot's logs).

Accepted files (one row per observed (s, a, s') triple):

* CSV with a header naming exactly the columns ``s, a, s_next, count`` (any order)::

      s,a,s_next,count
      0,3,1,12
      0,3,2,4

* JSON, either a list of objects ``[{"s": 0, "a": 3, "s_next": 1, "count": 12}, ...]``
  or an object of equal-length columns ``{"s": [...], "a": [...], "s_next": [...],
  "count": [...]}``.

* The transition-model JSON published by the ISIR group (``format = "isir"``)::

      {"transitionActions": [
          {"state": 0, "transitions": [{"action": 2, "state": 1, "prob": 12}, ...]},
          ...],
       "actioncount": ..., "timecount": ...}

  Despite its name ``prob`` holds **counts**. ``actioncount`` and ``timecount`` are kept
  verbatim in :attr:`CountTable.metadata` (their meaning is the publisher's; simlab does
  not interpret them). Other top-level keys are kept there too.

The type is chosen by suffix (``.csv``, ``.json``); any other name (notably a file
without extension, as the ISIR files are published) is **sniffed**: a file whose first
non-blank character is ``[`` or ``{`` is JSON, anything else CSV.

Validation (a :class:`CountsFileError`, both a :class:`~simlab.base.errors.ConfigError` and a
:class:`~simlab.base.errors.DataError`, naming the file, the row and the field): UTF-8 text;
every value a whole number (``12`` or ``12.0``, not ``12.5``, not ``true``) within int64;
counts >= 0; ``s`` and ``s_next`` in ``0..S-1``, ``a`` in ``0..A-1``; unknown or missing
columns/fields; an empty file. ``S`` comes from the caller (``--states`` or
``--n-states``) or, when not given, is the largest state index + 1 (states never seen at
all are then invisible). The table is dense ``(S, A, S)``: one larger than
:data:`MAX_TABLE_BYTES` is refused with its size before anything is allocated (a stray
huge index must not exhaust memory).
Duplicate (s, a, s') rows are **summed** — a table concatenated from several logging
sessions naturally repeats triples — counted in :attr:`CountTable.duplicates` and
reported with a :class:`DuplicateRowsWarning`.

The table is ActionSet-independent: ``n_actions`` (8 or 16) only sizes it; what action
``a`` means is attached by the caller (:mod:`simlab.base.actions`).
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.base import validation
from simlab.base.errors import ConfigError, DataError, warn
from simlab.base.io import NESTED_TOO_DEEPLY
from simlab.data.schema import N_ACTIONS

COLUMNS = ("s", "a", "s_next", "count")
#: Largest dense ``(S, A, S)`` int64 table :func:`load_counts` allocates (bytes).
MAX_TABLE_BYTES = 1 << 30
_INT64_MAX = int(np.iinfo(np.int64).max)
_INT64_MIN = int(np.iinfo(np.int64).min)
#: ISIR field -> simlab column, per level.
_ISIR_STATE_FIELDS = ("state", "transitions")
_ISIR_TRANSITION_FIELDS = ("action", "state", "prob")


class CountsFileError(ConfigError, DataError):
    """A counts file is unreadable or holds a bad value (names file, row and field)."""


class DuplicateRowsWarning(UserWarning):
    """Some (s, a, s') rows of a counts file repeated earlier ones and were summed."""


def _bad(path: Path, where: str, problem: str, fix: str | None = None) -> CountsFileError:
    return CountsFileError(problem, path=path, key=where or None, fix=fix)


@dataclass(frozen=True)
class CountTable:
    """Counts n(s, a, s') read from a file.

    Attributes:
        counts: ``(S, A, S)`` int64 array.
        rows: number of data rows read.
        duplicates: rows whose (s, a, s') repeated an earlier row (summed into it).
        path: the file.
        format: ``"csv"``, ``"json-rows"``, ``"json-columns"`` or ``"isir"``.
        metadata: extra top-level fields of the file (ISIR: ``actioncount``,
            ``timecount``, verbatim); empty for the other formats.
    """

    counts: NDArray[np.int64]
    rows: int
    duplicates: int
    path: Path
    format: str = "csv"
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def n_states(self) -> int:
        """S."""
        return int(self.counts.shape[0])

    @property
    def n_actions(self) -> int:
        """A (8 or 16)."""
        return int(self.counts.shape[1])


#: Longest number text read (digits and sign): int64 has 19 digits; Python refuses to read
#: integers beyond 4300 digits anyway (CVE-2020-10735), with a message about its own limit.
_MAX_DIGITS = 40


class _LongNumber(str):
    """A JSON integer too long to be a count (its text, kept for the message)."""


def _parse_json_int(text: str) -> int | _LongNumber:
    return _LongNumber(text) if len(text) > _MAX_DIGITS else int(text)


def _shown(value: Any) -> str:
    """``repr(value)``, shortened to 40 characters."""
    text = repr(value)
    return text if len(text) <= 40 else f"{text[:20]}...{text[-10:]} ({len(text)} characters)"


def _whole(value: Any, path: Path, key: str) -> int:

    def bad() -> CountsFileError:
        return _bad(path, key, f"expected a whole number, got {_shown(value)}")

    if isinstance(value, _LongNumber) or (isinstance(value, str)
                                          and len(value.strip()) > _MAX_DIGITS
                                          and value.strip().lstrip("+-").isdigit()):
        raise _bad(path, key, f"a {len(value.strip().lstrip('+-'))}-digit number does not fit "
                   "a 64-bit integer", fix="counts and indices are whole numbers below 2**63")
    if isinstance(value, bool):
        raise bad()
    if isinstance(value, str):
        text = value.strip()
        try:
            value = int(text)
        except ValueError:
            try:
                value = float(text)
            except ValueError:
                raise bad() from None
    if isinstance(value, float):
        if not (math.isfinite(value) and value.is_integer()):
            raise bad()
        value = int(value)
    if not isinstance(value, int):
        raise bad()
    if not _INT64_MIN <= value <= _INT64_MAX:
        raise _bad(path, key, f"{value} does not fit a 64-bit integer")
    return int(value)


def _check_columns(path: Path, names: list[str] | set[str], where: str) -> None:
    unknown = sorted(set(names) - set(COLUMNS))
    missing = [c for c in COLUMNS if c not in names]
    if unknown:
        raise _bad(path, where, f"unknown column(s) {unknown} (expected s, a, s_next, count)")
    if missing:
        raise _bad(path, where, f"missing column(s) {missing}")


#: ``(row label, {column: value}, {column: label of the value in the file})``.
Rows = list[tuple[str, dict[str, Any], dict[str, str]]]


def _labels(where: str) -> dict[str, str]:
    return {c: f"{where}: {c}" for c in COLUMNS}


def _read_csv(path: Path, text: str) -> Rows:
    reader = csv.DictReader(io.StringIO(text, newline=""))
    if reader.fieldnames is None:
        raise _bad(path, "", "empty file (expected a header s,a,s_next,count)")
    _check_columns(path, [n.strip() for n in reader.fieldnames], "header")
    rows = []
    for row in reader:
        clean = {k.strip(): v for k, v in row.items() if k is not None}
        if None in row or any(v is None for v in clean.values()):
            raise _bad(path, f"line {reader.line_num}", "expected 4 values")
        rows.append((f"line {reader.line_num}", clean, _labels(f"line {reader.line_num}")))
    return rows


def _field(path: Path, obj: Any, name: str, where: str) -> Any:
    if not isinstance(obj, dict):
        raise _bad(path, where, f"expected an object, got {type(obj).__name__}")
    if name not in obj:
        raise _bad(path, f"{where}.{name}", "missing field")
    return obj[name]


def _read_isir(path: Path, doc: dict[str, Any]) -> Rows:
    entries = doc["transitionActions"]
    if not isinstance(entries, list):
        raise _bad(path, "transitionActions", "expected a list of {state, transitions}")
    rows: Rows = []
    for i, entry in enumerate(entries):
        where = f"transitionActions[{i}]"
        s = _field(path, entry, "state", where)
        transitions = _field(path, entry, "transitions", where)
        if not isinstance(transitions, list):
            raise _bad(path, f"{where}.transitions", "expected a list of {action, state, prob}")
        for j, tr in enumerate(transitions):
            w = f"{where}.transitions[{j}]"
            a, s2, n = (_field(path, tr, f, w) for f in _ISIR_TRANSITION_FIELDS)
            labels = {"s": f"{where}.state", "a": f"{w}.action", "s_next": f"{w}.state",
                      "count": f"{w}.prob"}
            rows.append((w, {"s": s, "a": a, "s_next": s2, "count": n}, labels))
    return rows


def _read_json(path: Path, text: str) -> tuple[Rows, str, dict[str, Any]]:
    try:
        doc = json.loads(text, parse_int=_parse_json_int)
    except json.JSONDecodeError as exc:
        raise _bad(path, "", f"not valid JSON ({exc})") from None
    except RecursionError:
        raise _bad(path, "", NESTED_TOO_DEEPLY) from None
    rows: Rows = []
    if isinstance(doc, list):
        for i, item in enumerate(doc):
            if not isinstance(item, dict):
                raise _bad(path, f"row {i}", "expected an object with s, a, s_next, count")
            _check_columns(path, set(item), f"row {i}")
            rows.append((f"row {i}", item, _labels(f"row {i}")))
        return rows, "json-rows", {}
    if not isinstance(doc, dict):
        raise _bad(path, "", "expected a list of objects or an object of columns")
    if "transitionActions" in doc:
        meta = {k: v for k, v in doc.items() if k != "transitionActions"}
        return _read_isir(path, doc), "isir", meta
    if not set(doc) & set(COLUMNS):
        raise _bad(path, "(top level)", "neither 'transitionActions' (ISIR transition model) "
                   "nor the columns s, a, s_next, count")
    _check_columns(path, set(doc), "(top level)")
    cols = [doc[c] for c in COLUMNS]
    if not all(isinstance(c, list) for c in cols) or len({len(c) for c in cols}) != 1:
        raise _bad(path, "", "s, a, s_next and count must be lists of equal length")
    for i in range(len(cols[0])):
        rows.append((f"row {i}", {c: doc[c][i] for c in COLUMNS}, _labels(f"row {i}")))
    return rows, "json-columns", {}


def _read_text(path: Path) -> str:
    data = path.read_bytes()
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise _bad(path, f"byte {exc.start}", "not UTF-8 text (a binary or wrongly encoded "
                   "file?)", fix="save it as UTF-8 CSV or JSON") from None
    if not text.strip():
        raise _bad(path, "", "empty file", fix="expected CSV s,a,s_next,count or JSON")
    return text


def _read_rows(path: Path) -> tuple[Rows, str, dict[str, Any]]:
    text = _read_text(path)
    suffix = path.suffix.lower()
    kind = suffix[1:] if suffix in (".csv", ".json") else (
        "json" if text.lstrip()[:1] in ("[", "{") else "csv")
    if kind == "csv":
        return _read_csv(path, text), "csv", {}
    return _read_json(path, text)


def _check_size(path: Path, S: int, n_actions: int, given: bool) -> None:
    nbytes = S * n_actions * S * 8
    if nbytes > MAX_TABLE_BYTES:
        origin = "n_states" if given else "largest state index + 1"
        raise _bad(path, "s", f"{S} states ({origin}) x {n_actions} actions would need a "
                   f"{nbytes / 2**30:.3g} GiB (S, A, S) table (limit "
                   f"{MAX_TABLE_BYTES / 2**30:.3g} GiB); refusing",
                   fix="check the state indices, or pass the true number of states "
                   "(--states / --n-states)")


def _action_fix(n_actions: int) -> str:
    """The fix for an action index beyond ``n_actions``: the other width, when there is one."""
    if n_actions == 8:
        return "--n-actions 16 for a 16-action robot"
    return "actions are numbered 0..15; check the file's action column"


def load_counts(
    path: str | os.PathLike[str],
    *,
    n_states: int | None = None,
    n_actions: int = N_ACTIONS,
) -> CountTable:
    """Read a count table (CSV, JSON or ISIR JSON; see the module docstring).

    Args:
        path: the file.
        n_states: S; default the largest state index + 1.
        n_actions: A, 8 or 16 (the raw table's width; the caller attaches the ActionSet).

    Returns:
        A :class:`CountTable` with ``counts`` ``(S, A, S)`` int64.

    Raises:
        ConfigError: (a :class:`CountsFileError`) a missing file or any bad content.
    """
    path = Path(path)
    validation.existing_file(path, "counts", what="counts file")
    if int(n_actions) not in (8, 16):
        raise ConfigError(f"expected 8 or 16, got {n_actions!r}", key="n_actions")
    n_actions = int(n_actions)
    raw, fmt, meta = _read_rows(path)
    if not raw:
        raise _bad(path, "", "no rows")
    values = np.empty((len(raw), 4), dtype=np.int64)
    for i, (_, row, labels) in enumerate(raw):
        for j, col in enumerate(COLUMNS):
            values[i, j] = _whole(row[col], path, labels[col])
    s, a, s_next, count = values.T
    bad = np.flatnonzero(count < 0)
    if bad.size:
        raise _bad(path, raw[bad[0]][2]["count"], f"negative count {count[bad[0]]}")
    for name, col in (("s", s), ("s_next", s_next), ("a", a)):
        neg = np.flatnonzero(col < 0)
        if neg.size:
            raise _bad(path, raw[neg[0]][2][name], f"negative index {col[neg[0]]}")
    for name, col in (("a", a),) if n_states is None else (
            ("s", s), ("s_next", s_next), ("a", a)):
        upper = n_actions if name == "a" else int(n_states)  # type: ignore[arg-type]
        over = np.flatnonzero(col >= upper)
        if over.size:
            raise _bad(path, raw[over[0]][2][name],
                       f"index {col[over[0]]} out of range 0..{upper - 1}",
                       fix=_action_fix(n_actions) if name == "a" else None)
    S = int(max(s.max(), s_next.max())) + 1 if n_states is None else int(n_states)
    _check_size(path, S, n_actions, n_states is not None)
    if count.sum(dtype=np.float64) > _INT64_MAX:
        raise _bad(path, "count", "the counts sum beyond a 64-bit integer")
    counts = np.zeros((S, n_actions, S), dtype=np.int64)
    np.add.at(counts, (s, a, s_next), count)
    triples = (s * n_actions + a) * S + s_next
    duplicates = int(len(triples) - len(np.unique(triples)))
    if duplicates:
        warn(f"{path}: {duplicates} duplicated (s, a, s') row(s) summed",
             DuplicateRowsWarning)
    return CountTable(counts=counts, rows=len(raw), duplicates=duplicates, path=path,
                      format=fmt, metadata=meta)


def check_action_width(table: CountTable, *, given: bool, flag: str = "--n-actions") -> None:
    """Refuse a table read as simlab's 16 actions only because no action count was
    ``given``, while every action of its file lies in 0..7: that is the shape of an
    8-action robot's data (its entropies of actions 8..15 would be NaN and a twin's
    "fast" columns would score nothing); the numbering cannot be guessed, so it is asked."""
    if given or table.n_actions != 16:
        return
    used = np.flatnonzero(table.counts.sum(axis=(0, 2)))
    if used.size and int(used.max()) < 8:
        raise CountsFileError(
            "every action in the file is in 0..7, but without an action count it is read as "
            "simlab's 16 actions (8..15 the fast moves, never taken here)", path=table.path,
            key="a", fix=f"give {flag} 8 and the robot's --convention (ccw-east for the ISIR "
            f"robot), or {flag} 16 for a 16-action robot that only took its slow moves")

