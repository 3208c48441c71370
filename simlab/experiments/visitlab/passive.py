"""``visitlab.passive_qmaps``: IMOL poster Fig. 5, what a passive Q-learner learns by
watching model-based agents."""

from __future__ import annotations

from typing import Any

import numpy as np

from simlab.base.errors import ConfigError
from simlab.experiments.context import RunContext, RunResult
from simlab.experiments.registry import runner
from simlab.experiments.visitlab.metrics import curve_metrics, pearson
from simlab.experiments.visitlab.runs import (
    cache_note,
    env_kwargs,
    get_runs,
    param_notes,
    parse_run,
)


@runner("visitlab.passive_qmaps")
def passive_qmaps(params: dict[str, Any], budget: dict[str, Any], ctx: RunContext) -> RunResult:
    """IMOL poster Fig. 5: Q maps learned by model-free agents on the goal-conditioned
    navigation task, alone or watching model-based agents that explore differently.

    ``[[params.runs]]`` as for ``visitlab.curves`` (navigation runs; an ``observer`` run
    contributes its observer's Q table, another run its own); ``params.goal`` the goal
    room of the maps. Metrics per run ``L``: ``L_corr_vstar`` (Pearson correlation of
    the learned ``max_a Q(s)`` with the optimal ``V*(s)`` over every state of every goal,
    pooled over seeds), ``L_mae_vstar`` (mean absolute error), ``L_visited`` (fraction
    of states whose learned value is not 0, i.e. that the learner ever updated toward a
    reward) and the curve metrics. Figures: ``qmaps.png``, ``q_vs_vstar.png``.
    """
    from simlab.visitlab.figures import plot_q_maps, plot_q_vs_vstar
    from simlab.visitlab.passive import nav_optimal_q
    from simlab.visitlab.training import make_env

    raw_runs = params.get("runs")
    if not isinstance(raw_runs, list) or not raw_runs:
        raise ConfigError("expected one or more [[params.runs]] tables", key="params.runs")
    specs = [parse_run(r, f"params.runs[{i}]", params, budget) for i, r in enumerate(raw_runs)]
    if any(s.task != "nav" for s in specs):
        raise ConfigError("poster Fig. 5 is about the navigation task", key="params.runs")
    runs = get_runs(ctx, specs)
    env = make_env("nav", variant=specs[0].variant, **env_kwargs(specs[0].env))
    lay = env.layout
    goal = params.get("goal", lay.goal_labels[-1])
    if goal not in lay.goal_labels:
        raise ConfigError(f"expected one of {lay.goal_labels}, got {goal!r}", key="params.goal")
    vstar = nav_optimal_q(lay).max(axis=1)
    goal_rows = np.concatenate([np.arange(lay.n_cells) + g * lay.n_cells
                                for g in lay.goal_labels])
    metrics: dict[str, Any] = {}
    tables, series = [], []
    for r in runs:
        q = r.q_observer if r.spec.observer else r.q
        learned = q.max(axis=2)[:, goal_rows]  # (seeds, states)
        v = np.broadcast_to(vstar[goal_rows], learned.shape)
        L = r.spec.label
        metrics[f"{L}_corr_vstar"] = pearson(learned.ravel(), v.ravel())
        metrics[f"{L}_mae_vstar"] = float(np.abs(learned - v).mean())
        metrics[f"{L}_visited"] = float((learned != 0).mean())
        metrics.update(curve_metrics(L, r.returns))
        legend = r.spec.legend or L
        tables.append((legend, q.max(axis=2).mean(axis=0)))
        series.append((legend, v.ravel(), learned.ravel()))
    figs = [plot_q_maps(lay, tables, int(goal), ctx.out / "qmaps.png",
                        title=f"max_a Q for {lay.room_names[int(goal)]} (mean of "
                              f"{specs[0].seeds} runs)"),
            plot_q_vs_vstar(series, ctx.out / "q_vs_vstar.png",
                            title=f"learned values vs V*(s), all goal rooms, {specs[0].seeds} runs")]
    notes = [cache_note(runs), "Observers watch for the whole run (take-over at 100 %), so their "
             "Q tables hold only what the actor's exploration showed them."]
    return RunResult(metrics=metrics, figures=figs, notes=notes + param_notes(params))
