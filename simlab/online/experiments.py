"""Runners of ``experiments/online_*.toml``: the navigation results of Dromnelle et al. 2022.

Runner ``online.navigation`` runs :func:`simlab.online.command.online` (every arm, the
seeds on the reproduction's executor) on one of two models:

* ``model = "isir-synthetic"`` — the 38-state, 8-action count model of
  :mod:`simlab.online.synthetic`, written as an ISIR ``transitionActions`` file into the
  experiment's folder and read back through :func:`simlab.data.counts.load_counts` (the
  path a published file takes; ``ccw-east`` actions);
* ``model = "table"`` — simlab's physics-free table MDP
  (:func:`simlab.training.synthetic.synthetic_arena_mdp`: 41 Voronoi states of the 1.5 m
  table, 16 primitives, transition noise growing with speed).

Metrics, per arm ``A`` (``mb``, ``mf``, ``random``, ``entropy``, ``entropy_and_cost_k1``
...): ``A_reward``, ``A_reward_vs_mb``, ``A_cost_vs_mb``, ``A_mb_share``; with a change
also ``A_reward_before`` / ``A_reward_after``, ``A_recovery`` (decisions to 80 % of the
pre-change reward rate; None: not recovered) and ``A_mb_share_jump`` (MB share in the
window after the change minus the window before it: MB re-engaged when > 0).
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from simlab.errors import ConfigError
from simlab.experiments.context import RunContext, RunResult
from simlab.experiments.registry import runner

__all__ = ["model_mdp", "navigation"]

MODELS = ("isir-synthetic", "table")


def model_mdp(name: str, seed: int, folder: Any) -> Any:
    """The :class:`~simlab.data.mdp.EmpiricalMDP` of model ``name`` (module docstring)."""
    from simlab.data.mdp import mdp_from_arrays

    rng = np.random.default_rng(seed)
    if name == "table":
        from simlab.training.synthetic import synthetic_arena_mdp

        return synthetic_arena_mdp(rng)
    if name != "isir-synthetic":
        raise ConfigError(f"unknown model {name!r}", key="params.model",
                          fix=f"choose one of {', '.join(MODELS)}")
    from simlab.actions import parse_action_set
    from simlab.data.counts import load_counts
    from simlab.data.estimate import empirical_mdp
    from simlab.io import atomic_write_text
    from simlab.online.synthetic import corridor_counts, isir_document

    path = folder / "transitionModel"
    doc = isir_document(corridor_counts(rng), note="synthetic stand-in (simlab.online.synthetic)")
    atomic_write_text(path, json.dumps(doc))
    table = load_counts(path, n_actions=8)
    cm = empirical_mdp(table.counts)
    return mdp_from_arrays(cm.T, counts=cm.counts, visited=cm.visited, entropy=cm.entropy,
                           source=path, action_set=parse_action_set(8, "ccw-east"))


def _share_jump(runs: list[dict[str, np.ndarray]], at: int, window: int) -> float:
    e = np.stack([r["expert"] for r in runs]).astype(float)
    return float(e[:, at:at + window].mean() - e[:, max(0, at - window):at].mean())


@runner("online.navigation")
def navigation(params: dict[str, Any], budget: dict[str, Any], ctx: RunContext) -> RunResult:
    """MB, MF and the meta-controlled agents learning online (module docstring)."""
    from simlab.online.command import OnlineConfig, online

    settings = dict(params)
    # a budget may shorten the schedule with the run (change_at of a quick budget)
    settings.update({k: v for k, v in budget.items() if k not in ("seeds", "decisions")})
    model = settings.pop("model", "isir-synthetic")
    model_seed = int(settings.pop("model_seed", 0))
    notes = list(settings.pop("notes", []))
    m = model_mdp(model, model_seed, ctx.out)
    try:
        cfg = OnlineConfig.from_mapping({
            **settings, "mdp": m, "out": ctx.out / "online", "seeds": budget["seeds"],
            "decisions": budget.get("decisions", 3200), "seed": int(ctx.root_seed),
            "progress": ctx.progress})
    except ConfigError as exc:
        raise ConfigError(exc.problem, key=f"params.{exc.key}", fix=exc.fix) from None
    res = online(cfg, executor=ctx.executor)
    s = res.summary
    at = s["task"]["changes"][0]["at"] if s["task"]["changes"] else None
    metrics: dict[str, Any] = {"seeds": cfg.seeds, "decisions": cfg.decisions,
                               "states": m.n_states}
    for arm, a in s["arms"].items():
        metrics[f"{arm}_reward"] = a["reward"]["mean"]
        metrics[f"{arm}_reward_vs_mb"] = a.get("reward_vs_mb")
        metrics[f"{arm}_cost_vs_mb"] = a.get("cost_vs_mb")
        metrics[f"{arm}_mb_share"] = a["mb_share"]
        if at is not None:
            metrics[f"{arm}_reward_before"] = a["reward_before"]["mean"]
            metrics[f"{arm}_reward_after"] = a["reward_after"]["mean"]
            metrics[f"{arm}_recovery"] = a["recovery_decisions"]
            metrics[f"{arm}_mb_share_jump"] = _share_jump(res.logs[arm], at, cfg.window)
    notes.append(f"model {model} ({m.n_states} states, {m.n_actions} actions); "
                 f"{cfg.seeds} runs x {cfg.decisions} decisions per arm; change: "
                 f"{s['change'] or 'none'}; costs in value-iteration backups.")
    figures = [p for k, p in res.files.items() if k.endswith(".png")]
    return RunResult(metrics=metrics, figures=figures, notes=notes,
                     details={"arms": s["arms"], "task": s["task"]})
