"""A candidate's walk: parameters in, a count table in the real action set out.

Each evaluation is the random walk :func:`simlab.data.collect.collect` would write, run in
memory (:func:`simlab.data.collect.walk_results`: the same parts, nothing written), drawing
only the primitives of the real actions (:meth:`~simlab.base.actions.ActionSet.primitives`,
recorded in the real numbering), by default from every state's centre in turn (one walk per
state, the budget split evenly). Walks run on :mod:`simlab.base.parallel` (local processes,
or Ray with an address), walk by walk (:class:`WalkRunner`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.base.actions import SIMLAB16, ActionSet


@dataclass(frozen=True)
class WalkJob:
    index: int
    arena: Any
    states: Any
    params: Any
    hours: float | None
    transitions: int | None
    seed: int
    simulator: str
    pose_source: str
    action_set: ActionSet
    start_states: Any
    n_states: int



@dataclass(frozen=True)
class SimTable:
    """A candidate's walk, in the real action set.

    Attributes:
        counts: ``(S, A_real, S)`` counts.
        rows: transitions of the walk; ``walk_rows`` the same (the walk draws only the
            real actions' primitives).
        blocked: blocked transitions.
        mean_duration: mean stepped duration (s) of a transition (no idle time).
        hours: time of the walk with the decision latency (h).
        wall_seconds: wall time of the evaluation.
    """

    counts: NDArray[np.int64]
    rows: int
    walk_rows: int
    blocked: int
    mean_duration: float
    hours: float
    wall_seconds: float



def action_set_options(aset: ActionSet) -> dict[str, Any]:
    """``collect``'s action-set fields for ``aset`` (none for simlab's 16): the convention
    by name when it has one (``ccw-east``), else its directions (``3,5,1,...``)."""
    if aset == SIMLAB16:
        return {}
    name = aset.to_json()["convention"]
    return {"n_actions": aset.n_actions,
            "convention": name if name != "custom" else
            ",".join(str(d) for d in aset.directions),
            "speed": aset.speed}



def walk_plan(job: WalkJob) -> Any:
    """The collection ``job`` walks (:func:`simlab.data.collect.plan_walks`), one walk per
    start state; nothing is written."""
    import os

    from simlab.data.collect import CollectConfig, plan_walks

    cfg = CollectConfig(arena=job.arena, states=job.states, out=Path(os.devnull),
                        hours=job.hours, transitions=job.transitions, seed=job.seed,
                        simulator=job.simulator, pose_source=job.pose_source,
                        params=job.params, start_states=job.start_states, progress=False,
                        **action_set_options(job.action_set))
    cfg.validate()
    return plan_walks(cfg)


def table_of(job: WalkJob, plan: Any, parts: list[Any]) -> SimTable:
    """The count table of ``job``'s finished walk ``parts`` (in walk and part order)."""
    from simlab.data.collect import part_states
    from simlab.data.count_model import count_transitions

    states = [part_states(r, plan.disc) for r in parts]  # a walk has one part or more
    s = np.concatenate([x[0] for x in states])
    s_next = np.concatenate([x[1] for x in states])
    a = np.concatenate([r.columns["a"] for r in parts])
    blocked = np.concatenate([r.columns["blocked"] for r in parts])
    duration = np.concatenate([r.columns["duration"] for r in parts])
    counts = count_transitions(s, a, s_next, job.n_states, job.action_set.n_actions)
    rows = int(a.size)
    latency = float(job.params.decision_latency)
    return SimTable(counts=counts, rows=rows, walk_rows=rows, blocked=int(blocked.sum()),
                    mean_duration=float(duration.mean()) if rows else float("nan"),
                    hours=float((duration + latency).sum()) / 3600.0,
                    wall_seconds=float(sum(r.wall_seconds for r in parts)))


def simulate_table(job: WalkJob) -> SimTable:
    """One candidate's walk, in this process."""
    runner = WalkRunner(1)
    try:
        return runner.map([job])[0]
    finally:
        runner.close()


def simulate_counts(arena: Any, states: Any, params: Any, *, hours: float | None = None,
                    transitions: int | None = None, seed: int, action_set: ActionSet,
                    simulator: str = "physics", pose_source: str = "truth",
                    start_states: Any = None) -> SimTable:
    """One walk of ``hours`` simulated hours (or ``transitions``) in ``action_set``, in
    this process.

    What a candidate's evaluation does; also a way to make a synthetic "real" table with
    hidden parameters (tests, benchmarks).
    """
    from simlab.physics.inputs import load_arena_config, load_discretizer

    disc = load_discretizer(states)
    return simulate_table(WalkJob(index=0, arena=load_arena_config(arena), states=disc,
                               params=params, hours=None if hours is None else float(hours),
                               transitions=None if transitions is None else int(transitions),
                               seed=int(seed), simulator=simulator, pose_source=pose_source,
                               action_set=action_set, start_states=start_states,
                               n_states=int(disc.n_states)))



def pool_tables(tables: list[SimTable]) -> SimTable:
    """The walks of ``tables`` as one table (counts and rows summed)."""
    rows = sum(t.rows for t in tables)
    dur = sum(t.mean_duration * t.rows for t in tables if t.rows)
    return SimTable(counts=sum(t.counts for t in tables), rows=rows,
                    walk_rows=sum(t.walk_rows for t in tables),
                    blocked=sum(t.blocked for t in tables),
                    mean_duration=dur / rows if rows else float("nan"),
                    hours=sum(t.hours for t in tables),
                    wall_seconds=sum(t.wall_seconds for t in tables))



class WalkRunner:
    """Simulates candidate tables on the one parallel layer (:mod:`simlab.base.parallel`): in
    this process for one worker, else a pool of ``workers`` processes (one arena per
    process, workers exit with us), or Ray tasks on ``address`` (or, with ``backend =
    "ray"`` and no address, on the Ray runtime this process runs); tables come back in job
    order.

    The unit of work is a walk, not a candidate: the walks of every job of a :meth:`map`
    (one per start state) go to the workers as they free up, the first job's first, so
    the workers stay busy to the last walk whatever the number of candidates or how long
    each one's walks take (a walk of a slow-turning candidate is longer). A part depends
    only on its job, so the tables are those of one walk after the other in this process.
    """

    def __init__(self, workers: int, address: str | None = None, *,
                 backend: str = "local") -> None:
        from simlab.data.backends import make_backend

        ray = address is not None or backend == "ray"
        self._backend = make_backend("ray" if ray else "local", workers, address)

    def map(self, jobs: list[WalkJob]) -> list[SimTable]:
        from simlab.data.collect import walk_results

        plans = [walk_plan(job) for job in jobs]
        results = walk_results(plans, self._backend)
        return [table_of(job, plan, parts)
                for job, plan, parts in zip(jobs, plans, results, strict=True)]

    def close(self) -> None:
        self._backend.close()
