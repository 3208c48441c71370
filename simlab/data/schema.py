"""Layout of a transition dataset directory: file names and the Parquet schema.

A dataset is a directory::

    DIR/_manifest.json                   provenance, parameters, seeds, per-part checksums
    DIR/parts/part-w000-00000.parquet    worker 0, part 0 (names sort by worker, then part)
    DIR/parts/part-w000-00001.parquet
    DIR/parts/part-w001-00000.parquet
    ...

**One path for every reader: ``DIR/parts``.** The parts directory holds Parquet files and
nothing else (the temporary file of a part being written lives in ``DIR``, renamed into
``parts/`` when complete), so these all read the same rows (``tests/data/test_readers.py``
checks each one that is installed)::

    pyarrow.parquet.read_table("DIR/parts")          pandas.read_parquet("DIR/parts")
    polars.read_parquet("DIR/parts")                 polars.scan_parquet("DIR/parts")
    duckdb.sql("SELECT * FROM read_parquet('DIR/parts')")       # DuckDB >= 2.0
    ray.data.read_parquet("DIR/parts")

(DuckDB before 2.0 does not list directories: ``read_parquet('DIR/parts/*.parquet')``.)

Decision: with the parts beside the manifest no single string served every
reader (Arrow does not expand globs, Polars refuses a directory holding ``_manifest.json``,
DuckDB's ``FROM 'path'`` shorthand wants a file extension), hence the sub-directory; the
manifest stays at ``DIR/_manifest.json``, where simlab looks for it. Rows come in file-name
order within a reader's listing, which is (worker, part) order; :func:`simlab.data.dataset.
parquet_files` gives the part paths the manifest lists, in that order, for anything else.
simlab itself reads a dataset through its manifest (:func:`simlab.data.dataset.open_dataset`),
which also reads datasets of the first layout (parts directly in ``DIR``: the manifest's
``file`` entries are paths relative to ``DIR`` either way); for those the reader path is
``DIR`` itself (Arrow, pandas, Ray) or ``DIR/part-*.parquet`` (DuckDB, Polars), and
:func:`simlab.data.dataset.parts_path` returns the right directory for both layouts.

The manifest's name starts with an underscore on purpose: Arrow (and so pandas and Ray Data)
skip ``_``- and ``.``-prefixed files when they discover a dataset, so
``pyarrow.parquet.read_table(DIR)`` also reads every part (recursively); Polars does not.

Units and meanings are in each part's Parquet schema: every field carries ``unit`` and
``description`` metadata (:data:`COLUMN_DOCS`), and the schema metadata key
``simlab.columns`` holds the same table as JSON.

One row is one transition (one motion primitive). Columns:

===============  ==========  ========================================================
column           type        meaning
===============  ==========  ========================================================
worker           int32       worker (independent walk) index
part             int32       part index within the worker
step             int64       transition index within the worker's walk, from 0
t                float64     simulated seconds (worker clock) when the primitive starts
duration         float64     stepped simulated seconds of the primitive (no idle time)
s, a, s_next     int32       Markov state before, action 0-15, Markov state after
x, y, yaw        float64     pose before (m, m, rad), from the dataset's pose source
x_next, ...      float64     pose after (m, m, rad), from the pose source
blocked          bool        the obstacle detector skipped the translation
pose_source      dictionary  ``truth`` / ``odometry`` / ``mcl`` / ``log``
x_true, ...      float64     ground-truth poses, only for the simulated pose sources
                             ``odometry`` and ``mcl`` (a real robot's ``log`` has none)
twin_member      int32       member of the twin ensemble the walk drove, only in a
                             ``collect --ensemble`` dataset (the manifest's
                             ``parameters.ensemble`` holds the members' records)
===============  ==========  ========================================================
"""

from __future__ import annotations

import re

import pyarrow as pa

#: Version of the directory layout; bump on incompatible changes. Moving the parts into
#: ``parts/`` kept version 1: the manifest's ``file`` entries are paths relative to the
#: dataset directory, so readers of either layout resolve both.
FORMAT_VERSION = 1
#: ``format`` field of every manifest.
FORMAT_NAME = "simlab.transitions"
#: File name of the manifest inside a dataset directory (see the module docstring).
MANIFEST_NAME = "_manifest.json"
#: Number of motion primitives (thesis 3.2: 8 directions x 2 speeds): index = speed * 8 + direction.
N_ACTIONS = 16

#: Every pose source a dataset may record: the simulator's three, and ``log`` for poses
#: imported from a real robot's log (no ground truth exists for those).
POSE_SOURCE_NAMES = ("truth", "odometry", "mcl", "log")
#: Pose sources whose datasets carry no ``*_true`` columns.
NO_TRUTH_SOURCES = ("truth", "log")

POSE_COLUMNS = ("x", "y", "yaw", "x_next", "y_next", "yaw_next")
TRUTH_COLUMNS = ("x_true", "y_true", "yaw_true", "x_next_true", "y_next_true", "yaw_next_true")

#: Unit and meaning of every column, stored in the Parquet schema as each field's metadata
#: (``unit``, ``description``) and in the part's schema metadata under ``simlab.columns``
#: (JSON), so a reader of a bare part file knows what the numbers are.
COLUMN_DOCS: dict[str, tuple[str, str]] = {
    "worker": ("1", "worker (independent walk) index"),
    "part": ("1", "part index within the worker"),
    "step": ("1", "transition index within the worker's walk, from 0"),
    "t": ("s", "simulated robot time (worker clock) when the primitive starts"),
    "duration": ("s", "stepped simulated time of the primitive (no idle time)"),
    "s": ("1", "Markov state (Voronoi cell index) before the action"),
    "a": ("1", "action index in the manifest's action_set"),
    "s_next": ("1", "Markov state after the action"),
    "x": ("m", "x before, map frame, from the pose source"),
    "y": ("m", "y before, map frame, from the pose source"),
    "yaw": ("rad", "heading before, counter-clockwise from +x, from the pose source"),
    "x_next": ("m", "x after, map frame, from the pose source"),
    "y_next": ("m", "y after, map frame, from the pose source"),
    "yaw_next": ("rad", "heading after, from the pose source"),
    "blocked": ("1", "the obstacle detector skipped the translation"),
    "pose_source": ("1", "where the poses come from: truth, odometry, mcl or log"),
    "x_true": ("m", "ground-truth x before (simulated odometry/mcl datasets)"),
    "y_true": ("m", "ground-truth y before"),
    "yaw_true": ("rad", "ground-truth heading before"),
    "x_next_true": ("m", "ground-truth x after"),
    "y_next_true": ("m", "ground-truth y after"),
    "yaw_next_true": ("rad", "ground-truth heading after"),
    "twin_member": ("1", "index of the twin ensemble's member whose primitives drove the "
                    "walk (collect --ensemble; 0 is calibrate's winner)"),
}

#: Sub-directory of a dataset that holds the parts (see the module docstring).
PARTS_DIR = "parts"

_PART_RE = re.compile(r"^part-w(\d{3})-(\d{5})\.parquet$")


def part_name(worker: int, part: int) -> str:
    """File name of part ``part`` of worker ``worker`` (``part-w000-00000.parquet``)."""
    if not 0 <= worker <= 999 or not 0 <= part <= 99_999:
        raise ValueError(f"worker {worker} / part {part} outside the file-name range")
    return f"part-w{worker:03d}-{part:05d}.parquet"


def part_file(worker: int, part: int) -> str:
    """Path of a part relative to the dataset directory, as the manifest's ``file`` records
    it (``parts/part-w000-00000.parquet``, POSIX separators)."""
    return f"{PARTS_DIR}/{part_name(worker, part)}"


def parse_part_name(name: str) -> tuple[int, int] | None:
    """``(worker, part)`` of a part file name, or None if ``name`` is not one."""
    m = _PART_RE.match(name)
    return None if m is None else (int(m.group(1)), int(m.group(2)))


def transition_schema(pose_source: str, *, twin_member: bool = False) -> pa.Schema:
    """Arrow schema of a part for the given pose source.

    The ``*_true`` columns are there unless the pose source is ``truth`` or ``log``; the
    ``twin_member`` column, last, only with ``twin_member`` (a ``collect --ensemble``), so
    that every other dataset keeps its columns.
    """
    fields = [
        pa.field("worker", pa.int32(), nullable=False),
        pa.field("part", pa.int32(), nullable=False),
        pa.field("step", pa.int64(), nullable=False),
        pa.field("t", pa.float64(), nullable=False),
        pa.field("duration", pa.float64(), nullable=False),
        pa.field("s", pa.int32(), nullable=False),
        pa.field("a", pa.int32(), nullable=False),
        pa.field("s_next", pa.int32(), nullable=False),
    ]
    fields += [pa.field(name, pa.float64(), nullable=False) for name in POSE_COLUMNS]
    fields += [
        pa.field("blocked", pa.bool_(), nullable=False),
        pa.field("pose_source", pa.dictionary(pa.int32(), pa.string()), nullable=False),
    ]
    if pose_source not in NO_TRUTH_SOURCES:
        fields += [pa.field(name, pa.float64(), nullable=False) for name in TRUTH_COLUMNS]
    if twin_member:
        fields.append(pa.field("twin_member", pa.int32(), nullable=False))
    return pa.schema([f.with_metadata(column_metadata(f.name)) for f in fields])


def column_metadata(name: str) -> dict[bytes, bytes]:
    """Field metadata ``{unit, description}`` of a column (empty for unknown names)."""
    if name not in COLUMN_DOCS:
        return {}
    unit, text = COLUMN_DOCS[name]
    return {b"unit": unit.encode(), b"description": text.encode()}


def schema_to_json(schema: pa.Schema) -> list[dict[str, str]]:
    """The schema as ``[{"name": ..., "type": ...}]`` for the manifest."""
    return [{"name": f.name, "type": str(f.type)} for f in schema]
