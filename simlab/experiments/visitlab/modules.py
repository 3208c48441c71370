"""The three trained modules of the combined architecture, shared by
``visitlab.combined`` and ``visitlab.adaptability``: their run tables, the combined
task, the modules of one seed and their quality metrics."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from simlab.base import validation
from simlab.base.errors import ConfigError
from simlab.experiments.visitlab.metrics import curve_metrics
from simlab.experiments.visitlab.runs import (
    RunData,
    RunSpec,
    as_table,
    env_kwargs,
    parse_run,
)

MODULE_KEYS = ("nav", "gotohuman", "social")


def module_specs(params: Mapping[str, Any], budget: Mapping[str, Any]) -> dict[str, RunSpec]:
    """The three module runs of the combined architecture: ``[params.nav]``,
    ``[params.gotohuman]``, ``[params.social]`` (run tables without ``task``), trained
    for ``budget.nav_trials``, ``budget.gth_trials``, ``budget.social_trials``. The
    social run keeps its model (for continued learning)."""
    out = {}
    trials_keys = {"nav": "nav_trials", "gotohuman": "gth_trials", "social": "social_trials"}
    for task in MODULE_KEYS:
        raw = as_table(params.get(task), f"params.{task}")
        if "task" in raw:
            raise ConfigError("the task of a module is its table's name", key=f"params.{task}.task")
        raw = {"label": task, **raw, "task": task}
        out[task] = parse_run(raw, f"params.{task}", params, budget,
                              trials_key=trials_keys[task], keep_model=task == "social")
    return out


def combined_task(params: Mapping[str, Any], specs: Mapping[str, RunSpec], human: Any = None):
    from simlab.visitlab.combined import CombinedTask
    from simlab.visitlab.perception import perception_for

    c = as_table(params.get("combined"), "params.combined")
    unknown = sorted(set(c) - {"layout", "speed_weights", "max_steps"})
    if unknown:
        raise ConfigError(f"unknown key(s) {', '.join(unknown)}", key="params.combined")
    if human is None:
        human = env_kwargs(specs["social"].env).get("human", "easy")
    return CombinedTask(layout=c.get("layout", "gridworld"), human=human,
                        perception=perception_for(specs["social"].variant),
                        speed_weights=tuple(c.get("speed_weights", (0.1, 0.1, 0.8))),
                        max_steps=validation.whole(c.get("max_steps", 100),
                                                   "params.combined.max_steps", minimum=1))


def modules_of(runs: Mapping[str, RunData], i: int):
    from simlab.visitlab.combined import Modules

    return Modules(runs["nav"].q[i], runs["social"].q[i], runs["gotohuman"].q[i])


def direction_matrix(weights: Sequence[float]) -> np.ndarray:
    """``(25, 8)`` matrix ``M`` with ``Q_row @ M`` = the weighted sums per direction of
    :func:`simlab.visitlab.combined.direction_values` (STAY has no direction)."""
    from simlab.visitlab.actions import ACTION_DIR, ACTION_SPEED

    m = np.zeros((25, 8))
    for a in range(24):
        m[a, ACTION_DIR[a]] = weights[ACTION_SPEED[a] - 1]
    return m


def module_metrics(runs: Mapping[str, RunData], task: Any) -> dict[str, Any]:
    """Quality of the navigation module's required directions and the modules' curves."""
    from simlab.visitlab.passive import nav_optimal_q

    lay = task.layout
    m = direction_matrix(task.speed_weights)
    n = lay.n_cells
    rows = np.concatenate([np.arange(n)[lay.cell_labels != g] + g * n for g in lay.goal_labels])
    best_star = nav_optimal_q(lay)[rows] @ m
    top = best_star.max(axis=1) - 1e-9
    ok = [np.mean(best_star[np.arange(rows.size), (q[rows] @ m).argmax(axis=1)] >= top)
          for q in runs["nav"].q]
    return {"nav_direction_optimal": float(np.mean(ok)),
            "nav_plateau": curve_metrics("x", runs["nav"].returns)["x_plateau"],
            "gth_plateau": curve_metrics("x", runs["gotohuman"].returns)["x_plateau"],
            "social_plateau": curve_metrics("x", runs["social"].returns)["x_plateau"]}


def evaluate_job(task: Any, modules: Any, trials: int, seed: int, index: int, n_seeds: int,
                 epsilon: float) -> Any:
    """Greedy (``epsilon`` 0) or epsilon-greedy evaluation of seed ``index``'s modules."""
    from simlab.visitlab.combined import evaluate
    from simlab.visitlab.training import seed_generators

    return evaluate(task, modules, int(trials), seed_generators(seed, n_seeds)[index],
                    epsilon=float(epsilon))


# --------------------------------------------------------------------------- combined

