"""The social task in physics: the combined architecture closed loop on the table.

Not a figure of the thesis: its conclusion names it as the next step ("have the Turtlebot
deal with a social navigation problem"). The runner calls
:func:`simlab.social.pipeline.social_pipeline` (train the grid social module, lead the
simulated human through the table's goal areas, against a uniformly random policy on the
same seeds) and turns its summary into metrics. The physics walk of the empirical module
runs its segments on the reproduction's executor (``ctx.executor``), like the other
experiments' jobs; the data do not depend on it.
"""

from __future__ import annotations

from typing import Any

from simlab.experiments.context import RunContext, RunResult
from simlab.experiments.registry import runner


@runner("social.closed_loop")
def closed_loop(params: dict[str, Any], budget: dict[str, Any], ctx: RunContext) -> RunResult:
    """Goal areas reached with the human, per simulated hour, learned vs random.

    Metrics: ``combined_goals_per_hour`` / ``random_goals_per_hour`` (pooled over the
    runs), ``goal_rate_ratio`` (None when random reached none), ``combined_goals`` /
    ``random_goals``, ``social_reward_per_decision`` (physics) beside
    ``grid_plateau_reward_per_step`` (the grid training's plateau), ``runs``, ``hours``.
    """
    from simlab.social.pipeline import SocialPipelineConfig, social_pipeline

    settings = {**params, **budget}
    settings["runs"] = settings.pop("seeds")  # the framework's seeds = closed-loop runs
    # the walk's segments run on the reproduction's executor (its --workers / --backend),
    # not on worker processes of their own: a budget's ``workers`` gives way to it
    settings.pop("workers", None)
    cfg = SocialPipelineConfig.from_mapping(
        {**settings, "out": ctx.out / "run", "seed": int(ctx.root_seed)})
    res = social_pipeline(cfg, executor=ctx.executor)
    s = res.summary
    c, r = s["pooled"]["combined"], s["pooled"]["random"]
    metrics = {
        "combined_goals_per_hour": c["goals_per_hour"],
        "random_goals_per_hour": r["goals_per_hour"],
        "goal_rate_ratio": s["goal_rate_ratio"],
        "combined_goals": c["goals"],
        "random_goals": r["goals"],
        "social_reward_per_decision": c["social_reward_per_decision"],
        "grid_plateau_reward_per_step": s["training"].get("plateau_reward_per_step"),
        "empirical_goals_per_hour": s["goals_per_hour"].get("empirical"),
        "predicted_goals_per_hour": s["tabular_prediction"]["goals_per_hour"],
        "empirical_goal_rate_ratio": s.get("empirical_goal_rate_ratio"),
        "predicted_grid_goals_per_hour": (s["predicted_goals_per_hour"] or {}).get(
            "grid", {}).get("goals_per_hour"),
        "runs": cfg.runs,
        "hours": cfg.hours,
    }
    notes = [
        f"{cfg.runs} run(s) of {cfg.hours:g} simulated h per policy on the {cfg.arena!r} "
        f"arena with the {cfg.human!r} human; the social module trained on the grid "
        f"({cfg.variant} variant, {cfg.trials} trials) and mapped to the 22 physics actions.",
        "The required direction is the heading from the human to the current goal centre "
        "(the open table needs no path planning); a goal counts when the engaged human "
        "(level >= 5) stands in it.",
        "empirical_goals_per_hour: the social module planned on the empirical social MDP of "
        "a physics walk (module both); predicted_goals_per_hour: the renewal model on that "
        "MDP (summary.json's tabular_prediction and predicted_goals_per_hour).",
    ]
    return RunResult(metrics=metrics, figures=list(res.paths.get(k) for k in ("plot", "gif")
                                                   if k in res.paths),
                     notes=notes, details={"summary": s})
