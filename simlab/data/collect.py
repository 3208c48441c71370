"""``simlab collect``: the epsilon = 1 random-walk transition dataset (thesis 3.2.4-3.2.5).

The thesis (3.2.5) let the real robot walk for about 10 hours with uniformly random
actions and logged 8,448 transitions. :func:`collect` does the same headlessly in
PyBullet, with ``workers`` independent walks in parallel, and writes a dataset
directory (see :mod:`simlab.data.schema`).

Twin ensemble (``ensemble``, domain randomisation): each walk drives one member of the
``[[ensemble]]`` of the ``primitives`` file (calibrate's twin ensemble), drawn by
:func:`simlab.physics.primitive_options.ensemble_members` from the seed and the walk's
index alone; with ``start_states`` the walks are the start states whatever the number of
workers, so the same seed gives the same members and the same dataset with any
``workers``. The unit is the walk, not the part: a member is a robot, and a walk is one
robot's continuous run. The manifest records the ensemble's size, every member's record
and the member of each walk (``parameters.ensemble``); the ``twin_member`` column repeats
the walk's member on each row.

Budget: ``hours`` is total simulated robot time split evenly over the workers
(10 h with 2 workers = 5 h per worker clock; a primitive starts only while its
worker's clock is below the budget, so the last one may end a little after it), or
``transitions`` in total (worker ``w`` gets ``N // W`` plus one if
``w < N % W``). The result is deterministic given (seed, workers, parameters); the
same seed with another number of workers is another dataset.

Exact resume: see :mod:`simlab.data.walkers` for why every part can be recomputed on
its own. The driver writes the manifest first, then each finished part atomically
followed by the manifest listing it; ``resume=True`` checks the directory's manifest
against this run (arena hash, discretizer hash, seed, workers, parameters, version),
verifies the listed parts' checksums and continues each worker from its first missing
part. A part file the manifest does not list (the run was killed between writing the
part and the manifest) is recomputed and replaced by the identical part; stray
temporary files are removed.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib.util
import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
from numpy.typing import NDArray

from simlab.base import validation as v
from simlab.base.actions import SIMLAB16, ActionSetOptions
from simlab.base.errors import ConfigError
from simlab.base.io import exclusive_directory
from simlab.base.options import command, option
from simlab.data.backends import BACKENDS, make_backend
from simlab.data.dataset import unlisted_parts, validate_part, write_part
from simlab.data.manifest import (
    check_resumable,
    file_sha256,
    manifest_path,
    new_manifest,
    physics_rate,
    read_manifest,
    write_manifest,
)
from simlab.data.schema import (
    MANIFEST_NAME,
    TRUTH_COLUMNS,
    schema_to_json,
    transition_schema,
)
from simlab.data.walkers import (
    SIMULATORS,
    KinematicParams,
    PartJob,
    PartResult,
    WalkSpec,
    check_pose_source,
)
from simlab.localization.sources import POSE_SOURCES
from simlab.physics.inputs import load_arena_config, load_discretizer
from simlab.physics.primitive_options import TwinEnsembleOptions, ensemble_members
from simlab.physics.rate import rate_option, resolve_rate, settings_for

#: Default transitions per part: small enough that a crash loses little, large enough
#: that per-part overheads (world rebuild, file, manifest) stay negligible.
DEFAULT_PART_SIZE = 250


@dataclass(frozen=True)
class CollectResult:
    """Summary of a collection run.

    Attributes:
        directory: the dataset directory.
        transitions: rows in the dataset (all parts, including resumed ones).
        parts: part files in the dataset.
        parts_written: parts computed by this run (the rest were already there).
        simulated_seconds: sum over workers of their clocks at the end (s).
        wall_seconds: wall time of this run (s).
        peak_worker_rss_mb: largest peak resident memory of a worker process (MiB);
            for one local worker this is the calling process.
        complete: every worker finished its budget.
        worker_cpu_seconds: CPU time each worker's parts took in this run (s); on an
            idle machine with a core per worker, the wall time is about their maximum.
        states_visited: states the walk was in (``s`` or ``s_next``) at least once, of
            ``n_states``: the walk's coverage of the lab.
        physics_hz: the physics rate of the walk (Hz; None for the kinematic simulator).
    """

    directory: Path
    transitions: int
    parts: int
    parts_written: int
    simulated_seconds: float
    wall_seconds: float
    peak_worker_rss_mb: float
    complete: bool
    worker_cpu_seconds: tuple[float, ...] = ()
    states_visited: int = 0
    n_states: int = 0
    physics_hz: float | None = None

    @property
    def simulated_hours(self) -> float:
        return self.simulated_seconds / 3600.0


# --------------------------------------------------------------------------------------
# Inputs
# --------------------------------------------------------------------------------------


def _json_default(obj: Any) -> Any:
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return dataclasses.asdict(obj)
    if isinstance(obj, np.generic | np.ndarray):
        return obj.tolist()
    raise TypeError(f"cannot record {type(obj).__name__} in the manifest")


def _jsonable(obj: Any) -> Any:
    """``obj`` as it reads back from JSON (tuples -> lists, dataclasses -> dicts)."""
    return json.loads(json.dumps(obj, default=_json_default))


def _arena_info(arena: Any) -> dict[str, Any]:
    return {
        "name": arena.name,
        "sha256": getattr(arena, "source_sha256", None),
        "bounds": [float(v) for v in arena.bounds],
        "start": [float(v) for v in arena.start],
        "goals": [
            {"name": g.name, "x": float(g.x), "y": float(g.y), "radius": float(g.radius)}
            for g in arena.goals
        ],
    }


def _robot_info(simulator: str) -> dict[str, Any]:
    if simulator == "kinematic":
        return {"name": "point robot (kinematic simulator)"}
    from simlab.physics.robot import load_robot_spec

    spec = load_robot_spec()
    return {"name": spec.name, "urdf_sha256": file_sha256(spec.urdf_path)}


def _default_params(simulator: str) -> Any:
    if simulator == "kinematic":
        return KinematicParams()
    from simlab.physics.motion import PrimitiveParams

    return PrimitiveParams()


def _split_transitions(total: int, workers: int) -> list[int]:
    base, extra = divmod(int(total), workers)
    return [base + (1 if w < extra else 0) for w in range(workers)]


# --------------------------------------------------------------------------------------
# Output directory
# --------------------------------------------------------------------------------------


def _is_stray_temp(name: str) -> bool:
    """Temporary files our atomic writes leave when killed (``.<name>.<random>.tmp``)."""
    return name.startswith((".part-", f".{MANIFEST_NAME}.")) and name.endswith(".tmp")


def _prepare_directory(out: Path, manifest: dict[str, Any], resume: bool) -> dict[str, Any]:
    """Give the directory ``out`` (existing, locked by the caller) a fresh manifest, or load
    and check its manifest for a resume."""
    entries = sorted(os.listdir(out))
    if not entries:
        write_manifest(out, manifest)
        return manifest
    if not resume:
        raise ConfigError(
            "output directory is not empty", path=out,
            fix="pass --resume to continue the collection in it, or choose a new --out",
        )
    if all(_is_stray_temp(name) for name in entries):  # killed while writing the first manifest
        for name in entries:
            (out / name).unlink(missing_ok=True)
        write_manifest(out, manifest)
        return manifest
    existing = read_manifest(out)
    check_resumable(existing, manifest, out)
    for entry in existing["parts"]:
        validate_part(out, entry, existing)
    for name in entries:
        if _is_stray_temp(name):
            (out / name).unlink(missing_ok=True)
    return existing


def _orphans(out: Path, manifest: dict[str, Any]) -> set[str]:
    return set(unlisted_parts(out, manifest))


# --------------------------------------------------------------------------------------
# The driver
# --------------------------------------------------------------------------------------


@dataclass
class _WorkerState:
    next_part: int = 0
    step: int = 0
    t: float = 0.0
    pose: tuple[float, float, float] | None = None
    remaining: int | None = None
    done: bool = False


def _worker_states(manifest: dict[str, Any], plan: WalkPlan, out: Path) -> list[_WorkerState]:
    """Each walk's state: at its start, or past the parts the manifest lists (a resume)."""
    states = plan.fresh_states()
    by_worker: dict[int, list[dict[str, Any]]] = {}
    for entry in manifest["parts"]:
        by_worker.setdefault(int(entry["worker"]), []).append(entry)
    for w, entries in by_worker.items():
        entries.sort(key=lambda e: int(e["part"]))
        if [int(e["part"]) for e in entries] != list(range(len(entries))):
            raise ConfigError(
                f"worker {w}'s parts are not contiguous from 0",
                path=manifest_path(out),
                fix="the manifest was edited; collect into a new --out",
            )
        st = states[w]
        last = entries[-1]
        st.next_part = len(entries)
        st.step = sum(int(e["rows"]) for e in entries)
        st.t = float(last["t_end"])
        st.pose = tuple(float(v) for v in last["pose_end"])  # type: ignore[assignment]
        if st.remaining is not None:
            st.remaining -= st.step
        st.done = bool(last["final"])
    return states


def _part_table(result: PartResult, step0: int, discretizer: Any, pose_source: str,
                schema: pa.Schema, member: int | None = None) -> pa.Table:
    cols = result.columns
    n = result.rows
    s, s_next = part_states(result, discretizer)
    data: dict[str, Any] = {
        "worker": np.full(n, result.worker, dtype=np.int32),
        "part": np.full(n, result.part, dtype=np.int32),
        "step": np.arange(step0, step0 + n, dtype=np.int64),
        "t": cols["t"],
        "duration": cols["duration"],
        "s": s,
        "a": cols["a"].astype(np.int32),
        "s_next": s_next,
    }
    for name in ("x", "y", "yaw", "x_next", "y_next", "yaw_next"):
        data[name] = cols[name]
    data["blocked"] = cols["blocked"]
    data["pose_source"] = pa.DictionaryArray.from_arrays(
        pa.array(np.zeros(n, dtype=np.int32)), pa.array([pose_source])
    )
    if pose_source != "truth":
        for name in TRUTH_COLUMNS:
            data[name] = cols[name]
    if member is not None:
        data["twin_member"] = np.full(n, member, dtype=np.int32)
    arrays = [pa.array(data[f.name], type=f.type) if not isinstance(data[f.name], pa.Array)
              else data[f.name] for f in schema]
    return pa.Table.from_arrays(arrays, schema=schema)


@dataclass(frozen=True, kw_only=True)
class CollectConfig(TwinEnsembleOptions, ActionSetOptions):
    """Options of ``simlab collect`` / :func:`collect` (one budget: ``hours`` or
    ``transitions``). The primitive options (:class:`TwinEnsembleOptions`) and ``params``
    are two ways to give the primitive parameters: the flags for the command line,
    ``params`` (a ``PrimitiveParams``, ``KinematicParams`` or a ``[primitives]`` TOML
    path) from Python; giving both is refused.

    The action-set fields (``--n-actions 8 --convention ccw-east --speed fast``) restrict
    the walk to a real robot's actions: it draws uniformly over their primitives and
    records ``a`` in their numbering (the manifest records the set), so the estimated MDP
    and the Q-tables trained on it have the real data's actions and a twin-trained Q-table
    is scored on the real model directly. Default: simlab's 16 primitives.

    The fields:

    * ``arena``: built-in arena name, ``.toml`` path or an ``ArenaConfig``.
    * ``states``: states file of ``simlab discretize`` (JSON) or a discretizer object
      (``state_of(xy (N, 2)) -> (N,)``, ``n_states``, ``centres``, ``content_hash()``).
    * ``out``: dataset directory; must be empty or absent unless ``resume``.
    * ``hours``: total simulated robot time (h), split evenly over the workers;
      ``transitions``: total number of transitions instead.
    * ``seed``: root seed; worker ``w``, part ``p`` draw from
      ``SeedSequence(seed, spawn_key=(w, p))``.
    * ``workers``: independent walks, one arena (process) each.
    * ``resume``: continue the collection already in ``out`` (see the module docstring).
    * ``backend``: ``"local"`` (process pool; in-process for one worker) or ``"ray"``;
      ``address``: Ray cluster address (default: local Ray).
    * ``part_size``: transitions per part file (the unit of crash loss and resumption).
    * ``pose_source``: ``"truth"``, ``"odometry"`` or ``"mcl"`` — the poses recorded and
      discretized (truth columns are added when it is not ``truth``).
    * ``simulator``: ``"physics"`` (PyBullet) or ``"kinematic"`` (physics-free point robot
      for dry runs; see :class:`~simlab.data.walkers.KinematicWalker`).
    * ``params`` or the primitive options: see :meth:`CollectConfig.resolved_params`.
      Recorded complete in ``manifest["parameters"]["primitive"]``
      (``PrimitiveParams.from_json`` or
      :func:`simlab.physics.motion.primitive_params_from_record` reads it back). With
      ``mode = "until_state_change"`` the walker gets the discretizer of ``states``.
    * ``ensemble``: each walk drives a member of the ``[[ensemble]]`` of ``primitives``
      (module docstring; needs ``primitives``, a file of ``simlab calibrate`` with an
      ensemble). ``manifest["parameters"]["primitive"]`` is then the file's
      ``[primitives]`` table (the winner, what replay takes), ``["ensemble"]`` holds
      ``size``, ``members`` (each member's record, overrides applied) and ``walk_members``
      (the member of each walk); rows carry ``twin_member``.
    * ``pose_source_options``: keyword arguments for the pose source factory.
    * ``start_states``: ``"all"`` or a list of states: one walk from each state's centre
      (its own seed stream, the budget split evenly; ``workers`` processes run them), so
      the walk covers the lab; recorded as ``manifest["parameters"]["start_states"]``.
      A centre where the robot does not fit (in or against an obstacle) starts its walk at
      the nearest place of the same state where it does, with a warning; a state where it
      fits nowhere is refused.
    * ``n_actions``/``convention``/``speed``: walk in a real robot's action set (see
      above); recorded as ``manifest["action_set"]``.
    * ``physics_hz``: the physics rate (default :data:`simlab.physics.rate.DEFAULT_HZ`,
      refused below :data:`~simlab.physics.rate.MIN_HZ`); recorded with its solver
      iterations as ``manifest["parameters"]["physics"]``, so a resume at another rate is
      refused and readers know the rate (:func:`simlab.data.manifest.physics_rate`).
    * ``progress``: show a tqdm bar with transitions/s and simulated hours per wall second.
    """

    COMMAND = "collect"
    ARGUMENTS = ("arena", "states")

    arena: Any = option("table", "built-in arena name or .toml path")
    states: Any | None = option(None, "states file written by `simlab discretize` (JSON) "
                         "(required)")
    out: Path = option(help="dataset directory (new or empty)")
    hours: float | None = option(
        None, "total simulated robot time in hours, split over the workers (or --transitions)")
    transitions: int | None = option(None, "total number of transitions (or --hours)")
    seed: int = option(0, "root seed")
    workers: int = option(1, "parallel walks, one arena per process")
    resume: bool = option(False, "continue an interrupted collection in --out")
    backend: str = option("local", "local process pool or Ray tasks", choices=BACKENDS)
    address: str | None = option(
        None, "Ray cluster address (ray backend; default: start Ray locally)")
    part_size: int = option(DEFAULT_PART_SIZE, "transitions per part file")
    pose_source: str = option("truth", "poses that are recorded and discretized",
                              choices=POSE_SOURCES)
    simulator: str = option("physics", "physics (PyBullet) or kinematic (physics-free "
                            "dry run)", choices=SIMULATORS)
    params: Any | None = option(None, "PrimitiveParams / KinematicParams / [primitives] TOML path "
                         "(Python and TOML only; default: the simulator's defaults)", cli=False)
    pose_source_options: Any | None = option(None, "keyword arguments of the pose source factory",
                                      cli=False)
    start_states: Any | None = option(
        None, "start a walk at the centre of each of these states, the budget split evenly "
        "over them: 'all' or a list such as 0,5,12 (default: one walk per worker from the "
        "arena's start pose)", metavar="all|LIST")
    progress: bool = option(True, "progress bar (--no-progress hides it)")
    physics_hz: float | None = rate_option()

    def validate(self) -> None:
        from simlab.physics.arena import check_arena_option

        check_arena_option(self.arena)
        if self.states is None:
            raise ConfigError("a states file is required", key="states",
                              fix="--states states.json (written by `simlab discretize`)")
        if (self.hours is None) == (self.transitions is None):
            raise ConfigError("give exactly one budget: --hours H or --transitions N",
                              key="budget")
        if self.hours is not None:
            v.positive(self.hours, "hours")
        if self.transitions is not None:
            v.whole(self.transitions, "transitions", minimum=1)
        v.whole(self.workers, "workers", minimum=1, maximum=999)
        if self.transitions is not None and self.transitions < self.workers:
            raise ConfigError(
                f"{self.transitions} transitions cannot be split over {self.workers} workers",
                key="workers", fix="use fewer workers or more transitions")
        v.whole(self.seed, "seed")
        v.whole(self.part_size, "part_size", minimum=1)
        self.make_action_set()  # a bad convention names its field here
        if self.start_states is not None:
            parse_start_states(self.start_states, None)
        self._check_backend()
        check_pose_source(self.pose_source, self.simulator)
        if self.simulator == "kinematic" and self.physics_hz is not None:
            raise ConfigError("the kinematic simulator has no physics step", key="physics_hz",
                              fix="drop --physics-hz or use --simulator physics")
        resolve_rate(self.physics_hz)  # a rate too coarse for the primitives is refused here
        if self.params is not None and not isinstance(self.params, str | os.PathLike):
            self.resolved_params()  # a table of a --config file: its keys and values checked
        if self.pose_source_options is not None and not isinstance(self.pose_source_options,
                                                                   dict):
            raise ConfigError(f"expected a table of the pose source's options, got "
                              f"{self.pose_source_options!r}", key="pose_source_options")
        if self.pose_source_options and self.pose_source != "mcl":
            raise ConfigError(f"the {self.pose_source} pose source takes no options",
                              key="pose_source_options",
                              fix='drop pose_source_options, or use pose_source = "mcl"')
        self.check_ensemble()
        if self.primitive_options_given:
            if self.simulator == "kinematic":
                raise ConfigError("primitive settings apply to the physics simulator only",
                                  key="--primitives",
                                  fix="drop them or use --simulator physics")
            if self.params is not None:
                raise ConfigError("give the primitive parameters once: params or the "
                                  "primitive options", key="params")

    def _check_backend(self) -> None:
        if self.backend == "local" and self.address is not None:
            raise ConfigError("--address applies to the ray backend only", key="address",
                              fix="add --backend ray or drop --address")
        if self.backend == "ray" and importlib.util.find_spec("ray") is None:
            raise ConfigError("the ray backend needs Ray", key="backend",
                              fix='pip install "simlab[ray]", or use --backend local')

    def resolved_params(self) -> Any:
        """The primitive parameters the walkers use (see the class docstring)."""
        if self.primitive_options_given:
            return self.primitive_params()
        if self.params is None:
            return _default_params(self.simulator)
        if isinstance(self.params, str | os.PathLike):  # a [primitives] TOML file
            from simlab.physics.motion import PrimitiveParams

            return PrimitiveParams.from_toml(self.params)
        if isinstance(self.params, dict):  # a table of a --config file
            if self.simulator == "kinematic":
                return v.table_of(KinematicParams, self.params, "params")
            from simlab.physics.motion import PrimitiveParams

            return PrimitiveParams.from_json(self.params, where="params")
        return self.params


def parse_start_states(value: Any, n_states: int | None) -> list[int] | None:
    """The start states of ``start_states`` (``"all"``, ``"0,5,12"`` or a list of ints);
    None for the arena's start pose. ``n_states`` None checks the spelling only."""
    if value is None:
        return None
    if isinstance(value, str) and value.strip().lower() == "all":
        return None if n_states is None else list(range(int(n_states)))
    starts = list(v.state_ids(value, "start_states") or ())
    if n_states is not None:
        bad = [s for s in starts if not 0 <= s < n_states]
        if bad:
            raise ConfigError(f"state {bad[0]} is not one of the {n_states} states",
                              key="start_states", fix=f"use states 0..{n_states - 1}")
    return starts


def _walks(cfg: CollectConfig, n_states: int
           ) -> tuple[list[int] | None, int, list[int] | None, float | None]:
    """``(start states or None, number of walks, transitions per walk, seconds per walk)``:
    one walk per worker from the arena's start, or one per start state; the budget is split
    evenly over the walks."""
    starts = parse_start_states(cfg.start_states, n_states)
    walks = cfg.workers if starts is None else len(starts)
    if cfg.transitions is not None and cfg.transitions < walks:
        raise ConfigError(f"{cfg.transitions} transitions cannot be split over {walks} "
                          "start states", key="start_states",
                          fix="use fewer start states or more transitions")
    per_worker = None if cfg.transitions is None else _split_transitions(
        int(cfg.transitions), walks)
    t_budget = None if cfg.hours is None else float(cfg.hours) * 3600.0 / walks
    return starts, walks, per_worker, t_budget


def _start_poses(starts: list[int] | None, disc: Any, arena: Any, states: Any
                 ) -> list[tuple[float, float, float]] | None:
    """Truth start pose of each walk, facing +x (the first primitive turns to its own
    heading anyway): where the robot is put down in its state
    (:func:`simlab.base.statecheck.start_positions`: the centre, or the nearest place of
    the state where it fits, warned; a state where it fits nowhere is refused)."""
    if starts is None:
        return None
    from simlab.base.statecheck import start_positions
    from simlab.physics.robot import load_robot_spec

    source = states if isinstance(states, str | os.PathLike) else None
    return [(x, y, 0.0) for x, y in start_positions(starts, disc, arena,
                                                     load_robot_spec().footprint,
                                                     source=source)]


@dataclass(frozen=True)
class WalkPlan:
    """The walks of one collection, planned without its directory (:func:`plan_walks`).

    ``collect`` writes their parts; :func:`walk_results` runs the walks of several plans
    at once in memory (calibration's candidates), so both run the same parts.

    Attributes:
        cfg: the collection's options (``out`` unused here).
        arena: the ``ArenaConfig``; ``disc``: the states' discretizer.
        params: the primitive parameters (the ``[primitives]`` winner with an ensemble).
        members: the twin ensemble's members, or None.
        specs: the walkers' specs: one, or one per member of the twin ensemble.
        starts: start state of each walk, or None (one walk per worker from the start).
        walks: the number of walks.
        per_worker: transitions of each walk (``transitions`` budget), or None.
        t_budget: simulated seconds of each walk (``hours`` budget), or None.
        start_poses: truth start pose of each walk, or None (the arena's start).
        walk_members: the member (index into ``specs``) of each walk; None without an
            ensemble.
    """

    cfg: CollectConfig
    arena: Any
    disc: Any
    params: Any
    members: tuple[Any, ...] | None
    specs: tuple[WalkSpec, ...]
    starts: list[int] | None
    walks: int
    per_worker: list[int] | None
    t_budget: float | None
    start_poses: list[tuple[float, float, float]] | None
    walk_members: tuple[int, ...] | None = None

    def member(self, walk: int) -> int | None:
        return None if self.walk_members is None else self.walk_members[walk]

    def job(self, walk: int, st: _WorkerState) -> PartJob:
        """The next part of walk ``walk``, which is at ``st``."""
        return PartJob(spec=self.specs[self.member(walk) or 0], seed=int(self.cfg.seed),
                       worker=walk, part=st.next_part, t0=st.t, pose0=st.pose,
                       part_size=int(self.cfg.part_size), remaining=st.remaining,
                       t_budget=self.t_budget)

    def fresh_states(self) -> list[_WorkerState]:
        """Every walk at its start."""
        return [_WorkerState(remaining=None if self.per_worker is None else self.per_worker[w],
                             pose=None if self.start_poses is None else self.start_poses[w])
                for w in range(self.walks)]


def plan_walks(cfg: CollectConfig) -> WalkPlan:
    """The walks of ``cfg`` (its directory is not touched): inputs loaded, the budget split
    over the walks, start poses and the walkers' specs."""
    arena_cfg = load_arena_config(cfg.arena)
    disc = load_discretizer(cfg.states)
    params = cfg.resolved_params()
    members = cfg.primitive_ensemble()
    starts, walks, per_worker, t_budget = _walks(cfg, int(disc.n_states))
    walk_members = None if members is None else tuple(
        ensemble_members(cfg.seed, walks, len(members)))
    specs = tuple(_walk_spec(cfg, arena_cfg, disc, p)
                  for p in (members if members is not None else (params,)))
    return WalkPlan(cfg=cfg, arena=arena_cfg, disc=disc, params=params, members=members,
                    specs=specs, starts=starts, walks=walks, per_worker=per_worker,
                    t_budget=t_budget,
                    start_poses=_start_poses(starts, disc, arena_cfg, cfg.states),
                    walk_members=walk_members)


@dataclass(frozen=True)
class _Run:
    """What every part of one collection shares (built once by :func:`collect`): its
    plan, directory and schema."""

    plan: WalkPlan
    out: Path
    schema: pa.Schema


@command(CollectConfig)
def collect(cfg: CollectConfig) -> CollectResult:
    """Collect an epsilon = 1 random-walk transition dataset into the directory ``out``.

    Takes a :class:`CollectConfig` or its fields as arguments (``collect("table",
    "states.json", out=..., hours=1.0)``); the fields are documented there.

    Returns:
        A :class:`CollectResult`.

    Raises:
        ConfigError: bad options; a non-empty ``out`` without ``resume``; a resume with
            options that differ from the dataset's (naming the field).
        DataError: a listed part is missing, truncated or corrupted (naming the file).
    """
    wall0 = time.perf_counter()
    out = Path(cfg.out)
    plan = plan_walks(cfg)
    disc, members, per_worker = plan.disc, plan.members, plan.per_worker
    schema = transition_schema(cfg.pose_source, twin_member=members is not None)
    manifest = _new_manifest(cfg, plan.arena, disc, plan.params, schema, per_worker,
                             plan.t_budget, plan.starts)
    if members is not None:
        manifest["parameters"]["ensemble"] = _jsonable({
            "size": len(members), "members": [m.to_json() for m in members],
            "walk_members": list(plan.walk_members or ())})
    if cfg.backend == "ray" and cfg.address is not None:  # before --out is touched
        from simlab.base.parallel import check_reachable

        check_reachable(cfg.address)
    # One run per directory: a second collect on the same --out stops here.
    with exclusive_directory(out, what="dataset directory"):
        manifest = _prepare_directory(out, manifest, cfg.resume)
        run = _Run(plan=plan, out=out, schema=schema)
        wstates = _worker_states(manifest, plan, out)
        orphans = _orphans(out, manifest)
        written, peak_rss, cpu = _run_parts(run, manifest, wstates, orphans)
        for name in orphans:  # left by a run killed at a point this run never reached
            (out / name).unlink(missing_ok=True)
        return CollectResult(
            directory=out,
            transitions=sum(int(e["rows"]) for e in manifest["parts"]),
            parts=len(manifest["parts"]),
            parts_written=written,
            simulated_seconds=float(sum(st.t for st in wstates)),
            wall_seconds=time.perf_counter() - wall0,
            peak_worker_rss_mb=peak_rss,
            complete=bool(manifest["complete"]),
            worker_cpu_seconds=tuple(cpu),
            states_visited=_states_visited(out, manifest),
            n_states=int(disc.n_states),
            physics_hz=physics_rate(manifest),
        )


def _states_visited(out: Path, manifest: dict[str, Any]) -> int:
    """Number of states in ``s`` or ``s_next`` of the dataset's parts."""
    import pyarrow.parquet as pq

    seen: set[int] = set()
    for entry in manifest["parts"]:
        table = pq.read_table(out / str(entry["file"]), columns=["s", "s_next"])
        for name in ("s", "s_next"):
            seen.update(np.unique(table.column(name).to_numpy()).tolist())
    return len(seen)


def _new_manifest(cfg: CollectConfig, arena_cfg: Any, disc: Any, params: Any,
                  schema: pa.Schema, per_worker: list[int] | None,
                  t_budget: float | None, starts: list[int] | None) -> dict[str, Any]:
    """The manifest this run writes (or checks a resumed directory's against)."""
    from simlab import __version__
    from simlab.base.statecheck import check_centres_in_arena

    states = cfg.states
    aset = cfg.make_action_set()
    parameters = _jsonable({
        "epsilon": 1.0,
        "n_actions": aset.n_actions,
        "hours": None if cfg.hours is None else float(cfg.hours),
        "transitions": None if cfg.transitions is None else int(cfg.transitions),
        "seconds_per_worker": t_budget,
        "transitions_per_worker": per_worker,
        "part_size": int(cfg.part_size),
        "primitive": params.to_json() if hasattr(params, "to_json") else params,
        "pose_source_options": cfg.pose_source_options or {},
    })
    centres = np.asarray(disc.centres, dtype=np.float64)
    check_centres_in_arena(centres, arena_cfg,
                           source=str(states) if isinstance(states, str | os.PathLike) else None)
    manifest = new_manifest(
        simlab_version=__version__,
        arena=_arena_info(arena_cfg),
        robot=_robot_info(cfg.simulator),
        simulator=cfg.simulator,
        pose_source=cfg.pose_source,
        discretizer={
            "hash": disc.content_hash(),
            "n_states": int(disc.n_states),
            "centres": centres.tolist(),
        },
        seed=int(cfg.seed),
        workers=int(cfg.workers) if starts is None else len(starts),
        parameters=parameters,
        schema=schema_to_json(schema),
    )
    # Recorded only when given, so that a default collection's manifest is unchanged.
    if aset != SIMLAB16:
        manifest["action_set"] = aset.to_json()
    if starts is not None:
        manifest["parameters"]["start_states"] = list(starts)
    if cfg.simulator == "physics":
        hz = resolve_rate(cfg.physics_hz)
        manifest["parameters"]["physics"] = settings_for(hz).to_json()
    manifest["sources"] = {
        "arena_file": getattr(arena_cfg, "source", None),
        "states_file": None if not isinstance(states, str | os.PathLike) else str(states),
    }
    return _jsonable(manifest)


def _walk_spec(cfg: CollectConfig, arena_cfg: Any, disc: Any, params: Any) -> WalkSpec:
    """What every part's walker is built from; ``key`` names it for the worker caches."""
    physics_hz = resolve_rate(cfg.physics_hz) if cfg.simulator == "physics" else None
    key_src = json.dumps({"arena": _jsonable(_arena_info(arena_cfg)),
                          "simulator": cfg.simulator, "pose_source": cfg.pose_source},
                         sort_keys=True) + repr(params) + repr(cfg.pose_source_options) \
        + repr(physics_hz)
    return WalkSpec(
        key=hashlib.sha256(key_src.encode()).hexdigest(),
        simulator=cfg.simulator,
        arena=arena_cfg,
        params=params,
        pose_source=cfg.pose_source,
        pose_source_options=dict(cfg.pose_source_options or {}),
        discretizer=disc if getattr(params, "mode", "fixed") == "until_state_change" else None,
        primitives=tuple(int(p) for p in cfg.make_action_set().primitives()),
        physics_hz=physics_hz,
    )


def run_walks(backend: Any, walks: list[tuple[WalkPlan, int, _WorkerState]],
              record: Callable[[WalkPlan, int, PartResult], None]) -> None:
    """Run every walk ``(plan, walk index, its state)`` of ``walks`` to its end on
    ``backend`` (a :class:`~simlab.data.backends.PartBackend`), one part of each walk in
    flight: the first part of every walk, in the order given, then a walk's next part as
    soon as its last is back. ``record(plan, walk, result)`` runs in this process for each
    finished part, in the order they finish, and must advance the walk's state (its
    ``next_part``, ``t``, ``pose``, ``remaining``, ``done``)."""
    handles = {backend.submit(plan.job(w, st)): (plan, w, st)
               for plan, w, st in walks if not st.done}
    while handles:
        for handle, result in backend.wait(list(handles)):
            plan, w, st = handles.pop(handle)
            record(plan, w, result)
            if not st.done:
                handles[backend.submit(plan.job(w, st))] = (plan, w, st)


def _advance(st: _WorkerState, result: PartResult) -> float:
    """Move a walk's state past its finished part ``result``; the simulated seconds the
    part covered."""
    st.next_part += 1
    st.step += result.rows
    sim_delta = result.t_end - st.t
    st.t, st.pose, st.done = result.t_end, result.pose_end, result.final
    if st.remaining is not None:
        st.remaining -= result.rows
    return sim_delta


def walk_results(plans: list[WalkPlan], backend: Any) -> list[list[PartResult]]:
    """Run the walks of every plan in memory, nothing written: the parts of all the plans'
    walks share ``backend``'s workers (a :class:`~simlab.data.backends.PartBackend`), so
    several small collections keep every worker busy. Per plan, its parts in walk and part
    order: the rows ``collect`` would write for it (a part depends only on its job)."""
    out: list[dict[tuple[int, int], PartResult]] = [{} for _ in plans]
    index = {id(plan): k for k, plan in enumerate(plans)}
    states = {id(plan): plan.fresh_states() for plan in plans}

    def record(plan: WalkPlan, w: int, result: PartResult) -> None:
        out[index[id(plan)]][(w, result.part)] = result
        _advance(states[id(plan)][w], result)

    run_walks(backend, [(plan, w, st) for plan in plans
                        for w, st in enumerate(states[id(plan)])], record)
    return [[parts[key] for key in sorted(parts)] for parts in out]


def part_states(result: PartResult, disc: Any) -> tuple[NDArray[np.int32], NDArray[np.int32]]:
    """``(s, s_next)`` (n,) of a finished part: the states of its recorded poses."""
    cols, n = result.columns, result.rows
    xy = np.stack([cols["x"], cols["y"]], axis=1)
    xy_next = np.stack([cols["x_next"], cols["y_next"]], axis=1)
    return (np.asarray(disc.state_of(xy), dtype=np.int32).reshape(n),
            np.asarray(disc.state_of(xy_next), dtype=np.int32).reshape(n))


def _run_parts(run: _Run, manifest: dict[str, Any], wstates: list[_WorkerState],
               orphans: set[str]) -> tuple[int, float, list[float]]:
    """Compute the missing parts, writing each with the manifest listing it.

    Returns (parts written, peak worker RSS in MiB, CPU seconds per worker)."""
    plan = run.plan
    cfg = plan.cfg
    done_rows = sum(int(e["rows"]) for e in manifest["parts"])
    bar = _Progress(cfg.progress, transitions=cfg.transitions, hours=cfg.hours,
                    done_rows=done_rows, done_seconds=sum(st.t for st in wstates))
    cpu = [0.0] * plan.walks
    totals = {"written": 0, "rss": 0.0}
    pending = [w for w in range(plan.walks) if not wstates[w].done]
    if not pending:
        bar.close()
        if not manifest["complete"]:
            manifest["complete"] = True
            write_manifest(run.out, manifest)
        return 0, 0.0, cpu

    def record(_plan: WalkPlan, w: int, result: PartResult) -> None:
        sim_delta = _record_part(run, manifest, wstates, result, orphans)
        totals["written"] += 1
        totals["rss"] = max(totals["rss"], result.peak_rss_mb)
        cpu[w] += result.cpu_seconds
        bar.update(result.rows, sim_delta)

    runner = make_backend(cfg.backend, min(cfg.workers, len(pending)), cfg.address)
    try:
        run_walks(runner, [(plan, w, wstates[w]) for w in pending], record)
    finally:
        runner.close()
        bar.close()
    return int(totals["written"]), float(totals["rss"]), cpu


def _record_part(run: _Run, manifest: dict[str, Any], wstates: list[_WorkerState],
                 result: PartResult, orphans: set[str]) -> float:
    """Write one finished part, then the manifest listing it; advance its worker's state.
    Returns the simulated seconds the part covered."""
    st = wstates[result.worker]
    plan = run.plan
    table = _part_table(result, st.step, plan.disc, plan.cfg.pose_source, run.schema,
                        plan.member(result.worker))
    entry = write_part(run.out, result.worker, result.part, table, plan.disc.content_hash())
    orphans.discard(entry["file"])
    entry.update(t_end=result.t_end, pose_end=list(result.pose_end), final=result.final)
    manifest["parts"].append(entry)
    manifest["parts"].sort(key=lambda e: (e["worker"], e["part"]))
    sim_delta = _advance(st, result)
    manifest["complete"] = all(s.done for s in wstates)
    write_manifest(run.out, manifest)
    return sim_delta


class _Progress:
    """tqdm bar in transitions (``--transitions``) or simulated hours (``--hours``),
    with the other rate as a postfix; aggregated over workers, updated per part."""

    def __init__(self, enabled: bool, *, transitions: int | None, hours: float | None,
                 done_rows: int, done_seconds: float) -> None:
        self._bar = None
        self._rows = 0
        self._seconds = 0.0
        self._t0 = time.perf_counter()
        self._by_rows = transitions is not None
        if not enabled:
            return
        from tqdm.auto import tqdm

        if self._by_rows:
            self._bar = tqdm(total=int(transitions), initial=done_rows, unit="tr",
                             desc="collect", dynamic_ncols=True)
        else:
            self._bar = tqdm(total=float(hours), initial=round(done_seconds / 3600.0, 3),
                             unit="sim-h", desc="collect", dynamic_ncols=True,
                             bar_format="{l_bar}{bar}| {n:.2f}/{total:.2f} sim-h "
                                        "[{elapsed}<{remaining}{postfix}]")

    def update(self, rows: int, sim_seconds: float) -> None:
        self._rows += rows
        self._seconds += sim_seconds
        if self._bar is None:
            return
        wall = max(time.perf_counter() - self._t0, 1e-9)
        # tqdm shows the rate of its own unit; the other rate goes in the postfix.
        if self._by_rows:
            postfix = {"sim-h/s": f"{self._seconds / 3600.0 / wall:.3f}"}
        else:  # (tqdm would print its own rate upside down, as s/sim-h, when below 1)
            postfix = {"sim-h/s": f"{self._seconds / 3600.0 / wall:.3f}",
                       "tr/s": f"{self._rows / wall:.1f}"}
        self._bar.set_postfix(postfix, refresh=False)
        if self._by_rows:
            self._bar.update(rows)
        else:  # the last primitive of a worker may end past its budget: clamp the bar
            self._bar.update(max(0.0, min(sim_seconds / 3600.0, self._bar.total - self._bar.n)))

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
