"""Fig. 3.5-style figure and visit counts from a Parquet dataset."""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from discretize.plot import plot_states, render_states_png, visits_from_dataset
from discretize.voronoi import Discretizer
from simlab.base.errors import ConfigError, DataError


def _write_parts(root, parts):
    root.mkdir(parents=True, exist_ok=True)
    for k, s in enumerate(parts):
        table = pa.table({"t": np.arange(len(s), dtype=np.int64), "s": np.asarray(s, np.int64)})
        pq.write_table(table, root / f"part-{k:05d}.parquet")


def test_visits_count_every_part(tmp_path, rng):
    parts = [rng.integers(0, 12, size=n) for n in (100, 37, 0, 250)]
    _write_parts(tmp_path / "ds", parts)
    visits = visits_from_dataset(tmp_path / "ds", 15)
    expected = np.bincount(np.concatenate(parts), minlength=15)
    np.testing.assert_array_equal(visits, expected)
    assert visits[12:].sum() == 0


def test_visits_errors(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        visits_from_dataset(tmp_path / "missing", 5)
    _write_parts(tmp_path / "big", [[0, 1, 7]])
    with pytest.raises(DataError, match="another discretizer"):
        visits_from_dataset(tmp_path / "big", 5)
    (tmp_path / "nos").mkdir()
    pq.write_table(pa.table({"a": [1, 2]}), tmp_path / "nos" / "p.parquet")
    with pytest.raises(DataError, match="no column 's'"):
        visits_from_dataset(tmp_path / "nos", 5)


def _png_size(data: bytes) -> tuple[int, int]:
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


def test_figure_with_and_without_visits(tmp_path, room):
    disc = Discretizer.from_map(room, 12)
    plain = render_states_png(room, disc, dpi=50)
    coloured = render_states_png(room, disc, visits=np.arange(12) ** 2, dpi=50)
    w, h = _png_size(plain)
    w2, h2 = _png_size(coloured)
    assert (w, h) == (320, 320) and w2 == 320 and h2 == 360  # colour bar adds height
    with pytest.raises(ValueError, match="visits"):
        render_states_png(room, disc, visits=np.ones(5))
    path = plot_states(tmp_path / "fig.png", room, disc)
    assert path.read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(ConfigError, match="already exists"):
        plot_states(path, room, disc)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fig.png"]  # no temporary left


def test_the_figure_reads_on_its_own(room):
    from discretize.plot import states_figure

    disc = Discretizer.from_map(room, 12)
    fig = states_figure(room, disc, visits=np.arange(12) ** 2)
    ax, bar = fig.axes
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x (m)", "y (m)")
    assert "visits per state" in bar.get_xlabel()
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels[0] == "state centres (numbered)"
    assert "eroded by the robot radius" in labels[1] and " m)" in labels[1]
    plain = states_figure(room, disc, robot_radius=None)
    assert len(plain.axes) == 1  # no colour bar without visits
    assert len(plain.axes[0].get_legend().get_texts()) == 1
