"""The ISIR transition-model JSON and the edge cases of every counts file."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from simlab.base.errors import ConfigError, DataError
from simlab.data.counts import (
    MAX_TABLE_BYTES,
    CountsFileError,
    DuplicateRowsWarning,
    load_counts,
)

# (s, a, s', count) of a small 8-action model.
ISIR_ROWS = [(0, 0, 1, 12), (0, 0, 0, 3), (0, 4, 0, 5), (1, 2, 2, 7), (2, 7, 0, 1)]


def _isir(rows=ISIR_ROWS, **extra) -> dict:
    by_state: dict[int, list] = {}
    for s, a, s2, n in rows:
        by_state.setdefault(s, []).append({"action": a, "state": s2, "prob": n})
    doc = {"transitionActions": [{"state": s, "transitions": tr}
                                 for s, tr in by_state.items()],
           "actioncount": 28, "timecount": [13.2, "h"]}
    doc.update(extra)
    return doc


def _write(path: Path, doc) -> Path:
    path.write_text(json.dumps(doc))
    return path


def _expected(rows, n_states: int = 3, n_actions: int = 8) -> np.ndarray:
    c = np.zeros((n_states, n_actions, n_states), dtype=np.int64)
    for s, a, s2, n in rows:
        c[s, a, s2] += n
    return c


def test_isir_model_is_read_with_its_metadata(tmp_path: Path) -> None:
    table = load_counts(_write(tmp_path / "model.json", _isir()), n_actions=8)
    np.testing.assert_array_equal(table.counts, _expected(ISIR_ROWS))
    assert table.format == "isir" and table.rows == 5 and table.duplicates == 0
    assert table.metadata == {"actioncount": 28, "timecount": [13.2, "h"]}
    assert table.n_actions == 8 and table.n_states == 3


def test_file_without_extension_is_sniffed(tmp_path: Path) -> None:
    table = load_counts(_write(tmp_path / "transitionModel", _isir()), n_actions=8)
    assert table.format == "isir"
    np.testing.assert_array_equal(table.counts, _expected(ISIR_ROWS))
    csv = tmp_path / "counts"
    csv.write_text("s,a,s_next,count\n0,0,1,12\n")
    assert load_counts(csv, n_actions=8).format == "csv"
    (tmp_path / "rows.txt").write_text('  [{"s": 0, "a": 1, "s_next": 1, "count": 2}]')
    assert load_counts(tmp_path / "rows.txt").format == "json-rows"


def test_isir_duplicates_are_summed_counted_and_warned(tmp_path: Path) -> None:
    rows = [*ISIR_ROWS, (0, 0, 1, 8), (2, 7, 0, 4)]
    doc = _isir(rows)
    doc["transitionActions"].append({"state": 0, "transitions": [
        {"action": 0, "state": 1, "prob": 1}]})
    with pytest.warns(DuplicateRowsWarning, match="3 duplicated"):
        table = load_counts(_write(tmp_path / "m.json", doc), n_actions=8)
    assert table.duplicates == 3 and table.counts[0, 0, 1] == 21 and table.counts[2, 7, 0] == 5


def test_default_sixteen_actions_and_action_range(tmp_path: Path) -> None:
    path = _write(tmp_path / "m.json", _isir())
    assert load_counts(path).counts.shape == (3, 16, 3)
    doc = _isir([(0, 8, 1, 2)])
    with pytest.raises(ConfigError, match=r"transitions\[0\]\.action: index 8 out of range 0\.\.7"):
        load_counts(_write(tmp_path / "b.json", doc), n_actions=8)
    with pytest.raises(ConfigError, match="n_actions: expected 8 or 16"):
        load_counts(path, n_actions=4)


@pytest.mark.parametrize(("doc", "message"), [
    ({"transitionActions": [{"transitions": []}]}, r"transitionActions\[0\]\.state: missing"),
    ({"transitionActions": [{"state": 0}]}, r"transitionActions\[0\]\.transitions: missing"),
    ({"transitionActions": [{"state": 0, "transitions": [{"action": 1, "state": 0}]}]},
     r"transitionActions\[0\]\.transitions\[0\]\.prob: missing field"),
    ({"transitionActions": [{"state": 0, "transitions": [{"action": 1, "prob": 2}]}]},
     r"transitions\[0\]\.state: missing field"),
    ({"transitionActions": {"state": 0}}, "transitionActions: expected a list"),
    ({"transitionActions": [5]}, r"transitionActions\[0\]: expected an object"),
    ({"transitionActions": [{"state": 0, "transitions": [
        {"action": 1, "state": 0, "prob": 0.4}]}]}, r"prob: expected a whole number, got 0\.4"),
    ({"transitionActions": [{"state": 0, "transitions": [
        {"action": 1, "state": 0, "prob": 2 ** 63}]}]}, "does not fit a 64-bit integer"),
    ({"transitionActions": [{"state": "x", "transitions": [
        {"action": 1, "state": 0, "prob": 2}]}]}, r"transitionActions\[0\]\.state: expected a whole number, got .x."),
    ({"transitionActions": [{"state": -1, "transitions": [
        {"action": 1, "state": 0, "prob": 2}]}]}, r"\[0\]\.state: negative index -1"),
    ({"actioncount": 3}, "neither 'transitionActions'"),
])
def test_bad_isir_content_names_file_and_field(tmp_path: Path, doc, message: str) -> None:
    path = _write(tmp_path / "model", doc)
    with pytest.raises(ConfigError, match=message) as exc:
        load_counts(path, n_actions=8)
    assert str(path) in str(exc.value)
    assert isinstance(exc.value, DataError)  # older callers catch DataError


def test_unknown_state_beyond_given_states(tmp_path: Path) -> None:
    path = _write(tmp_path / "m.json", _isir([(0, 1, 5, 2)]))
    with pytest.raises(ConfigError, match=r"transitions\[0\]\.state: index 5 out of range 0\.\.3"):
        load_counts(path, n_states=4, n_actions=8)


def test_huge_state_index_is_refused_without_allocating(tmp_path: Path) -> None:
    path = _write(tmp_path / "m.json", _isir([(0, 1, 10 ** 9, 2)]))
    with pytest.raises(ConfigError) as exc:
        load_counts(path, n_actions=8)
    text = str(exc.value)
    assert "1000000001 states" in text and "GiB" in text and "--n-states" in text
    side = int((MAX_TABLE_BYTES / 8 / 8) ** 0.5) + 1
    with pytest.raises(ConfigError, match=f"{side} states \\(n_states\\)"):
        load_counts(_write(tmp_path / "ok.json", _isir()), n_states=side, n_actions=8)


def test_non_utf8_and_empty_files(tmp_path: Path) -> None:
    path = tmp_path / "model"
    path.write_bytes(b'{"transitionActions": [{"state": \xff}]}')
    with pytest.raises(ConfigError, match="byte 33: not UTF-8"):
        load_counts(path)
    for name in ("empty", "empty.csv", "empty.json"):
        (tmp_path / name).write_text(" \n")
        with pytest.raises(ConfigError, match="empty file") as exc:
            load_counts(tmp_path / name)
        assert name in str(exc.value)
    _write(tmp_path / "none.json", {"transitionActions": []})
    with pytest.raises(ConfigError, match="no rows"):
        load_counts(tmp_path / "none.json")


def test_errors_are_one_error_class(tmp_path: Path) -> None:
    assert issubclass(CountsFileError, ConfigError) and issubclass(CountsFileError, DataError)
    with pytest.raises(ConfigError, match="counts file not found"):
        load_counts(tmp_path / "missing.json")
