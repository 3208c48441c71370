"""External count tables (CSV / JSON) and the goal-state rule."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from simlab.base.errors import DataError
from simlab.data.counts import DuplicateRowsWarning, load_counts
from simlab.data.estimate import estimate
from simlab.data.goals import goal_state_masks
from simlab.physics.arena import GoalArea

ROWS = [(0, 3, 1, 12), (0, 3, 2, 4), (2, 15, 2, 7), (1, 0, 0, 1)]


def _csv(path: Path, rows, header: str = "s,a,s_next,count") -> Path:
    path.write_text(header + "\n" + "".join(",".join(map(str, r)) + "\n" for r in rows))
    return path


def _expected(n_states: int = 3) -> np.ndarray:
    counts = np.zeros((n_states, 16, n_states), dtype=np.int64)
    for s, a, s2, c in ROWS:
        counts[s, a, s2] += c
    return counts


def test_csv_json_rows_and_json_columns_agree(tmp_path: Path) -> None:
    a = load_counts(_csv(tmp_path / "c.csv", ROWS))
    rows = [{"s": s, "a": a_, "s_next": s2, "count": c} for s, a_, s2, c in ROWS]
    (tmp_path / "rows.json").write_text(json.dumps(rows))
    b = load_counts(tmp_path / "rows.json")
    cols = {k: [r[k] for r in rows] for k in ("s", "a", "s_next", "count")}
    (tmp_path / "cols.json").write_text(json.dumps(cols))
    c = load_counts(tmp_path / "cols.json")
    for table in (a, b, c):
        np.testing.assert_array_equal(table.counts, _expected())
        assert table.rows == 4 and table.duplicates == 0


def test_header_order_is_free_and_whole_floats_are_accepted(tmp_path: Path) -> None:
    rows = [(c, s2, a, s) for s, a, s2, c in ROWS]
    table = load_counts(_csv(tmp_path / "c.csv", rows, "count,s_next,a,s"))
    np.testing.assert_array_equal(table.counts, _expected())
    (tmp_path / "f.json").write_text(json.dumps([{"s": 0, "a": 1, "s_next": 1, "count": 3.0}]))
    assert load_counts(tmp_path / "f.json").counts[0, 1, 1] == 3


def test_duplicates_are_summed_and_reported(tmp_path: Path) -> None:
    with pytest.warns(DuplicateRowsWarning, match="1 duplicated"):
        table = load_counts(_csv(tmp_path / "c.csv", [*ROWS, (0, 3, 1, 8)]))
    assert table.counts[0, 3, 1] == 20 and table.duplicates == 1


def test_n_states_from_caller_or_largest_index(tmp_path: Path) -> None:
    path = _csv(tmp_path / "c.csv", ROWS)
    assert load_counts(path).counts.shape == (3, 16, 3)
    assert load_counts(path, n_states=10).counts.shape == (10, 16, 10)


@pytest.mark.parametrize(("rows", "header", "message"), [
    ([(0, 1, 1, -2)], "s,a,s_next,count", "negative count"),
    ([(0, 1, 1, 2.5)], "s,a,s_next,count", "whole number"),
    ([(0, 1, 1, "x")], "s,a,s_next,count", "whole number"),
    ([(0, 16, 1, 2)], "s,a,s_next,count", "out of range"),
    ([(-1, 1, 1, 2)], "s,a,s_next,count", "negative index"),
    ([(0, 1, 1, 2)], "s,a,next,count", "unknown column"),
    ([(0, 1, 2)], "s,a,count", "missing column"),
])
def test_bad_csv_rows_are_named(tmp_path: Path, rows, header: str, message: str) -> None:
    path = _csv(tmp_path / "c.csv", rows, header)
    with pytest.raises(DataError) as exc:
        load_counts(path)
    assert str(path) in str(exc.value) and message in str(exc.value)
    if "column" not in message:
        assert "line 2" in str(exc.value)


def test_index_beyond_given_states_is_refused(tmp_path: Path) -> None:
    path = _csv(tmp_path / "c.csv", ROWS)
    with pytest.raises(DataError, match=r"index 2 out of range 0\.\.1"):
        load_counts(path, n_states=2)


def test_bad_json_is_named(tmp_path: Path) -> None:
    path = tmp_path / "c.json"
    path.write_text(json.dumps([{"s": 0, "a": 1, "s_next": 1, "count": True}]))
    with pytest.raises(DataError, match="row 0: count"):
        load_counts(path)
    path.write_text(json.dumps({"s": [0, 1], "a": [1], "s_next": [1, 1], "count": [1, 1]}))
    with pytest.raises(DataError, match="equal length"):
        load_counts(path)
    path.write_text("[")
    with pytest.raises(DataError, match="not valid JSON"):
        load_counts(path)


def test_estimate_from_counts_with_states_and_arena(tmp_path: Path, grid_states_file: Path,
                                                   grid_discretizer) -> None:
    path = _csv(tmp_path / "c.csv", ROWS)
    result = estimate(counts=path, out=tmp_path / "mdp.npz", states=grid_states_file,
                      arena="table", plot=False)
    with np.load(tmp_path / "mdp.npz", allow_pickle=False) as z:
        assert z["counts"].shape == (25, 16, 25)
        assert z["counts"][0, 3, 1] == 12 and z["counts"].sum() == 24
        np.testing.assert_array_equal(z["centres"], grid_discretizer.centres)
        assert z["goal_masks"].shape == (9, 25)
    assert result.mdp.T[0, 3, 1] == pytest.approx(0.75)
    assert not (tmp_path / "mdp_entropy.png").exists()
    summary = json.loads((tmp_path / "mdp.json").read_text())
    assert summary["source"]["rows"] == 4


def test_estimate_from_counts_with_n_states_only(tmp_path: Path) -> None:
    path = _csv(tmp_path / "c.csv", ROWS)
    estimate(counts=path, out=tmp_path / "mdp.npz", n_states=5)
    with np.load(tmp_path / "mdp.npz", allow_pickle=False) as z:
        assert z["T"].shape == (5, 16, 5)
        assert "centres" not in z.files and "goal_masks" not in z.files


def test_goal_masks_inside_circle_else_nearest_state() -> None:
    centres = np.array([[0.0, 0.0], [0.1, 0.0], [1.0, 1.0], [0.5, 0.5]])
    goals = [
        GoalArea("two", 0.05, 0.0, 0.06),      # holds states 0 and 1
        GoalArea("edge", 1.0, 1.2, 0.2),       # state 2 exactly on the boundary
        GoalArea("empty", 0.45, 0.47, 0.01),   # no centre inside -> nearest (3)
    ]
    names, masks = goal_state_masks(goals, centres)
    assert names.tolist() == ["two", "edge", "empty"] and names.dtype.kind == "U"
    assert masks.tolist() == [[True, True, False, False], [False, False, True, False],
                              [False, False, False, True]]
    # dict goals (as stored in a manifest) give the same masks
    as_dicts = [{"name": g.name, "x": g.x, "y": g.y, "radius": g.radius} for g in goals]
    np.testing.assert_array_equal(goal_state_masks(as_dicts, centres).masks, masks)
