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
import re
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base import validation as v
from simlab.base.errors import ConfigError, warn
from simlab.base.io import atomic_write_bytes, atomic_write_json, output_transaction
from simlab.base.options import CommandConfig, command, option
from simlab.data.goals import state_goal_name

__all__ = ["TASK_MODES", "GoalSummary", "TrainConfig", "TrainSummary", "TrainTask", "resolve_goals", "train"]

#: Task modes of :class:`TrainTask` (the first is the default).
TASK_MODES = ("per-step", "episodic")


@dataclasses.dataclass(frozen=True)
class TrainTask:
    """What the agent is asked to do (see the module docstring's decisions).

    Attributes:
        mode: ``per-step`` (default, +1 per step arriving in the goal) or ``episodic``
            (+1 on arrival, then restart from the start states).
        goal_states: state ids of one goal area (instead of the MDP's named goals).
        start_states: start states, drawn uniformly (default: all states).
        unvisited: ``mask`` or ``self-loop`` to override the MDP's rule (None: the MDP's).
    """

    mode: str = "per-step"
    goal_states: tuple[int, ...] | None = None
    start_states: tuple[int, ...] | None = None
    unvisited: str | None = None

    def __post_init__(self) -> None:
        if self.mode not in TASK_MODES:
            raise ConfigError(f"unknown task {self.mode!r}", key="task",
                              fix="use 'per-step' or 'episodic'")
        for key in ("goal_states", "start_states"):
            object.__setattr__(self, key, v.state_ids(getattr(self, key), key))
        if self.unvisited is not None and self.unvisited not in ("mask", "self-loop"):
            raise ConfigError(f"unknown rule {self.unvisited!r}", key="unvisited",
                              fix="use 'mask' or 'self-loop'")

    def as_dict(self) -> dict[str, Any]:
        return {"mode": self.mode,
                "goal_states": None if self.goal_states is None else list(self.goal_states),
                "start_states": None if self.start_states is None else list(self.start_states)}


@dataclasses.dataclass(frozen=True)
class GoalSummary:
    """Results of one goal (JSON-ready, see :meth:`as_dict`)."""

    goal: str
    final_mean_reward: float
    """Mean reward per episode over the last 10 % of episodes and all runs."""
    optimal_return: float
    """Expected return of value iteration's greedy policy on the true MDP."""
    ratio: float | None
    """``final_mean_reward / optimal_return`` (on-policy, exploration included);
    ``None`` when the optimum is 0 (an unreachable goal)."""
    greedy_return: float
    """Mean over runs of the exact expected return of each run's greedy policy."""
    greedy_ratio: float | None
    """``greedy_return / optimal_return`` (``None`` when the optimum is 0)."""
    saved_q_return: float
    """Exact expected return of the greedy policy of the saved (run-averaged) Q."""
    upper_bound: float
    """Best expected return of any time-dependent policy over the horizon."""
    episodes_to_90: int | None
    """First curve point (episode) whose block mean reaches 90 % of the optimum."""

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


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


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)


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


def param_pair(text: str) -> tuple[str, Any]:
    """``KEY=VALUE`` of ``--param`` (VALUE as JSON, else as a plain string)."""
    import argparse
    import json

    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    try:
        parsed = json.loads(value)
    except json.JSONDecodeError:
        parsed = value  # plain strings: --param selection=softmax
    return key.strip(), parsed


def _param_item(item: Any) -> tuple[str, Any]:
    """One ``"KEY=VALUE"`` of a list of overrides (an options file's ``param = [...]``)."""
    import argparse

    try:
        if not isinstance(item, str):
            raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {item!r}")
        return param_pair(item)
    except argparse.ArgumentTypeError as exc:
        raise ConfigError(str(exc), key="param", fix='e.g. param = ["tau=0.05"]') from None


_AGENTS = "q-learning, q-softmax, mb-egreedy, vi-softmax, rmax, sliding-window, passive-observer"


@dataclasses.dataclass(frozen=True, kw_only=True)
class TrainConfig(CommandConfig):
    """Options of ``simlab train`` / :func:`train`.

    ``task`` is a :class:`TrainTask` (Python) or its mode (``--task``); with a mode,
    ``goal_states``, ``start_states`` and ``unvisited`` complete it (``validate`` makes
    ``task`` the :class:`TrainTask`). ``params`` is a dict of hyper-parameter overrides;
    ``--param KEY=VALUE`` (repeatable) is added by the CLI module.
    """

    COMMAND = "train"

    mdp: Any = option(help="mdp.npz written by simlab estimate (or an EmpiricalMDP)")
    agent: str = option("vi-softmax", f"agent name ({_AGENTS})")
    goals: Any | None = option("all", "'all' or comma-separated goal names", parse=str)
    episodes: int = option(2000, "episodes per run")
    runs: int = option(10, "independent runs per goal")
    seed: int = option(0, "root seed")
    out: Path | None = option(None, "output directory (Python: None writes nothing) "
                              "(required)")
    horizon: int = option(50, "steps per episode")
    start: int | None = option(None, "fixed start state (default: uniform over states)")
    params: Any | None = option(None, "hyper-parameter overrides {name: value}", cli=False,
                                flag="param")
    bounds: tuple[float, ...] | None = option(
        None, "heat-map extent XMIN YMIN XMAX YMAX in metres (default: from --arena or the "
        "centres)")
    arena: Any | None = option(None, "arena name or TOML for the heat-map extent", parse=str)
    occupancy_map: Any | None = option(None, "map.yaml drawn under the heat maps", flag="map",
                                       parse=str)
    goal_states: Any | None = option(
        None, "train one goal made of these state ids, e.g. 18 or 18,19 (named s18, "
        "s18+19); no arena needed (default: the MDP's named goals)", parse=str)
    start_states: Any | None = option(
        None, "start states drawn uniformly, e.g. 0,32 (default: all states, or --start)",
        parse=str)
    task: Any | None = option(
        None, "per-step: +1 per step arriving in the goal, fixed-length episodes (thesis; "
        "default); episodic: +1 on arrival, then restart from the start states (real robot)",
        parse=str, metavar="{per-step,episodic}")
    unvisited: str | None = option(
        None, "unvisited (s, a): mask = never chosen, self-loop = the old free stay "
        "(default: the rule stored in the MDP, mask for old files)",
        choices=("mask", "self-loop"))
    plots: bool = option(True, "the PNG figures (--no-plots skips them)")
    overwrite: bool = option(False, "replace existing outputs")
    progress: bool = option(True, "progress bar (--no-progress hides it)")
    workers: int = option(1, "processes sharing the goals and figures (1: this one only; N "
                          "starts N-1 worker processes)")
    pool: Any | None = option(
        None, "a concurrent.futures process executor (e.g. simlab.base.parallel.spawn_worker()) "
        "whose workers train and draw part of the goals; the caller owns it (a simlab "
        "WorkerPool gets a goal per process at a time, any other executor one)", cli=False)

    def validate(self) -> None:
        v.whole(self.episodes, "episodes", minimum=1)
        v.whole(self.runs, "runs", minimum=1)
        v.whole(self.seed, "seed")
        v.whole(self.horizon, "horizon", minimum=1)
        v.whole(self.workers, "workers", minimum=1)
        v.executor(self.pool)
        if self.pool is not None and self.workers != 1:
            raise ConfigError("give either a pool or workers", key="workers")
        if self.bounds is not None and len(self.bounds) != 4:
            raise ConfigError(f"expected 4 numbers XMIN YMIN XMAX YMAX, got {self.bounds}",
                              key="bounds")
        if isinstance(self.params, list | tuple):  # `param = ["tau=0.05"]`, as on the CLI
            object.__setattr__(self, "params", dict(_param_item(p) for p in self.params))
        if self.params is not None and not isinstance(self.params, dict):
            raise ConfigError(f"expected a table of overrides, got {self.params!r}",
                              key="params", fix='e.g. params = {tau = 0.05} or '
                              'param = ["tau=0.05"]')
        extra = (self.goal_states, self.start_states, self.unvisited)
        if isinstance(self.task, TrainTask):
            if any(x is not None for x in extra):
                raise ConfigError("give goal_states/start_states/unvisited in the TrainTask",
                                  key="task")
            task = self.task
        else:
            task = TrainTask(mode="per-step" if self.task is None else self.task,
                             goal_states=self.goal_states, start_states=self.start_states,
                             unvisited=self.unvisited)
        object.__setattr__(self, "task", task)
        if task.goal_states is not None and self.goals not in (None, "all"):
            raise ConfigError("give either goals or goal_states", key="goal_states")


@command(TrainConfig)
def train(cfg: TrainConfig) -> TrainSummary:
    """Train ``agent`` on the empirical MDP ``mdp`` for each goal; write results to ``out``.

    Takes a :class:`TrainConfig` or its fields (``train(mdp, "q-learning", out=...)``):

    * ``mdp``: ``mdp.npz`` path (``simlab estimate``) or an
      :class:`~simlab.data.mdp.EmpiricalMDP`.
    * ``agent``: a registered agent name (:mod:`simlab.agents.registry`).
    * ``goals``: ``"all"``, a comma-separated string or a list of goal names.
    * ``episodes``, ``runs``, ``seed``, ``horizon``, ``start``: training budget,
      independent runs, root seed, steps per episode, fixed start state (``None``: uniform).
    * ``params``: hyper-parameter overrides of the agent's preset (``{"tau": 0.05}``).
    * ``bounds``, ``arena``: heat-map extent ``(x_min, y_min, x_max, y_max)`` m, or an arena
      (name, path or config) to take it from; default: the MDP file's ``bounds`` or the
      centres' extent.
    * ``occupancy_map``: optional ``map.yaml`` path or occupancy map under the heat maps.
    * ``out``: output directory (created); ``None`` writes nothing and only returns.
    * ``plots``, ``overwrite``, ``progress``: write PNGs; replace existing outputs; show a
      progress bar.
    * ``pool`` (Python only) or ``workers``: a process executor, or the number of processes,
      sharing the work with this process (:func:`_train_goals_shared`); the outputs are
      the same bytes as without.
    * ``task`` (a :class:`TrainTask` or its mode) with ``goal_states``, ``start_states``,
      ``unvisited``: task mode, goal/start states, unvisited rule (default: per-step, the
      MDP's goals and rule).
    """
    from simlab.data.mdp import EmpiricalMDP, load_mdp

    t0 = time.perf_counter()
    mdp = cfg.mdp
    m = mdp if isinstance(mdp, EmpiricalMDP) else load_mdp(mdp)
    from simlab.base.statecheck import npz_states_hash

    # the states fingerprint travels from the MDP into every Q-table (replay checks it)
    states_hash = None if isinstance(mdp, EmpiricalMDP) else npz_states_hash(mdp)
    task = cfg.task
    m, start = _apply_task(m, task, cfg.start)
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
    out = cfg.out
    files = {} if out is None else _output_files(out, names, cfg.plots, m.centres is not None)
    with contextlib.ExitStack() as stack:
        pool = cfg.pool
        if pool is None and cfg.workers > 1:
            from simlab.base.parallel import worker_pool

            pool = worker_pool(cfg.workers - 1)
            stack.callback(pool.shutdown, wait=True, cancel_futures=True)
        txn = None
        if out is not None:  # refuses existing outputs and takes the --out lock before training
            txn = stack.enter_context(output_transaction(out, files.values(),
                                                         overwrite=cfg.overwrite))
            if cfg.overwrite:
                for stale in _previous_outputs(Path(out), files.values()):
                    txn.retire(stale)
        job = _TrainJob(cfg=cfg, m=m, names=names, start=start, valid=m.valid, gamma=gamma,
                        files=files, plot_bounds=plot_bounds, background=background, t0=t0,
                        states_hash=states_hash, pool=pool)
        return _train_and_write(job, txn)
    raise AssertionError("unreachable")  # pragma: no cover


def _warn_about(m: Any) -> None:
    """Warn about an MDP estimated from nothing and about masked (s, a) pairs."""
    if m.counts is not None and int(np.asarray(m.counts).sum()) == 0:
        warn(f"{m.source or 'the MDP'}: estimated from 0 transitions; every (s, a) is a "
             "self-loop and training learns nothing (collect data first)")
    if m.valid is not None:
        warn(f"{int((~m.valid).sum())} unvisited (s, a) pairs masked: agents never choose "
             "them (unvisited='self-loop' for the old rule)")


#: Names of the files a train run writes per goal or per figure (see :func:`_output_files`):
#: only files of these names, listed by the previous run's summary.json, are retired.
_OWN_PATTERNS = ("q_*.npz", "heatmap_*.png", "heatmaps.png", "curves.png")


def _previous_outputs(out: Path, now: Any) -> list[Path]:
    """Files the previous ``train`` into ``out`` wrote (its ``summary.json`` lists them) that
    this run does not write again: the Q-tables and heat maps of goals no longer trained.
    ``--overwrite`` replaces them too, so that ``replay`` of ``out`` (every ``q_*.npz``)
    never picks up a stale goal. Files ``train`` did not write are never touched."""
    import json

    try:
        listed = json.loads((out / "summary.json").read_text(encoding="utf-8"))["files"]
        names = {Path(str(v)).name for v in listed.values()}
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return []  # no summary of ours: nothing is known to be ours
    keep = {Path(p).name for p in now}
    return [out / n for n in sorted(names - keep)
            if any(Path(n).match(pat) for pat in _OWN_PATTERNS) and (out / n).is_file()]


def _output_files(out: Any, names: list[str], plots: bool, centres: bool) -> dict[str, Path]:
    """Every file :func:`train` writes into ``out``, by role."""
    out = Path(out)
    files = {f"q_{g}": out / f"q_{_slug(g)}.npz" for g in names}
    files["curves"] = out / "curves.npz"
    files["summary"] = out / "summary.json"
    if plots:
        files["curves_png"] = out / "curves.png"
        if centres:
            files["heatmaps"] = out / "heatmaps.png"
            for g in names:
                files[f"heatmap_{g}"] = out / f"heatmap_{_slug(g)}.png"
    return files


@dataclasses.dataclass(frozen=True)
class _TrainJob:
    """Everything :func:`train` validated, handed to :func:`_train_and_write`."""

    cfg: TrainConfig
    m: Any
    names: list[str]
    start: Any
    valid: Any
    gamma: float
    files: dict[str, Path]
    plot_bounds: Any
    background: Any
    t0: float
    states_hash: str | None = None
    pool: Any = None


@dataclasses.dataclass(frozen=True)
class _Results:
    """What the runs of every goal produced."""

    runs: dict[str, Any]
    evaluations: dict[str, Any]
    summaries: list[GoalSummary]
    curve_rows: list[tuple[Any, Any, Any]]
    rewards: np.ndarray
    Qs: dict[str, np.ndarray]
    config: Any
    pngs: dict[str, bytes] = dataclasses.field(default_factory=dict)
    """Heat maps already drawn by :func:`_train_goals_shared`, by goal."""


def _train_and_write(job: _TrainJob, txn: Any) -> TrainSummary:
    """The body of :func:`train` inside its output transaction ``txn`` (None: no outputs)."""
    cfg = job.cfg
    pngs: dict[str, bytes] = {}
    if job.pool is None:
        runs, evaluations = _train_goals(job)
    else:
        runs, evaluations, pngs = _train_goals_shared(job)
    summaries, curve_rows = _goal_summaries(job, runs, evaluations)
    names = job.names
    res = _Results(runs=runs, evaluations=evaluations, summaries=summaries,
                   curve_rows=curve_rows, rewards=np.stack([runs[g].rewards for g in names]),
                   Qs={g: runs[g].Q_runs.mean(axis=0) for g in names},
                   config=runs[names[0]].config, pngs=pngs)
    if txn is not None:
        staged = {k: txn.path(v) for k, v in job.files.items()}
        run_meta = dict(seed=cfg.seed, episodes=cfg.episodes, runs=cfg.runs,
                        horizon=cfg.horizon, start=_start_meta(job.start),
                        states_hash=job.states_hash, gamma=job.gamma,
                        **_task_meta(job.m, cfg.task, job.valid))
        _write_outputs(job, res, staged, run_meta)
    return TrainSummary(
        agent=cfg.agent, config=res.config, goals=tuple(summaries), rewards=res.rewards,
        Q=res.Qs, files={k: str(v) for k, v in job.files.items()},
        seconds=time.perf_counter() - job.t0, out=None if cfg.out is None else Path(cfg.out),
    )  # fmt: skip


@dataclasses.dataclass(frozen=True)
class _GoalWork:
    """What training, evaluating and drawing one goal needs, and nothing else: the
    picklable job of a worker process (the config holds the pool, the job its files)."""

    agent: str
    params: Any
    episodes: int
    runs: int
    seed: int
    horizon: int
    episodic: bool
    m: Any
    start: Any
    valid: Any
    gamma: float
    heatmap: Any = None
    """The :class:`~simlab.training.heatmap.HeatmapScene` of the goals' heat maps, None: no
    heat map."""


def _goal_work(job: _TrainJob, heatmaps: bool = False) -> _GoalWork:
    cfg, m = job.cfg, job.m
    draw = heatmaps and "heatmaps" in job.files  # plots, centres and an output directory
    heatmap = _heatmap_scene(job) if draw else None
    return _GoalWork(agent=cfg.agent, params=cfg.params, episodes=cfg.episodes, runs=cfg.runs,
                     seed=cfg.seed, horizon=cfg.horizon, episodic=cfg.task.mode == "episodic",
                     m=m, start=job.start, valid=job.valid, gamma=job.gamma,
                     heatmap=heatmap)  # fmt: skip


def _train_goal(work: _GoalWork, g: str, on_run_done: Any = None) -> tuple[Any, Any]:
    """Train and evaluate goal ``g``: (training result, evaluation). Its seed depends on
    the goal's index only, so any process computes the same numbers."""
    from simlab.training.harness import EpisodeTask, evaluate_q, train_runs

    m = work.m
    task = EpisodeTask(m.T, m.goal_reward(g), horizon=work.horizon, start=work.start,
                       valid=work.valid, terminal=m.goal_mask(g) if work.episodic else None)
    seq = np.random.SeedSequence(work.seed, spawn_key=(m.goal_index(g),))
    res = train_runs(task, work.agent, episodes=work.episodes, runs=work.runs, seed=seq,
                     overrides=work.params, on_run_done=on_run_done)
    Q_mean = res.Q_runs.mean(axis=0)
    evaluation = evaluate_q(task, np.concatenate([res.Q_runs, Q_mean[None]]), work.gamma)
    return res, evaluation


def _train_and_draw_goal(work: _GoalWork, g: str, on_run_done: Any = None
                         ) -> tuple[Any, Any, bytes | None]:
    """:func:`_train_goal` and, when ``work.heatmap``, the goal's heat map as PNG bytes
    (the unit of work shared with the pool: the driver alone writes files)."""
    res, evaluation = _train_goal(work, g, on_run_done)
    png = None
    if work.heatmap is not None:
        from simlab.training.heatmap import render_q_heatmap

        png = render_q_heatmap(work.heatmap, res.Q_runs.mean(axis=0), work.m.goal_mask(g),
                               title=f"{work.agent}: goal {g}")
    return res, evaluation, png


def _train_goals(job: _TrainJob) -> tuple[dict[str, Any], dict[str, Any]]:
    """Train and evaluate every goal: (runs by goal, evaluations by goal)."""
    from tqdm.auto import tqdm

    cfg = job.cfg
    work = _goal_work(job)
    results, evaluations = {}, {}
    bar = tqdm(total=len(job.names) * cfg.runs, disable=not cfg.progress,
               desc=f"train {cfg.agent}", unit="run")
    try:
        for g in job.names:
            results[g], evaluations[g] = _train_goal(work, g, lambda: bar.update(1))
    finally:
        bar.close()
    return results, evaluations


class _SharedGoals:
    """Goals shared between this process, which takes them from the first, and a pool, fed
    from the last one at a time per worker (a goal handed over when a worker's previous
    one ends): neither side claims work it has not started, so the two meet wherever their
    speeds make them, without a guess of how warm the worker is."""

    def __init__(self, pool: Any, work: _GoalWork, names: list[str], on_done: Any) -> None:
        import collections
        import threading

        self._pool, self._work, self._on_done = pool, work, on_done
        self._todo = collections.deque(names)
        self._lock = threading.Lock()  # this thread and the pool's callback thread
        self.futures: dict[str, Any] = {}

    def take_first(self) -> str | None:
        """The next goal for this process (None: none left)."""
        with self._lock:
            return self._todo.popleft() if self._todo else None

    def feed(self, finished: Any = None) -> None:
        """Hand the last goal left to the pool (also the done-callback of each of its
        goals, so a worker gets its next goal when it ends one)."""
        if finished is not None and not finished.cancelled():
            self._on_done()
        with self._lock:
            if not self._todo:
                return
            g = self._todo.pop()
            future = self.futures[g] = self._pool.submit(_train_and_draw_goal, self._work, g)
        future.add_done_callback(self.feed)

    def handed_over(self) -> dict[str, Any]:
        """Once this process is out of goals: the pool's, by goal (no more will come)."""
        with self._lock:
            self._todo.clear()
            return dict(self.futures)


def _train_goals_shared(job: _TrainJob
                        ) -> tuple[dict[str, Any], dict[str, Any], dict[str, bytes]]:
    """:func:`_train_goals` with ``job.pool``: (runs, evaluations, heat-map PNGs by goal).

    A goal (training, evaluation and heat map) is the unit shared with the pool
    (:class:`_SharedGoals`); a goal the pool has not started when this process is out of
    work is taken back (``cancel``). Results do not depend on where a goal ran (its seed
    is its own).
    """
    from tqdm.auto import tqdm

    cfg, names = job.cfg, job.names
    bar = tqdm(total=len(names) * cfg.runs, disable=not cfg.progress,
               desc=f"train {cfg.agent}", unit="run")
    work = _goal_work(job, heatmaps=True)
    shared = _SharedGoals(job.pool, work, list(names), lambda: bar.update(cfg.runs))
    futures: dict[str, Any] = {}
    try:
        # one goal per process of a simlab pool (simlab.base.parallel.WorkerPool); any other
        # executor is fed one goal at a time
        for _ in range(getattr(job.pool, "processes", 1)):
            shared.feed()
        done = {}
        while (g := shared.take_first()) is not None:
            done[g] = _train_and_draw_goal(work, g, lambda: bar.update(1))
        futures = shared.handed_over()
        for g, future in futures.items():
            if future.cancel():  # not started: the pool is busy elsewhere
                done[g] = _train_and_draw_goal(work, g, lambda: bar.update(1))
        for g, future in futures.items():
            if g not in done:
                done[g] = future.result()
    finally:
        for future in shared.handed_over().values():
            future.cancel()
        bar.close()
    return ({g: done[g][0] for g in names}, {g: done[g][1] for g in names},
            {g: done[g][2] for g in names if done[g][2] is not None})


def _goal_summaries(job: _TrainJob, results: dict[str, Any], evaluations: dict[str, Any]
                    ) -> tuple[list[GoalSummary], list[tuple[Any, Any, Any]]]:
    """Per goal: the summary figures and the learning curve (x, mean, std)."""
    from simlab.training.curves import curve_points

    tail = max(1, job.cfg.episodes // 10)
    summaries = []
    curve_rows = []
    for g in job.names:
        res, ev = results[g], evaluations[g]
        x, mean, std = curve_points(res.rewards)
        curve_rows.append((x, mean, std))
        final = float(res.rewards[:, -tail:].mean())
        opt = float(ev.optimal_return)
        reached = np.flatnonzero(mean >= 0.9 * opt)
        greedy = float(ev.greedy_returns[:-1].mean())
        summaries.append(GoalSummary(
            goal=g, final_mean_reward=final, optimal_return=opt,
            ratio=final / opt if opt > 0 else None,
            greedy_return=greedy, greedy_ratio=greedy / opt if opt > 0 else None,
            saved_q_return=float(ev.greedy_returns[-1]), upper_bound=float(ev.upper_bound),
            episodes_to_90=int(x[reached[0]]) if len(reached) else None,
        ))  # fmt: skip
    return summaries, curve_rows


def _start_meta(start: Any) -> int | None:
    """The fixed start state for the metadata (start states are in ``task``)."""
    return int(start) if isinstance(start, int | np.integer) else None


def _task_meta(m: Any, task: TrainTask, valid: np.ndarray | None) -> dict[str, Any]:
    """The task metadata of every Q-table: action set, unvisited rule, task."""
    return {
        "action_set": None if m.action_set is None else m.action_set.to_json(),
        "unvisited": m.unvisited,
        "masked_pairs": 0 if valid is None else int((~valid).sum()),
        "task": task.as_dict(),
    }


def _write_outputs(job: _TrainJob, res: _Results, files: dict[str, Path],
                   run_meta: dict[str, Any]) -> None:
    """Write the Q-tables, curves, figures and summary to ``files`` (staged paths)."""
    import simlab
    from simlab.agents.storage import save_q_table

    m, names, agent = job.m, job.names, job.cfg.agent
    source = None if m.source is None else str(m.source)
    for g in names:
        runs = res.runs[g]
        arrays = {"Q_runs": runs.Q_runs, "Q_star": res.evaluations[g].Q_star,
                  "goal_mask": m.goal_mask(g)}  # fmt: skip
        arrays.update(runs.extra)
        if m.valid is not None:
            arrays["valid"] = m.valid
        meta = {"agent": agent, "config": res.config, "goal": g, "goal_index": m.goal_index(g),
                "mdp": source, "mdp_resolved": None if source is None
                else str(Path(source).resolve()), "Q": "mean over runs of the final Q-tables",
                "simlab_version": simlab.__version__, **run_meta}  # fmt: skip
        save_q_table(files[f"q_{g}"], res.Qs[g], metadata=meta, arrays=arrays, overwrite=True)

    import json

    from simlab.base.io import atomic_write

    curve_rows = res.curve_rows
    with atomic_write(files["curves"], "wb") as fh:
        np.savez_compressed(
            fh, rewards=res.rewards, goal_names=np.array(names), curve_x=curve_rows[0][0],
            curve_mean=np.stack([r[1] for r in curve_rows]),
            curve_std=np.stack([r[2] for r in curve_rows]),
            optimal_return=np.array([s.optimal_return for s in res.summaries]),
            meta_json=np.array(json.dumps({"agent": agent, "config": res.config,
                                           **run_meta})),
        )  # fmt: skip
    if job.cfg.plots:
        _write_figures(job, res, files, run_meta["runs"])
    summary = {
        "agent": agent,
        "config": res.config,
        "mdp": source,
        **run_meta,
        "goals": {s.goal: s.as_dict() for s in res.summaries},
        "files": {k: str(v) for k, v in job.files.items()},
    }
    atomic_write_json(files["summary"], summary)


def _write_figures(job: _TrainJob, res: _Results, files: dict[str, Path], runs: int) -> None:
    """The learning curves and, with centres, the Q heat maps.

    With ``job.pool`` the pool draws the curves (unless it has not started them when this
    process is done with the grid) while this process draws the grid; the per-goal heat
    maps come ready from :func:`_train_goals_shared` (``res.pngs``).
    """
    from simlab.training.curves import render_learning_curves, save_learning_curves

    m, agent = job.m, job.cfg.agent
    panels = [(f"{s.goal}: final {s.final_mean_reward:.1f} / optimal {s.optimal_return:.1f}",
               {agent: res.runs[s.goal].rewards}, s.optimal_return) for s in res.summaries]  # fmt: skip
    suptitle = f"{agent}, {runs} runs, mean and std per block"
    curves = None
    if job.pool is None:
        save_learning_curves(files["curves_png"], panels, suptitle=suptitle)
    else:
        curves = job.pool.submit(render_learning_curves, panels, suptitle=suptitle)
    if m.centres is not None:
        _write_heatmaps(job, res, files)
    if curves is not None and curves.cancel():  # the pool is busy elsewhere: draw it here
        save_learning_curves(files["curves_png"], panels, suptitle=suptitle)
    elif curves is not None:
        atomic_write_bytes(files["curves_png"], curves.result())


def _heatmap_scene(job: _TrainJob) -> Any:
    """What every goal's heat map shares: the MDP's centres, action set and valid actions,
    the arena's bounds and map."""
    from simlab.training.heatmap import HeatmapScene

    m = job.m
    return HeatmapScene(m.centres, job.plot_bounds, background=job.background,
                        action_set=m.action_set, valid=m.valid)


def _write_heatmaps(job: _TrainJob, res: _Results, files: dict[str, Path]) -> None:
    """The per-goal heat maps (drawn here unless ``res.pngs`` has them) and the grid."""
    from simlab.training.heatmap import save_heatmap_grid, save_q_heatmap

    m, names, agent = job.m, job.names, job.cfg.agent
    scene = _heatmap_scene(job)
    masks = [m.goal_mask(g) for g in names]
    for g, mask in zip(names, masks, strict=True):
        if g in res.pngs:
            atomic_write_bytes(files[f"heatmap_{g}"], res.pngs[g])
            continue
        save_q_heatmap(files[f"heatmap_{g}"], scene, res.Qs[g], mask,
                       title=f"{agent}: goal {g}")
    save_heatmap_grid(files["heatmaps"], scene, [res.Qs[g] for g in names], masks, names,
                      suptitle=f"max_a Q(s, a) and argmax arrows, {agent}")
