"""``visitlab.combined``: the combined architecture (thesis 3.1.1, 4.4)."""

from __future__ import annotations

from typing import Any

import numpy as np

from simlab.base import validation
from simlab.experiments.context import RunContext, RunResult
from simlab.experiments.registry import runner
from simlab.experiments.visitlab.modules import (
    MODULE_KEYS,
    combined_task,
    evaluate_job,
    module_metrics,
    module_specs,
    modules_of,
)
from simlab.experiments.visitlab.runs import cache_note, get_runs, param_notes, visitlab_seed


def _combined_notes(specs: dict[str, Any], task: Any) -> list[str]:
    """What :func:`combined`'s notes say of its modules, the GIF and a greedy social
    module's loops."""
    return [f"Modules (seed i of each): navigation {specs['nav'].agent} "
            f"({specs['nav'].trials:,} trials, random start and goal), go-to-human "
            f"{specs['gotohuman'].agent} ({specs['gotohuman'].trials:,} trials), social "
            f"{specs['social'].agent} with human '{task.human.name}' "
            f"({specs['social'].trials:,} trials). World {task.layout.name}, "
            f"{task.max_steps}-step trials, speed weights {task.speed_weights}.",
            "The GIF is the first evaluation trial of seed 0 in which at least two goal "
            "rooms were reached (the goal room is blue; the caption gives the social "
            "module's action, the delegated go-to-human move after '->', the interaction "
            "level and the required direction).",
            "A greedy social module can loop: in social training action 29 jumped two "
            "cells ahead of the human's gaze with a random orientation, here it is one "
            "go-to-human move, which does nothing once the robot stands in the facing "
            "field; trials_with_a_goal and the eps-greedy evaluation "
            "(egreedy_goals_per_trial, the module's own exploration rate) show how much "
            "this costs."]


@runner("visitlab.combined")
def combined(params: dict[str, Any], budget: dict[str, Any], ctx: RunContext) -> RunResult:
    """The combined architecture (thesis 3.1.1, 4.4): goal rooms reached per trial.

    Trains (or reuses) the three modules (:func:`module_specs`), then runs the frozen
    architecture greedily for ``budget.trials`` trials per seed, epsilon-greedily, and
    the chance level (the social module replaced by uniformly random actions). Metrics:
    ``goals_per_trial`` (mean over trials and seeds), ``goals_per_trial_seed_std``,
    ``egreedy_goals_per_trial`` (the social module epsilon-greedy with its training
    epsilon), ``random_goals_per_trial``, ``trials_with_a_goal`` (fraction),
    ``nav_direction_optimal`` (fraction of (cell, goal) outside the goal room where the
    navigation module's required direction is an optimal one), the modules' plateaus,
    ``gif_goals``. Figures: ``goals_per_trial.png``, ``episode.gif``.
    """
    from simlab.visitlab.combined import record_episodes, write_episode_gif
    from simlab.visitlab.figures import plot_histograms
    from simlab.visitlab.fused import loop_agent_config
    from simlab.visitlab.training import seed_generators

    specs = module_specs(params, budget)
    n = specs["nav"].seeds
    trials = validation.whole(budget.get("trials"), "budget.trials", minimum=1)
    task = combined_task(params, specs)
    got = get_runs(ctx, [specs[k] for k in MODULE_KEYS], desc="modules")
    runs = dict(zip(MODULE_KEYS, got, strict=True))
    seed = visitlab_seed(ctx.root_seed, 1)
    social_cfg = loop_agent_config(specs["social"].agent, "social", specs["social"].variant,
                                   dict(specs["social"].overrides))
    eps = float(getattr(social_cfg, "epsilon", 0.05))
    jobs = [{"task": task, "modules": modules_of(runs, i), "trials": trials, "seed": seed,
             "index": i, "n_seeds": n, "epsilon": e} for e in (0.0, eps, 1.0) for i in range(n)]
    res = ctx.map(evaluate_job, jobs, desc=f"{ctx.name}: evaluation")
    goals = np.stack([r.goals for r in res[:n]])
    explore = np.stack([r.goals for r in res[n:2 * n]])
    rand = np.stack([r.goals for r in res[2 * n:]])
    figures = [plot_histograms([("combined architecture (greedy)", goals.ravel()),
                                (f"eps-greedy social module ({eps:g})", explore.ravel()),
                                ("random social actions", rand.ravel())],
                               ctx.out / "goals_per_trial.png", xlabel="goal rooms reached per trial",
                               title=f"{task.max_steps}-step trials, {n} seeds x {trials} trials")]
    # the GIF: the first evaluation trial of seed 0 with two goals or more (else the best)
    k = min(trials, 50)
    episodes = record_episodes(task, modules_of(runs, 0), k, seed_generators(seed, n)[0])
    pick = next((e for e in episodes if e.goals >= 2), max(episodes, key=lambda e: e.goals))
    figures.append(write_episode_gif(task, pick, ctx.out / "episode.gif", overwrite=True))
    per_seed = goals.mean(axis=1)
    metrics = {"goals_per_trial": float(goals.mean()), "goals_per_trial_seed_std":
               float(per_seed.std()), "egreedy_goals_per_trial": float(explore.mean()),
               "random_goals_per_trial": float(rand.mean()),
               "trials_with_a_goal": float((goals > 0).mean()),
               **module_metrics(runs, task), "gif_goals": pick.goals,
               "trials": trials, "seeds": n, "max_steps": task.max_steps}
    notes = [cache_note(got), *_combined_notes(specs, task)]
    details = {"goals_per_seed": per_seed.round(4).tolist(),
               "random_goals_per_seed": rand.mean(axis=1).round(4).tolist()}
    return RunResult(metrics=metrics, figures=figures, notes=notes + param_notes(params),
                     details=details)


# --------------------------------------------------------------------------- Fig. 4.7

