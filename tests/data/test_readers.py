"""Every reader the dataset docs name reads a dataset from one path, ``DIR/parts``
(issue 15 item 3), and datasets of the first layout (parts beside the manifest) still read.

Each external reader is skipped when its library is not installed (``pip install -e
".[dev,ray]"`` installs them all). Rows are compared after sorting by (worker, step), the
dataset's own order, so the test does not depend on a reader's file scheduling.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from discretize.voronoi import Discretizer
from simlab.base.errors import DataError
from simlab.data.collect import CollectResult
from simlab.data.dataset import open_dataset, parts_path, read_dataset, write_part
from simlab.data.manifest import read_manifest
from simlab.data.schema import COLUMN_DOCS, MANIFEST_NAME, PARTS_DIR, parse_part_name, part_name

Collect = Callable[..., CollectResult]
Columns = tuple[np.ndarray, np.ndarray, np.ndarray]  # worker, step, x

#: A dataset written by simlab before parts moved into ``parts/`` (the first layout):
#: ``collect`` of the 25-state lattice, kinematic simulator, 60 transitions, seed 11,
#: 2 workers, parts of 20 rows, made with the code of commit fdc1819.
OLD_LAYOUT = Path(__file__).parent / "fixtures" / "old_layout"


def _pyarrow(path: str) -> Columns:
    t = pq.read_table(path, columns=["worker", "step", "x"])
    return tuple(t.column(n).to_numpy() for n in ("worker", "step", "x"))  # type: ignore[return-value]


def _pandas(path: str) -> Columns:
    pd = pytest.importorskip("pandas")
    df = pd.read_parquet(path, columns=["worker", "step", "x"])
    return df["worker"].to_numpy(), df["step"].to_numpy(), df["x"].to_numpy()


def _polars_read(path: str) -> Columns:
    pl = pytest.importorskip("polars")
    df = pl.read_parquet(path, columns=["worker", "step", "x"])
    return df["worker"].to_numpy(), df["step"].to_numpy(), df["x"].to_numpy()


def _polars_scan(path: str) -> Columns:
    pl = pytest.importorskip("polars")
    df = pl.scan_parquet(path).select("worker", "step", "x").collect()
    return df["worker"].to_numpy(), df["step"].to_numpy(), df["x"].to_numpy()


def _duckdb(path: str) -> Columns:
    duckdb = pytest.importorskip("duckdb")
    with duckdb.connect() as con:
        rows = con.execute(f"SELECT worker, step, x FROM read_parquet('{path}')").fetchall()
    a = np.array(rows, dtype=np.float64).reshape(-1, 3)
    return a[:, 0].astype(np.int64), a[:, 1].astype(np.int64), a[:, 2]


def _ray(path: str) -> Columns:
    ray = pytest.importorskip("ray")
    pytest.importorskip("pandas")  # Ray Data's parquet reader needs it
    ray.init(num_cpus=1, include_dashboard=False, ignore_reinit_error=True, log_to_driver=False)
    try:
        df = ray.data.read_parquet(path, columns=["worker", "step", "x"]).to_pandas()
    finally:
        ray.shutdown()
    return df["worker"].to_numpy(), df["step"].to_numpy(), df["x"].to_numpy()


READERS: dict[str, Callable[[str], Columns]] = {
    "pyarrow.parquet.read_table": _pyarrow,
    "pandas.read_parquet": _pandas,
    "polars.read_parquet": _polars_read,
    "polars.scan_parquet": _polars_scan,
    "duckdb.read_parquet": _duckdb,
    "ray.data.read_parquet": _ray,
}


def _sorted(cols: Columns) -> Columns:
    worker, step, x = (np.asarray(c) for c in cols)
    order = np.lexsort((step, worker))
    return worker[order].astype(np.int64), step[order].astype(np.int64), x[order]


@pytest.fixture(scope="module")
def two_worker_dataset(tmp_path_factory: pytest.TempPathFactory,
                       grid_discretizer: Discretizer) -> Path:
    """A kinematic dataset, 2 workers x 150 transitions in parts of 40 (8 part files),
    with a temporary file left in ``DIR`` as by a write killed midway."""
    from simlab.data.collect import collect

    out = tmp_path_factory.mktemp("readers") / "walk"
    collect(arena="table", states=grid_discretizer, out=out, transitions=300, seed=5, workers=2,
            part_size=40, simulator="kinematic", progress=False)
    (out / f".{part_name(0, 9)}.k1ll3d.tmp").write_bytes(b"half a part")
    return out


def test_parts_directory_holds_only_the_listed_parts(two_worker_dataset: Path) -> None:
    manifest = read_manifest(two_worker_dataset)
    on_disk = sorted(p.name for p in (two_worker_dataset / PARTS_DIR).iterdir())
    listed = sorted(str(e["file"]) for e in manifest["parts"])
    assert [f"{PARTS_DIR}/{n}" for n in on_disk] == listed and len(listed) == 8
    assert all(parse_part_name(n) is not None for n in on_disk)
    assert parts_path(two_worker_dataset) == two_worker_dataset / PARTS_DIR


@pytest.mark.parametrize("reader", [  # Ray starts a local cluster (~10 s): the slow tier
    pytest.param(name, marks=pytest.mark.slow) if name.startswith("ray") else name
    for name in READERS])
def test_every_reader_reads_the_documented_path(two_worker_dataset: Path, reader: str) -> None:
    """Same row count and the same ``x`` column as simlab's own reader, at ``DIR/parts``."""
    table = read_dataset(two_worker_dataset)
    expected = _sorted(tuple(table.column(n).to_numpy() for n in ("worker", "step", "x")))
    got = _sorted(READERS[reader](str(parts_path(two_worker_dataset))))
    assert len(got[0]) == table.num_rows == 300
    for want, have in zip(expected, got, strict=True):
        np.testing.assert_array_equal(have, want)


def test_units_and_meanings_reach_a_reader_of_the_parts_directory(
        two_worker_dataset: Path) -> None:
    schema = pq.read_schema(next((two_worker_dataset / PARTS_DIR).iterdir()))
    assert set(schema.names) <= set(COLUMN_DOCS)
    for field in schema:
        unit, text = COLUMN_DOCS[field.name]
        assert field.metadata[b"unit"].decode() == unit
        assert field.metadata[b"description"].decode() == text
    docs = json.loads(schema.metadata[b"simlab.columns"])
    assert docs["yaw"] == {"unit": "rad", "description": COLUMN_DOCS["yaw"][1]}


# ----------------------------------------------------------------- the first layout
def test_old_layout_fixture_is_the_first_layout() -> None:
    names = sorted(p.name for p in OLD_LAYOUT.iterdir())
    assert names == [MANIFEST_NAME] + [part_name(w, p) for w in (0, 1) for p in (0, 1)]
    assert parts_path(OLD_LAYOUT) == OLD_LAYOUT


def test_old_layout_reads_the_same_rows_as_a_new_collect(tmp_path: Path,
                                                         collect_kinematic: Collect) -> None:
    """The layout moved, the content did not: the same collect today gives the same table."""
    old = open_dataset(OLD_LAYOUT)
    collect_kinematic(tmp_path / "new", transitions=60, seed=11, workers=2, part_size=20)
    new = open_dataset(tmp_path / "new")
    assert old.table.num_rows == 60
    assert new.table.equals(old.table)
    old_entries = {(e["worker"], e["part"]): e for e in old.manifest["parts"]}
    for e in new.manifest["parts"]:
        before = old_entries[(e["worker"], e["part"])]
        assert e["file"] == f"{PARTS_DIR}/{before['file']}" and e["sha256"] == before["sha256"]


def test_old_layout_refuses_an_unlisted_part_and_keeps_its_layout(tmp_path: Path) -> None:
    copy = tmp_path / "old"
    shutil.copytree(OLD_LAYOUT, copy)
    table = pq.read_table(copy / part_name(1, 1))
    entry = write_part(copy, 1, 7, table, read_manifest(copy)["discretizer"]["hash"])
    assert entry["file"] == part_name(1, 7) and (copy / part_name(1, 7)).is_file()
    assert not (copy / PARTS_DIR).exists()
    with pytest.raises(DataError, match="not listed") as exc:
        open_dataset(copy)
    assert str(copy / part_name(1, 7)) in str(exc.value)


def test_new_layout_refuses_an_unlisted_part_in_either_place(tmp_path: Path,
                                                             collect_kinematic: Collect) -> None:
    out = tmp_path / "new"
    collect_kinematic(out, transitions=60, part_size=30)
    for stray in (out / PARTS_DIR / part_name(0, 9), out / part_name(0, 9)):
        shutil.copyfile(out / PARTS_DIR / part_name(0, 0), stray)
        with pytest.raises(DataError, match="not listed") as exc:
            open_dataset(out)
        assert str(stray) in str(exc.value)
        stray.unlink()
    assert open_dataset(out).table.num_rows == 60
