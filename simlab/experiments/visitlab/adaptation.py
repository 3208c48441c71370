"""``visitlab.adaptability``: thesis Fig. 4.7, continued learning with three humans."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from simlab.base import validation
from simlab.base.errors import ConfigError
from simlab.experiments.context import RunContext, RunResult
from simlab.experiments.registry import runner
from simlab.experiments.visitlab.metrics import curve_details
from simlab.experiments.visitlab.modules import MODULE_KEYS, combined_task, module_specs, modules_of
from simlab.experiments.visitlab.runs import (
    as_table,
    cache_note,
    env_kwargs,
    get_runs,
    param_notes,
    visitlab_seed,
)


def adapt_job(task: Any, modules: Any, model: dict[str, np.ndarray] | None, agent_cfg: Any,
              trials: int, seed: int, index: int, n_seeds: int) -> np.ndarray:
    """Goals per trial of seed ``index``'s social module continuing to learn."""
    from simlab.visitlab.adaptability import continue_learning
    from simlab.visitlab.training import seed_generators

    run = continue_learning(task, modules, agent_cfg, int(trials),
                            seed_generators(seed, n_seeds)[index], model=model)
    return run.goals


def _adaptation_humans(params: Mapping[str, Any], trained: Any) -> dict[str, Any]:
    """``[params.humans]`` (name -> preset name or table of Human fields), or the thesis's
    three humans for the training human (:func:`~simlab.visitlab.adaptability.thesis_humans`)."""
    from simlab.visitlab.adaptability import thesis_humans
    from simlab.visitlab.humans import human as get_human

    raw = as_table(params.get("humans"), "params.humans")
    if not raw:
        return thesis_humans(trained)
    out = {}
    for name, h in raw.items():
        if not str(name).replace("_", "").isalnum():
            raise ConfigError(f"use letters, digits and '_', got {name!r}",
                              key=f"params.humans.{name}")
        out[str(name)] = (env_kwargs({"human": dict(h)})["human"] if isinstance(h, Mapping)
                          else get_human(h))
    return out


def _carry_options(params: Mapping[str, Any]) -> list[bool]:
    """``params.carry_model``: distinct booleans, the first the one metrics describe."""
    carry = params.get("carry_model", [True])
    if (not isinstance(carry, list) or not carry or not all(isinstance(c, bool) for c in carry)
            or len(set(carry)) != len(carry)):
        raise ConfigError(f"expected a list of distinct booleans, got {carry!r}",
                          key="params.carry_model")
    return carry


def level_metrics(goals: np.ndarray) -> dict[str, Any]:
    """``start`` (mean goals per trial over the first 10 % of trials), ``final`` (last
    20 %) and ``trials_to_90pct`` (first trial at which the smoothed seed-mean curve
    reaches 90 % of ``final``; None if never) of ``goals`` ``(seeds, trials)``."""
    from simlab.visitlab.curves import smooth_curve

    trials = goals.shape[1]
    start = float(goals[:, :max(1, trials // 10)].mean())
    final = float(goals[:, -max(1, trials // 5):].mean())
    x, mean, _ = smooth_curve(goals, min(50, trials))
    hit = np.flatnonzero(mean >= 0.9 * final) if final > 0 else np.zeros(0, dtype=int)
    return {"start": start, "final": final,
            "trials_to_90pct": int(x[hit[0]]) if hit.size else None}


def _carry_panels(carry: list[bool], humans: dict[str, Any],
                  curves: dict[tuple[bool, str], list[np.ndarray]]
                  ) -> tuple[dict[str, Any], list[Any], dict[str, Any]]:
    """Per carry option (what continues: Q and model, or Q only) and human: the level
    metrics and ratios to ``same`` (:func:`adaptability`'s names), the figure panel and the
    curves' details, from ``curves[(carry, human)]`` = goals per trial of each seed."""
    metrics: dict[str, Any] = {}
    panels = []
    legends = {"same": "same human", "slower": "2x slower human", "pointing": "pointing need"}
    details: dict[str, Any] = {"curves": {}}
    for c in carry:
        suffix = "" if c == carry[0] else ("_model" if c else "_q_only")
        panel = []
        for name in humans:
            g = np.stack(curves[(c, name)])
            metrics.update({f"{name}_{k}{suffix}": v for k, v in level_metrics(g).items()})
            panel.append((legends.get(name, humans[name].name), g))
            details["curves"][f"{name}{suffix}"] = curve_details(name, g)
        same = metrics.get(f"same_final{suffix}")
        for name in humans:
            if same is not None and name != "same":
                metrics[f"{name}_over_same{suffix}"] = (metrics[f"{name}_final{suffix}"] / same
                                                       if same > 0 else None)
        title = ("Q table and model carried over" if c
                 else "Q table only (model rebuilt from the new human)")
        panels.append((title, panel))
    return metrics, panels, details


@runner("visitlab.adaptability")
def adaptability(params: dict[str, Any], budget: dict[str, Any], ctx: RunContext) -> RunResult:
    """Thesis Fig. 4.7: the social module trained with one human continues learning in
    the combined task with the same human, a 2x slower one and one needing POINTING.

    The modules are :func:`module_specs` (shared with ``visitlab.combined``); the
    humans :func:`simlab.visitlab.adaptability.thesis_humans` of the social module's
    human, or ``[params.humans]`` (name -> preset or table of Human fields; a human
    named ``same`` is the reference of the ratios); ``params.carry_model`` a list of
    booleans (what continues: Q and model, or Q only; one figure panel each; the first is
    the one the metrics without suffix describe). Metrics per human ``h`` (``same``, ``slower``, ``pointing``) and carry
    option (suffix ``_q_only`` for Q only, ``_model`` for Q and model, on the options
    after the first): ``h_start`` (mean goals per trial over the
    first 10 % of trials), ``h_final`` (last 20 %), ``h_trials_to_90pct`` (first trial at
    which the smoothed curve reaches 90 % of ``h_final``), and the ratios
    ``pointing_over_same`` and ``slower_over_same`` of the final levels. Figure:
    ``adaptability.png``.
    """
    from simlab.visitlab.figures import plot_curve_panels
    from simlab.visitlab.fused import loop_agent_config

    specs = module_specs(params, budget)
    n = specs["nav"].seeds
    trials = validation.whole(budget.get("trials"), "budget.trials", minimum=1)
    carry = _carry_options(params)
    base_task = combined_task(params, specs)
    humans = _adaptation_humans(params, base_task.human)
    got = get_runs(ctx, [specs[k] for k in MODULE_KEYS], desc="modules")
    runs = dict(zip(MODULE_KEYS, got, strict=True))
    s = specs["social"]
    cfg = loop_agent_config(s.agent, "social", s.variant, dict(s.overrides))
    seed = visitlab_seed(ctx.root_seed, 1)
    jobs, keys = [], []
    for c in carry:
        for name, h in humans.items():
            for i in range(n):
                jobs.append({"task": base_task.with_human(h), "modules": modules_of(runs, i),
                             "model": runs["social"].model(i) if c else None, "agent_cfg": cfg,
                             "trials": trials, "seed": seed, "index": i, "n_seeds": n})
                keys.append((c, name))
    res = ctx.map(adapt_job, jobs, desc=f"{ctx.name}: continued learning")
    curves_: dict[tuple[bool, str], list[np.ndarray]] = {}
    for k, g in zip(keys, res, strict=True):
        curves_.setdefault(k, []).append(g)
    metrics, panels, details = _carry_panels(carry, humans, curves_)
    fig = plot_curve_panels(panels, ctx.out / "adaptability.png",
                            ylabel="goal rooms reached per trial",
                            title=f"Continued learning with a new human ({n} seeds, "
                                  f"{base_task.max_steps}-step trials)", n_points=min(50, trials))
    metrics.update({"trials": trials, "seeds": n})
    trained = env_kwargs(s.env).get("human", "easy")
    described = "; ".join(f"{name}: '{h.name}' (s_H {h.speed_probs}, P_H {h.pointing_need:g})"
                          for name, h in humans.items())
    notes = [cache_note(got),
             f"Social module trained with '{getattr(trained, 'name', trained)}'; continued with "
             f"{described}. The social agent ({s.agent}) continues with its own settings; the "
             "navigation and go-to-human modules are frozen (greedy)."]
    return RunResult(metrics=metrics, figures=[fig], notes=notes + param_notes(params),
                     details=details)


# --------------------------------------------------------------------------- poster Fig. 5

