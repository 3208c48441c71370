"""The one stage cache of simlab: results keyed on their settings and on the code that made them.

Used by the physics chain (:class:`simlab.orchestration.stages.PhysicsChain`: map,
states, dataset, MDP, Q-tables, replay) and by the Visit-the-lab training runs of
``simlab reproduce`` (:mod:`simlab.experiments.visitlab.runs`).

A stage lives in ``<root>/<stage>-<digest>/`` where ``digest`` (16 hex digits of sha256)
hashes the stage's key (its settings, its parent stage's digest, its seed), the stage
name, the simlab version and :func:`code_fingerprint` of the source its numbers depend
on: after a change to that code a stage is rebuilt, never silently reused (folders of
older code stay until the cache folder is deleted).

A folder is complete when its marker ``_stage.json`` exists (``{"key", "summary",
"wall_seconds"}``, written last, atomically); a folder without it (an interrupted build)
is deleted and rebuilt, and a build that raises removes its folder at once (a failed
start never blocks the rerun). A lock file per stage (``filelock.FileLock``, simlab's one
lock library; ``<root>/.<stage>-<digest>.lock``) keeps two processes from building the same
stage at once.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import shutil
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from simlab.base.errors import ConfigError
from simlab.base.fingerprint import source_fingerprint
from simlab.base.io import atomic_write_json

MARKER = "_stage.json"

#: What the results of each cache scope depend on, as paths relative to the ``simlab``
#: package (``discretize/`` is the discretizer package, ``assets/...`` the bundled
#: robot and arena files). Decision: the physics chain depends on every package it runs;
#: a Visit-the-lab training run on the simulation and training loop modules and the
#: agents, not on figures, the combined architecture or the runners (they do not change
#: a run's numbers).
SOURCES: dict[str, tuple[str, ...]] = {
    "physics": ("physics", "data", "orchestration/mapping.py", "agents", "training", "envs",
                "replay", "localization", "discretize/", "assets/robots", "assets/arenas"),
    "visitlab-run": ("visitlab/actions.py", "visitlab/grid.py", "visitlab/perception.py",
                     "visitlab/humans.py", "visitlab/dynamics.py", "visitlab/envs.py",
                     "visitlab/training.py", "visitlab/fused.py", "visitlab/passive.py", "agents"),
}


def _source_path(name: str) -> Path:
    import simlab

    if name == "discretize/":
        import discretize

        return Path(discretize.__file__).resolve().parent
    if name.startswith("assets/"):
        from simlab.base.assets import asset_dir

        return Path(asset_dir(name.split("/", 1)[1]))
    path = Path(simlab.__file__).resolve().parent / name
    if name.endswith(".py") and not path.exists() and path.with_suffix("").is_dir():
        return path.with_suffix("")  # a module that became a package
    return path


@functools.cache
def code_fingerprint(scope: str) -> str:
    """:func:`source_fingerprint` of the sources :data:`SOURCES` lists for ``scope``
    (``"physics"`` or ``"visitlab-run"``); computed once per process and scope."""
    if scope not in SOURCES:
        raise ConfigError(f"unknown cache scope {scope!r}", key="scope",
                          fix=f"one of {', '.join(SOURCES)}")
    return source_fingerprint([_source_path(n) for n in SOURCES[scope]])


def stage_key(stage: str, key: Mapping[str, Any], fingerprint: str) -> tuple[str, dict[str, Any]]:
    """``(digest, full key)`` of a cached stage: ``key`` plus the stage name, the simlab
    version and the ``fingerprint`` of the code it runs (16 hex digits of sha256)."""
    from simlab import __version__

    full = {"stage": stage, "simlab": __version__, "code": fingerprint, **key}
    return hashlib.sha256(json.dumps(full, sort_keys=True).encode()).hexdigest()[:16], full


@contextlib.contextmanager
def file_lock(path: Path) -> Iterator[None]:
    """Hold the lock file ``path`` (created if needed) for the block, waiting for another
    holder: two processes never build the same cached stage at once."""
    from filelock import FileLock

    path.parent.mkdir(parents=True, exist_ok=True)
    with FileLock(path):
        yield


@dataclass(frozen=True)
class Slot:
    """Where a stage of a given key lives: its folder, digest and full key."""

    stage: str
    path: Path
    key: str
    full_key: dict[str, Any]

    @property
    def complete(self) -> bool:
        """True when the marker exists (a finished build)."""
        return (self.path / MARKER).exists()


@dataclass(frozen=True)
class Stage:
    """A built stage: its folder, key, the numbers its build recorded, and whether this
    call built it (False: found in the cache)."""

    path: Path
    key: str
    summary: dict[str, Any]
    built: bool
    wall_seconds: float


class StageCache:
    """The stages of one ``scope`` (:data:`SOURCES`) under ``root``.

    :meth:`get` finds or builds one stage (``build(folder) -> summary`` under the lock);
    :meth:`slot` and :meth:`store` serve callers that compute several stages' contents
    elsewhere (in parallel) and only write them here. ``log`` gets one line per build.
    """

    def __init__(self, root: Path, scope: str, *,
                 log: Callable[[str], None] | None = None) -> None:
        self.root = Path(root)
        self.scope = scope
        self._fingerprint = code_fingerprint(scope)
        self._log = log or (lambda _m: None)
        self._seen: dict[str, Stage] = {}

    def slot(self, stage: str, key: Mapping[str, Any]) -> Slot:
        """The :class:`Slot` of ``stage`` for ``key`` (nothing is read or written)."""
        digest, full = stage_key(stage, key, self._fingerprint)
        return Slot(stage, self.root / f"{stage}-{digest}", digest, full)

    def _lock(self, slot: Slot) -> contextlib.AbstractContextManager[None]:
        return file_lock(self.root / f".{slot.path.name}.lock")

    def _write(self, slot: Slot, write: Callable[[Path], dict[str, Any]],
               wall: float | None) -> Stage:
        """Build ``slot`` with ``write`` (the lock is held); ``wall`` None: time it."""
        d = slot.path
        if d.exists():  # an interrupted build
            shutil.rmtree(d)
        d.mkdir(parents=True)
        t0 = time.perf_counter()
        try:
            summary = write(d)
        except BaseException:
            shutil.rmtree(d, ignore_errors=True)  # the rerun starts clean
            raise
        wall = time.perf_counter() - t0 if wall is None else wall
        atomic_write_json(d / MARKER, {"key": slot.full_key, "summary": summary,
                                       "wall_seconds": wall})
        self._log(f"{slot.stage}: built in {wall:.0f} s ({d.name})")
        return Stage(d, slot.key, summary, True, wall)

    def _read(self, slot: Slot) -> Stage:
        rec = json.loads((slot.path / MARKER).read_text())
        return Stage(slot.path, slot.key, rec.get("summary", {}), False, 0.0)

    def get(self, stage: str, key: Mapping[str, Any],
            build: Callable[[Path], dict[str, Any]]) -> Stage:
        """The stage ``stage`` for ``key``: found complete, or made by ``build(folder) ->
        summary`` (JSON-ready numbers recorded in the marker). Memoized per object."""
        slot = self.slot(stage, key)
        if slot.path.name in self._seen:
            return self._seen[slot.path.name]
        with self._lock(slot):
            st = self._read(slot) if slot.complete else self._write(slot, build, None)
        self._seen[slot.path.name] = st
        return st

    def store(self, slot: Slot, write: Callable[[Path], dict[str, Any]],
              wall_seconds: float) -> bool:
        """Write ``slot`` with ``write(folder) -> summary`` unless another process
        completed it meanwhile; ``wall_seconds`` is what computing it cost. True if
        written."""
        with self._lock(slot):
            if slot.complete:
                return False
            self._write(slot, write, wall_seconds)
            return True

    @property
    def stages(self) -> list[Stage]:
        """The stages :meth:`get` built or found, in the order first asked for."""
        return list(self._seen.values())
