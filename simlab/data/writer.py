"""Public writer of simlab transition datasets, for data that did not come from ``collect``.

Anyone holding per-transition arrays (a real robot's pose log, a ROS bag, another
simulator) can make a dataset that :func:`~simlab.data.dataset.open_dataset`, ``simlab
estimate`` and the rest read exactly like a collected one::

    from simlab.data.writer import DatasetInfo, TransitionArrays, write_dataset

    walk = TransitionArrays(t=t, a=a, pose=pose, pose_next=pose_next, blocked=blocked,
                            duration=duration)            # s, s_next: from the centres
    write_dataset("data/lab", walk, DatasetInfo(discretizer="states/lab.json",
                  action_set=parse_action_set(8, "ccw-east"), pose_source="log",
                  provenance={"log": "run3.txt", "robot": "turtlebot3 #2"}))

Layout and columns are those of :mod:`simlab.data.schema`: parts in ``DIR/parts/`` (the one
path pyarrow, pandas, Polars, DuckDB and Ray Data all read), manifest at
``DIR/_manifest.json``. Each :class:`TransitionArrays` is one independent walk (a
``worker``); it is cut into parts of ``part_size`` rows, every part written atomically
(temporary name, fsync, rename), and the manifest — which is what makes the directory a
dataset — is written **last**, so an interrupted write never looks like a complete dataset.
The manifest holds the :class:`~simlab.base.actions.ActionSet` as ``action_set``, the pose
source, the discretizer (hash, centres) and the caller's free-form ``provenance``.

Decisions: a writer run produces a complete dataset (``complete: true``) and cannot be
resumed (there is nothing to re-run); ``seed`` is recorded as given (0 by default: data
that was not simulated has none). An existing non-empty directory is refused unless
``overwrite``. The new parts and manifest are written in a hidden staging directory
inside ``out`` (``.simlab-staging-*``, removed by the next write after a kill); only once
they are complete is the old dataset removed (manifest first, then its parts) and the new
``parts/`` and manifest renamed in, so a failed write (a full disk) leaves the old dataset
as it was, and a crash in the swap leaves a directory no reader accepts rather than a
mixture of two datasets. Parts without a manifest (a write killed before the staging
existed) are removed by the next write without ``overwrite``.
"""

from __future__ import annotations

import contextlib
import math
import os
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa

from simlab.base.actions import SIMLAB16, ActionSet
from simlab.base.errors import ConfigError
from simlab.base.io import (
    STAGING_PREFIX,
    exclusive_directory,
    put_back,
    set_aside,
    unstaged_error,
)
from simlab.data.dataset import write_part
from simlab.data.manifest import manifest_path, new_manifest, write_manifest
from simlab.data.schema import (
    NO_TRUTH_SOURCES,
    PARTS_DIR,
    POSE_SOURCE_NAMES,
    TRUTH_COLUMNS,
    parse_part_name,
    schema_to_json,
    transition_schema,
)
from simlab.physics.inputs import load_discretizer

#: Rows per part file unless told otherwise.
DEFAULT_PART_SIZE = 10_000


def _array(value: Any, name: str, dtype: Any, n: int | None, width: int | None = None
           ) -> np.ndarray:
    arr = np.asarray(value, dtype=dtype)
    shape = (n,) if width is None else (n, width)
    if arr.ndim != len(shape) or (width is not None and arr.shape[1] != width) or (
            n is not None and arr.shape[0] != n):
        raise ConfigError(f"expected shape {tuple('N' if d is None else d for d in shape)}, "
                          f"got {arr.shape}", key=f"transitions.{name}")
    if arr.dtype.kind == "f" and not np.all(np.isfinite(arr)):
        raise ConfigError("values must be finite", key=f"transitions.{name}")
    return arr


@dataclass(frozen=True)
class TransitionArrays:
    """One walk's transitions, ``N`` rows, validated and copied on construction.

    Attributes:
        t: ``(N,)`` s, time when each transition (decision) starts, non-decreasing.
        a: ``(N,)`` int, action index in the dataset's action set.
        pose: ``(N, 3)`` ``x, y, yaw`` before (m, m, rad, map frame).
        pose_next: ``(N, 3)`` pose after.
        blocked: ``(N,)`` bool, the translation was not executed.
        duration: ``(N,)`` s, how long the transition took (>= 0).
        s, s_next: ``(N,)`` int Markov states; None: nearest centre of the poses.
        truth, truth_next: ``(N, 3)`` ground-truth poses; required for the simulated pose
            sources ``odometry`` and ``mcl``, refused for ``truth`` and ``log``.
    """

    t: Any
    a: Any
    pose: Any
    pose_next: Any
    blocked: Any
    duration: Any
    s: Any = None
    s_next: Any = None
    truth: Any = None
    truth_next: Any = None

    def __post_init__(self) -> None:
        t = _array(self.t, "t", np.float64, None)
        n = len(t)
        fix = object.__setattr__
        fix(self, "t", t)
        fix(self, "a", _array(self.a, "a", np.int64, n))
        for name in ("pose", "pose_next", "truth", "truth_next"):
            if getattr(self, name) is not None:
                fix(self, name, _array(getattr(self, name), name, np.float64, n, 3))
        fix(self, "blocked", _array(self.blocked, "blocked", bool, n))
        fix(self, "duration", _array(self.duration, "duration", np.float64, n))
        for name in ("s", "s_next"):
            if getattr(self, name) is not None:
                fix(self, name, _array(getattr(self, name), name, np.int64, n))
        if (self.truth is None) != (self.truth_next is None):
            raise ConfigError("give both truth and truth_next, or neither", key="transitions")
        if n and np.any(np.diff(t) < 0):
            raise ConfigError("times must not decrease", key="transitions.t")
        if np.any(self.duration < 0):
            raise ConfigError("durations must be >= 0", key="transitions.duration")

    def __len__(self) -> int:
        return len(self.t)


@dataclass(frozen=True)
class DatasetInfo:
    """What a dataset is about (everything of the manifest except the transitions).

    Attributes:
        discretizer: states file (``simlab discretize`` JSON) or a discretizer object
            (``state_of``, ``n_states``, ``centres``, ``content_hash()``).
        action_set: meaning of the action column (stored as ``action_set``).
        pose_source: one of :data:`~simlab.data.schema.POSE_SOURCE_NAMES`.
        provenance: free-form JSON-able record (files, robot, operator, ...).
        arena: ``arena`` record: ``name`` and optionally ``bounds`` ``[xmin, xmax, ymin,
            ymax]`` (m) and ``goals`` (as collect writes them).
        robot: ``robot`` record (free-form).
        simulator: what produced the motion (``real`` for a real robot).
        parameters: extra ``parameters`` entries (free-form, JSON-able).
        seed: recorded seed (0 when nothing was random).
        action_names: for actions that are not motion primitives (e.g. the 22 actions of
            the social task): one name per action index. The manifest then records
            ``action_set: null`` and ``parameters.action_names``; ``action_set`` is ignored.
    """

    discretizer: Any
    action_set: ActionSet = SIMLAB16
    pose_source: str = "log"
    provenance: Mapping[str, Any] = field(default_factory=dict)
    arena: Mapping[str, Any] = field(default_factory=lambda: {"name": "real"})
    robot: Mapping[str, Any] = field(default_factory=dict)
    simulator: str = "real"
    parameters: Mapping[str, Any] = field(default_factory=dict)
    seed: int = 0
    action_names: Sequence[str] | None = None

    def __post_init__(self) -> None:
        if self.action_names is not None:
            names = tuple(str(n) for n in self.action_names)
            if not names or len(set(names)) != len(names):
                raise ConfigError("expected distinct, non-empty action names",
                                  key="action_names")
            object.__setattr__(self, "action_names", names)
        if self.pose_source not in POSE_SOURCE_NAMES:
            raise ConfigError(f"unknown pose source {self.pose_source!r}", key="pose_source",
                              fix=f"choose one of {', '.join(POSE_SOURCE_NAMES)}")
        if not isinstance(self.action_set, ActionSet):
            raise ConfigError("expected an ActionSet (simlab.base.actions)", key="action_set")
        if "name" not in self.arena:
            raise ConfigError("the arena record needs a 'name'", key="arena")


@dataclass(frozen=True)
class WriteResult:
    """What :func:`write_dataset` wrote: the directory, its manifest, the row count."""

    out: Path
    manifest: dict[str, Any]
    rows: int


def _states(walk: TransitionArrays, disc: Any, n_states: int, n_actions: int, w: int
            ) -> tuple[np.ndarray, np.ndarray]:
    s = disc.state_of(walk.pose[:, :2]) if walk.s is None else walk.s
    s2 = disc.state_of(walk.pose_next[:, :2]) if walk.s_next is None else walk.s_next
    for name, col, upper in (("s", s, n_states), ("s_next", s2, n_states), ("a", walk.a,
                                                                             n_actions)):
        if len(col) and (col.min() < 0 or col.max() >= upper):
            raise ConfigError(f"values outside 0..{upper - 1} (min {col.min()}, max "
                              f"{col.max()})", key=f"walk {w}: {name}")
    return np.asarray(s, dtype=np.int32), np.asarray(s2, dtype=np.int32)


def _part_table(walk: TransitionArrays, rows: slice, w: int, p: int, states: tuple[
        np.ndarray, np.ndarray], pose_source: str, schema: pa.Schema) -> pa.Table:
    n = len(walk.t[rows])
    data: dict[str, Any] = {
        "worker": np.full(n, w, dtype=np.int32), "part": np.full(n, p, dtype=np.int32),
        "step": np.arange(rows.start, rows.start + n, dtype=np.int64),
        "t": walk.t[rows], "duration": walk.duration[rows],
        "s": states[0][rows], "a": walk.a[rows].astype(np.int32), "s_next": states[1][rows],
        "blocked": walk.blocked[rows],
        "pose_source": pa.DictionaryArray.from_arrays(pa.array(np.zeros(n, dtype=np.int32)),
                                                      pa.array([pose_source])),
    }
    for k, name in enumerate(("x", "y", "yaw")):
        data[name] = walk.pose[rows, k]
        data[f"{name}_next"] = walk.pose_next[rows, k]
    if pose_source not in NO_TRUTH_SOURCES:
        for k, name in enumerate(TRUTH_COLUMNS):
            src = walk.truth if k < 3 else walk.truth_next
            data[name] = src[rows, k % 3]  # type: ignore[index]
    arrays = [data[f.name] if isinstance(data[f.name], pa.Array)
              else pa.array(data[f.name], type=f.type) for f in schema]
    return pa.Table.from_arrays(arrays, schema=schema)


def _killed_run_leftovers(out: Path, entries: list[Path]) -> bool:
    """True when ``entries`` are only part files (in ``parts/`` or the top level) and no
    manifest: what a writer killed before its manifest leaves (never a dataset, since the
    manifest makes one). The caller holds the directory's lock, so no live writer owns them."""
    if manifest_path(out).exists():
        return False
    parts_dir = out / PARTS_DIR
    inner = list(parts_dir.iterdir()) if parts_dir.is_dir() else []
    return all(parse_part_name(p.name) is not None and p.is_file()
               for p in inner + [p for p in entries if p != parts_dir]) \
        and (not parts_dir.exists() or parts_dir.is_dir())


def _clear(out: Path, overwrite: bool) -> None:
    """Refuse a directory that is not empty (unless ``overwrite``) or that holds files that
    are not a dataset's (:func:`_set_aside` then moves the old dataset out of the way)."""
    entries = _dataset_entries(out)
    if not entries:
        return
    if not overwrite and _killed_run_leftovers(out, entries):
        overwrite = True  # a killed write's own parts: removed like an overwrite's
    parts_dir = out / PARTS_DIR
    inner = sorted(parts_dir.iterdir()) if parts_dir.is_dir() else []
    foreign = [p.name for p in entries
               if p.name != manifest_path(out).name and parse_part_name(p.name) is None
               and p != parts_dir]
    foreign += [f"{PARTS_DIR}/{p.name}" for p in inner
                if parse_part_name(p.name) is None and not p.name.startswith(".")]
    if foreign or (parts_dir.exists() and not parts_dir.is_dir()):
        raise ConfigError(f"directory holds files that are not a dataset's "
                          f"({(foreign or [PARTS_DIR])[0]}, ...); not replacing it", path=out,
                          fix="choose another --out")
    if not overwrite:  # only now: --overwrite is the fix only when it would work
        raise ConfigError("output directory is not empty: it holds a dataset", path=out,
                          fix="choose another --out or pass --overwrite")


#: Where, inside a write's staging folder, the dataset it replaces waits until the new one
#: is in place.
PREVIOUS = "previous"


def _dataset_entries(out: Path) -> list[Path]:
    """The dataset files of ``out`` (hidden names are simlab's own: staging, lock)."""
    return [p for p in out.iterdir() if not p.name.startswith(".")]


def _set_aside(out: Path, overwrite: bool, dest: Path) -> None:
    """Move the dataset of ``out`` (checked by :func:`_clear`) into ``dest``: its manifest
    first (a dataset no more), then its parts."""
    _clear(out, overwrite)
    entries = _dataset_entries(out)
    if not entries:
        return
    manifest = manifest_path(out)
    for p in sorted(entries, key=lambda q: q != manifest):
        set_aside(p, dest / p.name)


def _clear_staging(out: Path) -> None:
    """Remove the staging folders in ``out`` (the caller holds its lock: a killed write's,
    or this call's own). A write stopped after it set the previous dataset aside and before
    the new one was whole in ``out`` (no manifest there) left the only copy of that dataset
    in its staging folder: it goes back first (the new write's parts removed, its manifest
    last)."""
    for stale in sorted(out.glob(f"{STAGING_PREFIX}*")):
        previous = stale / PREVIOUS
        if previous.is_dir() and manifest_path(previous).exists() \
                and not manifest_path(out).exists():
            here = _dataset_entries(out)
            parts = [p for p in here
                     if p.name == PARTS_DIR or parse_part_name(p.name) is not None]
            if len(parts) < len(here):  # something else is there now: leave the dataset
                continue                # where it waits rather than remove what is not ours
            for p in parts:  # the unfinished write's parts
                if p.is_dir():
                    shutil.rmtree(p)
                else:
                    p.unlink()
            manifest = manifest_path(previous)
            for p in sorted(previous.iterdir(), key=lambda q: q == manifest):
                put_back(p, out / p.name)
        shutil.rmtree(stale, ignore_errors=True)


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, Mapping):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def _checked_walks(walks: TransitionArrays | Sequence[TransitionArrays], info: DatasetInfo,
                   part_size: int) -> list[TransitionArrays]:
    """``walks`` as a list, each with truth poses exactly when the pose source has them;
    ``part_size`` a whole number >= 1."""
    walks = [walks] if isinstance(walks, TransitionArrays) else list(walks)
    if not walks or not all(isinstance(w, TransitionArrays) for w in walks):
        raise ConfigError("expected one or more TransitionArrays", key="walks")
    if isinstance(part_size, bool) or int(part_size) != part_size or part_size < 1:
        raise ConfigError(f"expected a whole number >= 1, got {part_size!r}", key="part_size")
    truth_needed = info.pose_source not in NO_TRUTH_SOURCES
    for w, walk in enumerate(walks):
        if truth_needed != (walk.truth is not None):
            raise ConfigError(f"pose source {info.pose_source!r} "
                              f"{'needs' if truth_needed else 'takes no'} truth poses",
                              key=f"walk {w}: truth")
    return walks


def _manifest(info: DatasetInfo, disc: Any, n_actions: int, workers: int, part_size: int,
              schema: pa.Schema) -> dict[str, Any]:
    """The ``_manifest.json`` content before the parts are written (their list is added by
    :func:`_write_walks`): versions, the discretizer's hash and centres, the action set
    (or the action names of an imported dataset), provenance."""
    from simlab import __version__

    manifest = new_manifest(
        simlab_version=__version__, arena=info.arena, robot=info.robot,
        simulator=info.simulator, pose_source=info.pose_source,
        discretizer={"hash": disc.content_hash(), "n_states": int(disc.n_states),
                     "centres": np.asarray(disc.centres, dtype=np.float64).tolist()},
        seed=int(info.seed), workers=workers,
        parameters={**dict(info.parameters), "n_actions": n_actions,
                    "part_size": int(part_size),
                    **({} if info.action_names is None
                       else {"action_names": list(info.action_names)})},
        schema=schema_to_json(schema))
    manifest["action_set"] = info.action_set.to_json() if info.action_names is None else None
    manifest["provenance"] = dict(info.provenance)
    manifest["writer"] = "simlab.data.writer"
    return manifest


def write_dataset(
    out: str | os.PathLike[str],
    walks: TransitionArrays | Sequence[TransitionArrays],
    info: DatasetInfo,
    *,
    part_size: int = DEFAULT_PART_SIZE,
    overwrite: bool = False,
    workers: Sequence[int] | None = None,
) -> WriteResult:
    """Write a simlab transition dataset (Parquet parts + ``_manifest.json``) into ``out``.

    Args:
        out: dataset directory (created; must be empty unless ``overwrite``).
        walks: one walk, or several (worker ``w`` = ``walks[w]``).
        info: manifest content (discretizer, action set, pose source, provenance...).
        part_size: rows per part file (>= 1).
        overwrite: replace a dataset already in ``out``.
        workers: the worker number of each walk (distinct, 0..999; default 0, 1, ...):
            an import keeps the numbers its source recorded (worker 1's walk alone stays
            worker 1; the manifest's ``workers`` is then the largest number + 1).

    Returns:
        :class:`WriteResult`. Read it back with :func:`simlab.data.dataset.open_dataset`.

    Raises:
        ConfigError: bad arrays (naming the field), states or actions out of range,
            a non-empty ``out`` without ``overwrite``. Nothing is written then.
    """
    walks = _checked_walks(walks, info, part_size)
    numbers = _worker_numbers(workers, len(walks))
    disc = load_discretizer(info.discretizer)
    n_states = int(disc.n_states)
    n_actions = info.action_set.n_actions if info.action_names is None \
        else len(info.action_names)
    states = [_states(walk, disc, n_states, n_actions, w) for w, walk in enumerate(walks)]
    schema = transition_schema(info.pose_source)
    manifest = _manifest(info, disc, n_actions, max(numbers) + 1, part_size, schema)
    out = Path(out)
    created = not out.exists()
    try:
        with exclusive_directory(out, what="dataset directory"):
            _clear_staging(out)  # a killed write's; we hold the lock
            _clear(out, overwrite)  # refuse before any work
            try:
                staging = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=out))
                written = _write_walks(staging, walks, numbers, states, info, schema,
                                       manifest, part_size, disc)
                # the old dataset moves aside only once the new one is whole, and is
                # deleted only once the new one is in place
                _set_aside(out, overwrite, staging / PREVIOUS)
                os.replace(staging / PARTS_DIR, out / PARTS_DIR)
                os.replace(manifest_path(staging), manifest_path(out))  # last: a dataset now
            except OSError as exc:  # name the user's dataset, not the staging copy
                if exc.filename is None or STAGING_PREFIX not in str(exc.filename):
                    raise
                raise unstaged_error(exc, out) from exc
            finally:
                # by the glob, not the name (an interrupt can land after mkdtemp made the
                # folder, before its name was bound); an old dataset set aside and not
                # replaced goes back
                _clear_staging(out)
    except BaseException:  # a full disk, Ctrl-C: a first write leaves no directory behind
        if created:
            with contextlib.suppress(OSError):
                out.rmdir()  # only when empty
        raise
    return WriteResult(out=out, manifest=written, rows=sum(len(w) for w in walks))


def _worker_numbers(workers: Sequence[int] | None, n: int) -> list[int]:
    """The worker number of each of ``n`` walks: ``workers`` checked, or 0..n-1."""
    if workers is None:
        return list(range(n))
    numbers = list(workers)
    if (len(numbers) != n or len(set(numbers)) != n
            or not all(isinstance(w, int | np.integer) and not isinstance(w, bool)
                       and 0 <= w <= 999 for w in numbers)):
        raise ConfigError(f"expected {n} distinct whole numbers 0..999, one per walk, got "
                          f"{numbers!r}", key="workers")
    return [int(w) for w in numbers]


def _write_walks(out: Path, walks: list[TransitionArrays], numbers: list[int],
                 states: list[Any], info: DatasetInfo, schema: pa.Schema,
                 manifest: dict[str, Any], part_size: int, disc: Any) -> dict[str, Any]:
    """The parts of every walk (walk k as worker ``numbers[k]``), then the manifest (its
    ``parts`` filled in as written); returns the manifest as written."""
    for walk, w, walk_states in zip(walks, numbers, states, strict=True):
        n = len(walk)
        starts = range(0, n, int(part_size)) if n else []
        for p, start in enumerate(starts):
            rows = slice(start, min(n, start + int(part_size)))
            table = _part_table(walk, rows, w, p, walk_states, info.pose_source, schema)
            entry = write_part(out, w, p, table, disc.content_hash())
            last = rows.stop - 1
            entry.update(t_end=float(walk.t[last] + walk.duration[last]),
                         pose_end=[float(v) for v in walk.pose_next[last]],
                         final=rows.stop == n)
            manifest["parts"].append(entry)
    manifest["complete"] = True
    written = _jsonable(manifest)
    write_manifest(out, written)
    return written
