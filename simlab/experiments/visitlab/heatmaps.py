"""``visitlab.nav_heatmaps``: thesis Fig. 4.3, navigation value maps of the 9 goal rooms."""

from __future__ import annotations

from typing import Any

import numpy as np

from simlab.base.errors import ConfigError
from simlab.experiments.context import RunContext, RunResult
from simlab.experiments.registry import runner
from simlab.experiments.visitlab.metrics import curve_metrics, greedy_success, pearson
from simlab.experiments.visitlab.runs import (
    cache_note,
    env_kwargs,
    get_runs,
    param_notes,
    parse_run,
)


@runner("visitlab.nav_heatmaps")
def nav_heatmaps(params: dict[str, Any], budget: dict[str, Any], ctx: RunContext) -> RunResult:
    """Thesis Fig. 4.3: the navigation Q values for each goal room.

    ``params.run``: the run table (goal-conditioned navigation: random start and goal).
    Metrics: ``goals``; ``min_greedy_success`` / ``mean_greedy_success`` (fraction of
    the cells outside the goal room from which the greedy policy of a seed's Q reaches
    the goal room within one trial, worst goal / mean over goals and seeds);
    ``min_inside_minus_outside`` (per goal, mean ``max_a Q`` inside the goal room minus
    outside, averaged over seeds; the worst goal); ``mean_corr_vstar`` (correlation of
    ``max_a Q`` with the optimal V* over the cells, mean over goals and seeds).
    Figure: ``heatmaps.png`` (``max_a Q`` averaged over seeds).
    """
    from simlab.visitlab.figures import plot_nav_heatmaps
    from simlab.visitlab.passive import nav_optimal_q

    spec = parse_run(params.get("run"), "params.run", params, budget)
    if spec.task != "nav":
        raise ConfigError("expected a navigation run", key="params.run.task")
    (run,) = get_runs(ctx, [spec])
    env = env_kwargs(spec.env)
    from simlab.visitlab.training import make_env

    nav_env = make_env("nav", variant=spec.variant, **env)
    lay = nav_env.layout
    horizon = nav_env.max_steps
    qstar = nav_optimal_q(lay)
    n = lay.n_cells
    nxt = lay.transition_table()
    labels = lay.cell_labels
    success = np.zeros((run.q.shape[0], len(lay.goal_labels)))
    corr = np.zeros_like(success)
    for i, q in enumerate(run.q):
        for j, g in enumerate(lay.goal_labels):
            block = q[g * n:(g + 1) * n]
            success[i, j] = greedy_success(nxt, labels, block, g, horizon)
            corr[i, j] = pearson(block.max(axis=1), qstar[g * n:(g + 1) * n].max(axis=1))
    values = run.q.max(axis=2).mean(axis=0)  # mean over seeds of max_a Q
    gaps = []
    for g in lay.goal_labels:
        v = values[g * n:(g + 1) * n]
        inside = labels == g
        gaps.append(float(v[inside].mean() - v[~inside].mean()))
    fig = plot_nav_heatmaps(lay, values, ctx.out / "heatmaps.png", arrows_q=run.q[0],
                            title=f"{spec.agent}: max_a Q per goal room (mean of {spec.seeds} "
                                  f"seeds, {spec.trials:,} trials; arrows: seed 0's greedy move)")
    per_goal = success.mean(axis=0)
    metrics = {"goals": len(lay.goal_labels), "min_greedy_success": float(per_goal.min()),
               "mean_greedy_success": float(success.mean()),
               "min_inside_minus_outside": float(min(gaps)),
               "mean_corr_vstar": float(np.nanmean(corr)),
               **curve_metrics(spec.label, run.returns)}
    notes = [cache_note([run]),
             f"{spec.agent} trained on the {lay.name} world with a random start and a random "
             f"goal room each trial ({spec.trials:,} trials x {spec.seeds} seeds, "
             f"{horizon}-step trials); the maps show max_a Q averaged over seeds."]
    details = {"greedy_success_per_goal": per_goal.round(4).tolist(),
               "inside_minus_outside": [round(g, 4) for g in gaps],
               "corr_vstar_per_goal": np.nanmean(corr, axis=0).round(4).tolist()}
    return RunResult(metrics=metrics, figures=[fig], notes=notes + param_notes(params),
                     details=details)
