"""``simlab train``: train an agent on an empirical MDP for each goal area (SPEC A9).

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

Seeding: goal ``g`` (its index in the file's goal list) uses
``SeedSequence(seed, spawn_key=(g,))``, so training one goal alone gives the same
numbers as training it among all goals.
"""

from __future__ import annotations

import dataclasses
import os
import re
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from simlab.errors import ConfigError
from simlab.io import atomic_write_json, ensure_new

__all__ = ["GoalSummary", "TrainSummary", "resolve_goals", "train"]


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


def train(
    mdp: str | os.PathLike[str] | Any,
    agent: str = "vi-softmax",
    goals: str | Sequence[str] | None = "all",
    episodes: int = 2000,
    runs: int = 10,
    seed: int = 0,
    out: str | os.PathLike[str] | None = None,
    *,
    horizon: int = 50,
    start: int | None = None,
    params: dict[str, Any] | None = None,
    bounds: Sequence[float] | None = None,
    arena: Any = None,
    occupancy_map: Any = None,
    plots: bool = True,
    overwrite: bool = False,
    progress: bool = True,
) -> TrainSummary:
    """Train ``agent`` on the empirical MDP ``mdp`` for each goal; write results to ``out``.

    Parameters
    ----------
    mdp:
        ``mdp.npz`` path (``simlab estimate``) or an :class:`~simlab.envs.empirical_mdp.EmpiricalMDP`.
    agent:
        A registered agent name (:mod:`simlab.agents.registry`).
    goals:
        ``"all"``, a comma-separated string or a list of goal names.
    episodes, runs, seed, horizon, start:
        Training budget, independent runs, root seed, steps per episode, fixed
        start state (``None``: uniform).
    params:
        Hyper-parameter overrides of the agent's preset (``{"tau": 0.05}``).
    bounds, arena:
        Heat-map extent ``(x_min, y_min, x_max, y_max)`` m, or an arena (name,
        path or config) to take it from; default: the MDP file's ``bounds`` or
        the centres' extent.
    occupancy_map:
        Optional ``map.yaml`` path or occupancy map drawn under the heat maps.
    out:
        Output directory (created); ``None`` writes nothing and only returns.
    plots, overwrite, progress:
        Write PNGs; replace existing outputs; show a progress bar.
    """
    from tqdm.auto import tqdm

    from simlab.envs.empirical_mdp import EmpiricalMDP, load_mdp
    from simlab.training.curves import curve_points
    from simlab.training.harness import evaluate_q, train_runs

    t0 = time.perf_counter()
    m = mdp if isinstance(mdp, EmpiricalMDP) else load_mdp(mdp)
    names = resolve_goals(m, goals)
    from simlab.agents.registry import agent_config

    cfg = agent_config(agent, params)  # validates the name and overrides before any work
    gamma = float(cfg.gamma)
    if start is not None and not (0 <= int(start) < m.n_states):
        raise ConfigError(f"expected a state in [0, {m.n_states}), got {start}", key="start")
    plot_bounds = _bounds(m, bounds, arena) if plots else None
    background = occupancy_map
    if plots and isinstance(occupancy_map, str | os.PathLike):
        from discretize.mapio import read_map

        background = read_map(occupancy_map)

    files: dict[str, Path] = {}
    if out is not None:
        out = Path(out)
        for g in names:
            files[f"q_{g}"] = out / f"q_{_slug(g)}.npz"
        files["curves"] = out / "curves.npz"
        files["summary"] = out / "summary.json"
        if plots:
            files["curves_png"] = out / "curves.png"
            if m.centres is not None:
                files["heatmaps"] = out / "heatmaps.png"
                for g in names:
                    files[f"heatmap_{g}"] = out / f"heatmap_{_slug(g)}.png"
        for p in files.values():  # fail before training, not after
            ensure_new(p, overwrite=overwrite)
        out.mkdir(parents=True, exist_ok=True)

    results = {}
    evaluations = {}
    bar = tqdm(total=len(names) * runs, disable=not progress, desc=f"train {agent}", unit="run")
    try:
        for g in names:
            gi = m.goal_index(g)
            reward = m.goal_reward(g)
            seq = np.random.SeedSequence(seed, spawn_key=(gi,))
            res = train_runs(
                m.T, reward, agent, episodes=episodes, runs=runs, seed=seq, horizon=horizon,
                start=start, overrides=params, on_run_done=lambda: bar.update(1),
            )  # fmt: skip
            results[g] = res
            Q_mean = res.Q_runs.mean(axis=0)
            evaluations[g] = evaluate_q(m.T, reward, np.concatenate([res.Q_runs, Q_mean[None]]),
                                        gamma, horizon, start)  # fmt: skip
    finally:
        bar.close()

    tail = max(1, episodes // 10)
    summaries = []
    curve_rows = []
    for g in names:
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
    rewards = np.stack([results[g].rewards for g in names])
    Qs = {g: results[g].Q_runs.mean(axis=0) for g in names}
    config = results[names[0]].config
    if out is not None:
        _write_outputs(files, m, names, results, evaluations, Qs, rewards, curve_rows, summaries,
                       agent, config, dict(seed=seed, episodes=episodes, runs=runs,
                                           horizon=horizon, start=start, gamma=gamma),
                       plot_bounds, background, plots)  # fmt: skip
    return TrainSummary(
        agent=agent, config=config, goals=tuple(summaries), rewards=rewards, Q=Qs,
        files={k: str(v) for k, v in files.items()}, seconds=time.perf_counter() - t0,
        out=None if out is None else Path(out),
    )  # fmt: skip


def _write_outputs(files, m, names, results, evaluations, Qs, rewards, curve_rows, summaries,
                   agent, config, run_meta, plot_bounds, background, plots) -> None:  # fmt: skip
    import simlab
    from simlab.agents.storage import save_q_table

    source = None if m.source is None else str(m.source)
    for g in names:
        res = results[g]
        arrays = {"Q_runs": res.Q_runs, "Q_star": evaluations[g].Q_star,
                  "goal_mask": m.goal_mask(g)}  # fmt: skip
        arrays.update(res.extra)
        meta = {"agent": agent, "config": config, "goal": g, "goal_index": m.goal_index(g),
                "mdp": source, "Q": "mean over runs of the final Q-tables",
                "simlab_version": simlab.__version__, **run_meta}  # fmt: skip
        save_q_table(files[f"q_{g}"], Qs[g], metadata=meta, arrays=arrays, overwrite=True)

    import json

    from simlab.io import atomic_write

    x = curve_rows[0][0]
    with atomic_write(files["curves"], "wb") as fh:
        np.savez_compressed(
            fh, rewards=rewards, goal_names=np.array(names), curve_x=x,
            curve_mean=np.stack([r[1] for r in curve_rows]),
            curve_std=np.stack([r[2] for r in curve_rows]),
            optimal_return=np.array([s.optimal_return for s in summaries]),
            meta_json=np.array(json.dumps({"agent": agent, "config": config, **run_meta})),
        )  # fmt: skip
    if plots:
        from simlab.training.curves import save_learning_curves

        panels = [(f"{s.goal}: final {s.final_mean_reward:.1f} / optimal {s.optimal_return:.1f}",
                   {agent: results[s.goal].rewards}, s.optimal_return) for s in summaries]  # fmt: skip
        save_learning_curves(
            files["curves_png"],
            panels,
            suptitle=f"{agent}, {run_meta['runs']} runs, mean and std per block",
        )
        if m.centres is not None:
            from simlab.training.heatmap import save_heatmap_grid, save_q_heatmap

            masks = [m.goal_mask(g) for g in names]
            for g, mask in zip(names, masks, strict=True):
                save_q_heatmap(files[f"heatmap_{g}"], m.centres, Qs[g], plot_bounds, mask,
                               background=background, title=f"{agent}: goal {g}")  # fmt: skip
            save_heatmap_grid(files["heatmaps"], m.centres, [Qs[g] for g in names], masks, names,
                              plot_bounds, background=background,
                              suptitle=f"max_a Q(s, a) and argmax arrows, {agent}")  # fmt: skip
    summary = {
        "agent": agent,
        "config": config,
        "mdp": source,
        **run_meta,
        "goals": {s.goal: s.as_dict() for s in summaries},
        "files": {k: str(v) for k, v in files.items()},
    }
    atomic_write_json(files["summary"], summary)
