"""The training loop of ``simlab train``: every goal trained and evaluated, here or shared
with a process pool, and the per-goal summary figures.

Goal ``g`` (its index in the MDP's goal list) draws from ``SeedSequence(seed,
spawn_key=(g,))``, so a goal gives the same numbers wherever it runs and whichever goals run
beside it. The records: :class:`TrainJob` (what :func:`simlab.training.train.train`
validated), :class:`TrainResults` (what the runs produced), :class:`GoalSummary` (one goal's
figures, written to ``summary.json``).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from simlab.training.config import TrainConfig

__all__ = ["GoalSummary", "TrainJob", "TrainResults", "goal_summaries", "heatmap_scene",
           "train_goals", "train_goals_shared"]


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
class TrainJob:
    """Everything :func:`simlab.training.train.train` validated: what the loop and the
    writers of :mod:`simlab.training.outputs` read."""

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
class TrainResults:
    """What the runs of every goal produced."""

    runs: dict[str, Any]
    evaluations: dict[str, Any]
    summaries: list[GoalSummary]
    curve_rows: list[tuple[Any, Any, Any]]
    rewards: np.ndarray
    Qs: dict[str, np.ndarray]
    config: Any
    pngs: dict[str, bytes] = dataclasses.field(default_factory=dict)
    """Heat maps already drawn by :func:`train_goals_shared`, by goal."""


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


def _goal_work(job: TrainJob, heatmaps: bool = False) -> _GoalWork:
    cfg, m = job.cfg, job.m
    draw = heatmaps and "heatmaps" in job.files  # plots, centres and an output directory
    heatmap = heatmap_scene(job) if draw else None
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


def train_goals(job: TrainJob) -> tuple[dict[str, Any], dict[str, Any]]:
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


def train_goals_shared(job: TrainJob
                        ) -> tuple[dict[str, Any], dict[str, Any], dict[str, bytes]]:
    """:func:`train_goals` with ``job.pool``: (runs, evaluations, heat-map PNGs by goal).

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


def goal_summaries(job: TrainJob, results: dict[str, Any], evaluations: dict[str, Any]
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


def heatmap_scene(job: TrainJob) -> Any:
    """What every goal's heat map shares: the MDP's centres, action set and valid actions,
    the arena's bounds and map."""
    from simlab.training.heatmap import HeatmapScene

    m = job.m
    return HeatmapScene(m.centres, job.plot_bounds, background=job.background,
                        action_set=m.action_set, valid=m.valid)
