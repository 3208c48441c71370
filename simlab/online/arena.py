"""``simlab online --arena``: the online experiment in physics, on an arena as on an MDP.

The options of :class:`ArenaOptions` (a field group of
:class:`~simlab.online.command.OnlineConfig`) name the robot's world: an ``arena`` (a
built-in name or the TOML of ``simlab arena-from-map``), its ``states`` (``simlab
discretize``), the primitives (``--primitives`` the ``primitives.toml`` of ``simlab
calibrate``, or the direct flags), the robot's action set (``--n-actions 8 --convention
ccw-east --speed fast`` for a real lab's 8 actions) and the pose source (``truth``, which
carries the calibrated twin's own localization error when its primitives have one, or
``mcl``). Every run of every arm drives its own world (:mod:`simlab.online.physics`) in a
worker process; the outputs are those of the MDP runs plus the physics' own figures.

With ``--ensemble`` (domain randomisation over calibrate's twin ensemble) run ``i`` drives
the member :func:`~simlab.physics.primitive_options.ensemble_members` draws for it from
``--seed``: the same member in every arm, as run ``i`` of every arm shares its random
streams (common random numbers), and the same whatever the workers. ``summary.json``
records the ensemble's size and each run's member (``physics.ensemble``).

Decisions: the passages of ``--change passages`` are closed by boxes on their doorways
(:mod:`simlab.online.doorway`), or with ``--closing remove`` as the published experiment's
edited models close them, their transitions removed (:mod:`simlab.online.physics`);
``--after`` (a second model) has no physics meaning and is refused. Progress counts decisions over every run (workers report every
:data:`REPORT_EVERY` decisions).
"""

from __future__ import annotations

import dataclasses
import threading
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base.actions import ActionSetOptions
from simlab.base.errors import ConfigError
from simlab.base.options import option
from simlab.physics.primitive_options import TwinEnsembleOptions
from simlab.physics.rate import rate_option, resolve_rate

__all__ = [
    "PHYSICS_FILES",
    "ArenaOptions",
    "PhysicsJob",
    "physics_lab",
    "physics_summary",
    "physics_task",
    "run_physics_job",
    "run_physics_jobs",
]

#: Decisions between two progress reports of a worker.
REPORT_EVERY = 25
#: The physics runs' own figures, beside the MDP runs' outputs.
PHYSICS_FILES = ("physics.png", "visits.png")
#: What a physics run returns per run, not per decision (not columns of decisions.parquet).
PHYSICS_RUN_FIELDS = ("wall_seconds", "boxes")


@dataclasses.dataclass(frozen=True, kw_only=True)
class ArenaOptions(ActionSetOptions, TwinEnsembleOptions):
    """Where ``simlab online`` runs in physics (module docstring): arena, states, pose."""

    arena: Any | None = option(
        None, "learn in physics on this arena (built-in name or the .toml of simlab "
        "arena-from-map) instead of an MDP; needs --states", metavar="ARENA")
    states: Any | None = option(None, "states file of the arena (simlab discretize); the "
                                "goal and start states are its states")
    pose_source: str = option("truth", "pose the states are read from in physics: truth "
                              "(with the primitives' localization error, if any) or mcl "
                              "(a particle filter on the arena's map)", choices=("truth", "mcl"))
    closing: str = option("box", "in physics, how --change passages closes a passage: box "
                          "(a box on its doorway) or remove (as an edited model: its "
                          "transitions removed, a move across it taken back and drawn "
                          "again; truth pose only)", choices=("box", "remove"))
    mcl_map: str = option("updated", "in physics with --pose-source mcl, the filter's map "
                          "after a box is added: updated (it knows the box) or stale",
                          choices=("updated", "stale"))
    map: Path | None = option(None, "map_server YAML the particle filter localizes on "
                              "(--pose-source mcl; default: the arena's own walls)")
    physics_hz: float | None = rate_option()

    @property
    def in_physics(self) -> bool:
        return self.arena is not None

    def check_arena_options(self) -> None:
        """:class:`ConfigError` for arena options given without an arena (and the reverse)."""
        if self.arena is None:
            given = [k for k in ("states", "map", "physics_hz") if getattr(self, k) is not None]
            if self.primitive_options_given:
                given.append("primitives")
            if self.ensemble:
                given.append("ensemble")
            if self.action_set_given:
                given.append("n_actions")
            if self.pose_source != "truth" or self.mcl_map != "updated":
                given.append("pose_source")
            if self.closing != "box":
                given.append("closing")
            if given:
                raise ConfigError(f"--{given[0].replace('_', '-')} applies to a run in "
                                  "physics only", key=given[0],
                                  fix="add --arena ARENA --states STATES, or drop it")
            return
        from simlab.physics.arena import check_arena_option

        check_arena_option(self.arena)
        self.check_ensemble()
        if self.states is None:
            raise ConfigError("a run in physics needs the arena's states", key="states",
                              fix="--states states.json (written by simlab discretize)")
        if self.map is not None and self.pose_source != "mcl":
            raise ConfigError("--map is the particle filter's map", key="map",
                              fix="add --pose-source mcl or drop --map")
        if self.mcl_map != "updated" and self.pose_source != "mcl":
            raise ConfigError(f"--mcl-map {self.mcl_map} is what the particle filter's map "
                              f"does after a box is added; --pose-source {self.pose_source} "
                              "has no filter", key="mcl_map",
                              fix="add --pose-source mcl or drop --mcl-map")
        resolve_rate(self.physics_hz)


@dataclasses.dataclass(frozen=True)
class PhysicsJob:
    """One physics run's settings (they travel together to the worker): the
    :class:`~simlab.online.physics.PhysicsLab`, the
    :class:`~simlab.online.physics.PhysicsTask`, the experts' agent configs, the
    :class:`~simlab.online.meta.Arbitration` and the environment's
    :data:`~simlab.online.protocol.LoopRules`."""

    lab: Any
    task: Any
    mf_config: Any
    mb_config: Any
    arbitration: Any
    rules: Any = None


def physics_lab(cfg: Any) -> Any:
    """The :class:`~simlab.online.physics.PhysicsLab` of ``cfg``'s arena options; the
    states are checked against the arena (centres off the floor are a warning)."""
    import os

    from discretize.voronoi import load_states
    from simlab.base.statecheck import check_centres_in_arena
    from simlab.online.physics import PhysicsLab
    from simlab.physics.arena import load_arena
    from simlab.physics.motion import PrimitiveParams

    arena = load_arena(cfg.arena)
    states = cfg.states
    disc = load_states(states) if isinstance(states, str | os.PathLike) else states
    check_centres_in_arena(np.asarray(disc.centres, dtype=float), arena,
                           source=str(states) if isinstance(states, str | os.PathLike)
                           else None)
    params = cfg.primitive_params() or PrimitiveParams()
    aset = cfg.make_action_set()
    options = {} if cfg.map is None else {"map": str(cfg.map)}
    return PhysicsLab(arena, disc, params, tuple(int(p) for p in aset.primitives()), options,
                      physics_hz=resolve_rate(cfg.physics_hz))


def physics_task(cfg: Any, lab: Any) -> Any:
    """The :class:`~simlab.online.physics.PhysicsTask` of ``cfg`` on ``lab``: the task of
    the same options on an MDP (:meth:`~simlab.online.command.OnlineConfig.task`, so the
    same checks and the same passage choice by use), its passages closed by boxes on their
    doorways (found now: a passage that does not exist is refused before any run) or by
    removing their transitions (``--closing remove``)."""
    from simlab.online.physics import PhysicsChange, PhysicsTask

    changes = tuple(PhysicsChange(c.at, c.kind, goal=tuple(c.goal), passages=c.passages,
                                  use_states=c.use_states,
                                  closing=cfg.closing if c.kind == "passages" else "box")
                    for c in cfg.task().changes)
    task = PhysicsTask(tuple(cfg.goal), tuple(cfg.start_states), int(cfg.decisions), changes,
                       pose_source=cfg.pose_source, mcl_map=cfg.mcl_map)
    task.check_states(lab.n_states)
    _check_starts(cfg, lab, task)
    for c in task.changes:
        lab.boxes_of(c)
    return task


def _check_starts(cfg: Any, lab: Any, task: Any) -> None:
    """Where each start state puts the robot down, said once before any run
    (:func:`simlab.base.statecheck.start_positions`: a centre where it does not fit is
    warned of, a state where it fits nowhere refused); each restart then puts it down by
    the same rule at its heading (:mod:`simlab.online.physics`)."""
    import os

    from simlab.base.statecheck import start_positions
    from simlab.physics.robot import load_robot_spec

    source = cfg.states if isinstance(cfg.states, str | os.PathLike) else None
    start_positions(task.start_states, lab.discretizer, lab.arena,
                    load_robot_spec().footprint, source=source)


def run_physics_job(job: PhysicsJob, seed: np.random.SeedSequence, progress: Any = None
                    ) -> dict[str, np.ndarray]:
    """One physics run (a parallel job): a fresh agent learns in a fresh world. Returns
    its log columns (:meth:`~simlab.online.physics.PhysicsRun.columns`) and
    ``wall_seconds``. ``progress`` a queue told the decisions made, in batches."""
    from simlab.online.physics import RunStreams, run_physics_online

    agent = job.arbitration.agent(job.mf_config, job.mb_config, job.lab.n_states,
                                  job.lab.n_actions)
    tell = None
    if progress is not None:
        pending = [0]

        def tell(k: int) -> None:
            pending[0] += k
            if pending[0] >= REPORT_EVERY:
                progress.put(pending[0])
                pending[0] = 0

    run = run_physics_online(agent, job.lab, job.task, RunStreams.from_seed(seed),
                             rules=job.rules, progress=tell)
    if progress is not None and pending[0]:
        progress.put(pending[0])
    cols = run.columns()
    cols["wall_seconds"] = np.array([run.wall_seconds])
    cols["boxes"] = np.asarray(run.boxes, dtype=float).reshape(-1, 5)
    return cols


class _Direct:
    """The bar's queue when the runs are in this process: a put updates the bar."""

    def __init__(self, bar: Any) -> None:
        self.bar = bar

    def put(self, k: int) -> None:
        self.bar.update(int(k))


class _DecisionBar:
    """A tqdm bar of the decisions of every run: fed directly by runs in this process,
    through a manager queue by local worker processes; Ray tasks get no queue (the
    executor's bar of finished runs is shown instead)."""

    def __init__(self, total: int, enabled: bool, where: str) -> None:
        self.queue: Any = None
        self._thread: threading.Thread | None = None
        self._manager: Any = None
        self._bar: Any = None
        if not enabled or where not in ("in-process", "local"):
            return
        from tqdm.auto import tqdm

        self._bar = tqdm(total=total, desc="online decisions (physics)", unit="dec",
                         dynamic_ncols=True)
        if where == "in-process":
            self.queue = _Direct(self._bar)
            return
        from simlab.base.parallel import manager

        try:
            self._manager = manager()
        except BaseException:
            self._bar.close()
            raise
        self.queue = self._manager.Queue()
        self._thread = threading.Thread(target=self._drain, daemon=True)
        self._thread.start()

    def _drain(self) -> None:
        while True:
            k = self.queue.get()
            if k is None:
                return
            self._bar.update(int(k))

    def close(self) -> None:
        if self._thread is not None:
            self.queue.put(None)
            self._thread.join(timeout=5)
            self._manager.shutdown()
        if self._bar is not None:
            self._bar.close()


def run_physics_jobs(jobs: list[dict[str, Any]], executor: Any, progress: bool,
                     total: int) -> list[dict[str, np.ndarray]]:
    """Every physics run of ``jobs`` (keyword arguments of :func:`run_physics_job`) on
    ``executor``, with a bar of decisions (``total``) when ``progress``.

    A run that fails or a Ctrl-C ends the executor's workers before the bar's queue goes:
    a queued job still holds the queue's proxy (:func:`simlab.base.parallel.manager`)."""
    bar = _DecisionBar(total, progress, getattr(executor, "name", ""))
    try:
        if bar.queue is not None:
            jobs = [{**j, "progress": bar.queue} for j in jobs]
        return executor.map(run_physics_job, jobs, desc="online runs (physics)",
                            progress=progress and bar.queue is None)
    except BaseException:
        if bar.queue is not None:
            executor.stop_now()
        raise
    finally:
        bar.close()


def physics_summary(logs: dict[str, list[dict[str, np.ndarray]]], at: int | None,
                    physics_hz: float | None = None,
                    run_members: tuple[int, ...] | None = None,
                    ensemble_size: int = 0) -> dict[str, Any]:
    """Per arm: the share of blocked primitives (before / after the change; after it also
    ``undone_after``, the moves taken back per decision across removed passages), simulated
    hours per run, the decisions per wall second of a run; the boxes added and the physics
    rate (``physics_hz``, Hz) the world stepped at; with a twin ensemble, ``ensemble``:
    its ``size`` and ``run_members``, the member run ``i`` of every arm drove."""
    arms: dict[str, Any] = {}
    boxes: list[list[float]] = []
    for name, runs in logs.items():
        blocked = np.stack([r["blocked"] for r in runs]).astype(float)
        hours = np.array([r["duration"].sum() / 3600.0 for r in runs])
        rate = np.array([r["s"].shape[0] / max(float(r["wall_seconds"][0]), 1e-9)
                         for r in runs])
        rec: dict[str, Any] = {"blocked": float(blocked.mean()),
                               "robot_hours": {"mean": float(hours.mean()),
                                               "std": float(hours.std())},
                               "decisions_per_wall_second": float(np.median(rate))}
        if at is not None:
            rec["blocked_before"] = float(blocked[:, :at].mean())
            rec["blocked_after"] = float(blocked[:, at:].mean())
            undone = np.stack([r["undone"] for r in runs]).astype(float)
            rec["undone_after"] = float(undone[:, at:].mean())
        arms[name] = rec
        if not boxes and runs[0]["boxes"].size:
            boxes = np.round(runs[0]["boxes"], 4).tolist()
    out = {"arms": arms, "boxes": boxes, "physics_hz": resolve_rate(physics_hz)}
    if run_members is not None:
        out["ensemble"] = {"size": int(ensemble_size),
                           "run_members": [int(m) for m in run_members]}
    return out
