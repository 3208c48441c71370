"""``simlab train``: train an agent on an empirical MDP for each goal area (thesis 4.5, Fig. 4.9).

For every goal, ``runs`` independent agents learn for ``episodes`` episodes of
``horizon`` steps (reward 1 per step spent arriving in the goal area, start
state uniform unless ``start`` is given) on the fused njit path of
:mod:`simlab.training.harness`. Outputs in ``out``:

* ``q_<goal>.npz`` — ``Q`` (S, A) float64, the **mean over runs** of the final
  Q-tables (what the replay loads; averaging removes run-to-run noise), plus
  ``Q_runs`` (runs, S, A), ``Q_star`` (S, A) value iteration on the true matrix,
  ``goal_mask`` (S,) and JSON metadata (``meta_json``: agent, hyper-parameters,
  goal, seed, ...). A passive observer also stores ``actor_Q_runs``.
* ``curves.npz`` — ``rewards`` (G, runs, episodes), ``goal_names`` (G,),
  ``curve_x`` (n,), ``curve_mean`` / ``curve_std`` (G, n) (thesis Fig. 4.1
  reduction to 100 points), ``optimal_return`` (G,).
* ``curves.png`` — one panel per goal, mean and std band, optimal return dashed.
* ``summary.json`` — per goal: final mean reward (last 10 % of episodes, all
  runs), the optimal expected return (greedy policy of value iteration on the
  true ``T``, same gamma, horizon and start distribution), their ratio, the
  exact expected return of the learned greedy policies and the first episode at
  which the curve reached 90 % of the optimum.
* ``heatmap_<goal>.png`` and ``heatmaps.png`` (all goals, 3 x 3 for 9) — when the
  MDP file has ``centres``.

Decisions (where the thesis, 3.2.5 and 4.5, leaves the choice open):

* **Unvisited (s, a)**: under the MDP's ``mask`` rule (the default; ``TrainTask.unvisited``
  overrides it) training passes ``valid = visited`` ((S, A) bool; a state with no visited
  action keeps all) to the harness, so agents and planners never choose an untried action,
  and warns with the number of masked pairs. ``self-loop`` is the old rule. With full
  coverage nothing is masked and ``valid=None`` is passed: results are bit-identical.
  The Q-tables store ``valid`` (array) and the rule (metadata); their greedy policy
  (heat-map arrows, replay) is taken over valid actions only.
* **Goals as state ids**: ``TrainTask.goal_states`` = (18, 19) trains one goal made of
  those states, named ``s18+19`` (file ``q_s18_19.npz``), without any arena.
  ``start_states`` draws the start state uniformly among the listed states.
* **Task mode**: ``per-step`` (+1 for every step that arrives in the goal, the
  episode runs ``horizon`` steps: thesis) or ``episodic`` (+1 on arrival, the episode ends
  there and the next starts from the start states: the real robot's protocol; the goal
  states are ``terminal`` for the harness; ``horizon`` caps an episode).
* The MDP's ``action_set`` is copied into every Q-table's metadata.

The mask and the terminal goal states travel to the harness in its
:class:`~simlab.training.harness.EpisodeTask` (None when there is nothing to mask or end).

Seeding: goal ``g`` (its index in the file's goal list) uses
``SeedSequence(seed, spawn_key=(g,))``, so training one goal alone gives the same
numbers as training it among all goals.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base.errors import ConfigError, warn
from simlab.base.io import output_transaction
from simlab.base.options import command
from simlab.data.goals import state_goal_name
from simlab.training.config import TASK_MODES, TrainConfig, TrainTask, param_pair
from simlab.training.loop import (
    GoalSummary,
    TrainJob,
    TrainResults,
    goal_summaries,
    train_goals,
    train_goals_shared,
)
from simlab.training.outputs import output_files, previous_outputs, run_metadata, write_outputs

__all__ = ["TASK_MODES", "GoalSummary", "TrainConfig", "TrainSummary", "TrainTask", "param_pair",
           "resolve_goals", "train"]


@dataclasses.dataclass(frozen=True)
class TrainSummary:
    """What :func:`train` did."""

    agent: str
    config: dict[str, Any]
    goals: tuple[GoalSummary, ...]
    rewards: np.ndarray
    """(G, runs, episodes) reward per episode."""
    Q: dict[str, np.ndarray]
    """Goal -> saved Q (S, A) (mean over runs)."""
    files: dict[str, str]
    seconds: float
    out: Path | None


def resolve_goals(mdp: Any, goals: str | Sequence[str] | None) -> list[str]:
    """``"all"``/``None`` -> every goal of the MDP; ``"a,b"`` or a list -> those (validated)."""
    if not mdp.goal_names:
        raise ConfigError(
            "the MDP has no goal areas (goal_names/goal_masks)", path=mdp.source, key="goals",
            fix="estimate it with an arena that defines goals",
        )  # fmt: skip
    if goals is None or (isinstance(goals, str) and goals.strip().lower() == "all"):
        return list(mdp.goal_names)
    names = [g.strip() for g in goals.split(",")] if isinstance(goals, str) else list(goals)
    names = [n for n in names if n]
    if not names:
        raise ConfigError("no goal given", key="goals", fix="use 'all' or names such as g1,g2")
    for n in names:
        mdp.goal_index(n)  # raises, listing the valid goals
    if len(set(names)) != len(names):
        raise ConfigError(f"goal listed twice in {names}", key="goals")
    return names


def _bounds(mdp: Any, bounds: Sequence[float] | None, arena: Any) -> tuple[float, ...] | None:
    if bounds is not None:
        b = tuple(float(v) for v in bounds)
        if len(b) != 4 or not (b[0] < b[2] and b[1] < b[3]):
            raise ConfigError(f"expected x_min y_min x_max y_max, got {list(b)}", key="bounds")
        return b
    if arena is not None:
        from simlab.physics.arena import load_arena

        cfg = arena if hasattr(arena, "bounds") else load_arena(arena)
        return tuple(float(v) for v in cfg.bounds)
    return None if mdp.bounds is None else tuple(mdp.bounds)


def _apply_task(m: Any, task: TrainTask, start: int | None) -> tuple[Any, Any]:
    """The MDP with the task's goal and unvisited rule, and the start distribution."""
    S = m.n_states
    for key, states in (("goal_states", task.goal_states), ("start_states", task.start_states)):
        bad = [s for s in states or () if not 0 <= s < S]
        if bad:
            raise ConfigError(f"states {bad} not in [0, {S})", path=m.source, key=key)
    changes: dict[str, Any] = {}
    if task.unvisited is not None:
        changes["unvisited"] = task.unvisited
    if task.goal_states is not None:
        mask = np.zeros((1, S), dtype=bool)
        mask[0, list(task.goal_states)] = True
        name = state_goal_name(task.goal_states)
        changes.update(goal_names=(name,), goal_masks=mask)
    if changes:
        m = dataclasses.replace(m, **changes)
    if task.start_states is None:
        return m, start
    if start is not None:
        raise ConfigError("give either start or start_states", key="start_states")
    p0 = np.zeros(S)
    p0[list(task.start_states)] = 1.0 / len(task.start_states)
    return m, p0


@command(TrainConfig)
def train(cfg: TrainConfig) -> TrainSummary:
    """Train ``agent`` on the empirical MDP ``mdp`` for each goal; write results to ``out``.

    Takes a :class:`~simlab.training.config.TrainConfig` or its fields
    (``train(mdp, "q-learning", out=...)``); the fields are documented there.
    """
    job = _job(cfg, time.perf_counter())
    with contextlib.ExitStack() as stack:
        pool = cfg.pool
        if pool is None and cfg.workers > 1:
            from simlab.base.parallel import worker_pool

            pool = worker_pool(cfg.workers - 1)
            stack.callback(pool.shutdown, wait=True, cancel_futures=True)
        txn = None
        if cfg.out is not None:  # refuses existing outputs, takes the --out lock before training
            txn = stack.enter_context(output_transaction(cfg.out, job.files.values(),
                                                         overwrite=cfg.overwrite))
            if cfg.overwrite:
                for stale in previous_outputs(Path(cfg.out), job.files.values()):
                    txn.retire(stale)
        return _train_and_write(dataclasses.replace(job, pool=pool), txn)
    raise AssertionError("unreachable")  # pragma: no cover


def _job(cfg: TrainConfig, t0: float) -> TrainJob:
    """Everything checked before any work: the MDP with the task applied, the goals, gamma,
    the memory the runs need, the start state, the heat maps' extent and map, the files."""
    from simlab.data.mdp import EmpiricalMDP, load_mdp

    mdp = cfg.mdp
    m = mdp if isinstance(mdp, EmpiricalMDP) else load_mdp(mdp)
    from simlab.base.statecheck import npz_states_hash

    # the states fingerprint travels from the MDP into every Q-table (replay checks it)
    states_hash = None if isinstance(mdp, EmpiricalMDP) else npz_states_hash(mdp)
    m, start = _apply_task(m, cfg.task, cfg.start)
    names = resolve_goals(m, cfg.goals)
    _warn_about(m)
    from simlab.agents.registry import agent_config

    # validates the name and overrides before any work
    gamma = float(agent_config(cfg.agent, cfg.params).gamma)
    from simlab.base.guards import array_bytes, check_memory

    # per goal and run: the reward curve (float64) and the final Q-table
    check_memory(array_bytes((len(names), cfg.runs, cfg.episodes + m.n_states * m.n_actions),
                             16),
                 what=f"{len(names)} goal(s) x {cfg.runs} run(s) x {cfg.episodes} episodes",
                 key="episodes", fix="ask for fewer episodes, runs or goals")
    if isinstance(start, int | np.integer) and not (0 <= int(start) < m.n_states):
        raise ConfigError(f"expected a state in [0, {m.n_states}), got {start}", key="start")
    plot_bounds = _bounds(m, cfg.bounds, cfg.arena) if cfg.plots else None
    background = cfg.occupancy_map
    if cfg.plots and isinstance(background, str | os.PathLike):
        from discretize.mapio import read_map

        background = read_map(background)
    files = {} if cfg.out is None else output_files(cfg.out, names, cfg.plots,
                                                    m.centres is not None)
    return TrainJob(cfg=cfg, m=m, names=names, start=start, valid=m.valid, gamma=gamma,
                    files=files, plot_bounds=plot_bounds, background=background, t0=t0,
                    states_hash=states_hash)


def _warn_about(m: Any) -> None:
    """Warn about an MDP estimated from nothing and about masked (s, a) pairs."""
    if m.counts is not None and int(np.asarray(m.counts).sum()) == 0:
        warn(f"{m.source or 'the MDP'}: estimated from 0 transitions; every (s, a) is a "
             "self-loop and training learns nothing (collect data first)")
    if m.valid is not None:
        warn(f"{int((~m.valid).sum())} unvisited (s, a) pairs masked: agents never choose "
             "them (unvisited='self-loop' for the old rule)")


def _train_and_write(job: TrainJob, txn: Any) -> TrainSummary:
    """The body of :func:`train` inside its output transaction ``txn`` (None: no outputs)."""
    cfg = job.cfg
    pngs: dict[str, bytes] = {}
    if job.pool is None:
        runs, evaluations = train_goals(job)
    else:
        runs, evaluations, pngs = train_goals_shared(job)
    summaries, curve_rows = goal_summaries(job, runs, evaluations)
    names = job.names
    res = TrainResults(runs=runs, evaluations=evaluations, summaries=summaries,
                       curve_rows=curve_rows, rewards=np.stack([runs[g].rewards for g in names]),
                       Qs={g: runs[g].Q_runs.mean(axis=0) for g in names},
                       config=runs[names[0]].config, pngs=pngs)
    if txn is not None:
        staged = {k: txn.path(v) for k, v in job.files.items()}
        write_outputs(job, res, staged, run_metadata(job))
    return TrainSummary(
        agent=cfg.agent, config=res.config, goals=tuple(summaries), rewards=res.rewards,
        Q=res.Qs, files={k: str(v) for k, v in job.files.items()},
        seconds=time.perf_counter() - job.t0, out=None if cfg.out is None else Path(cfg.out),
    )  # fmt: skip
