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

from simlab.base.errors import ConfigError
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
    from simlab.base.actions import parse_action_set
    from simlab.base.io import atomic_write_text
    from simlab.data.counts import load_counts
    from simlab.data.estimate import empirical_mdp
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


def physics_run(mf_config: Any, mb_config: Any, criterion: str, kappa: float, arena: str,
                lattice: int, goal: tuple[int, ...], start_states: tuple[int, ...],
                decisions: int, change_at: int, new_goal: tuple[int, ...],
                box: tuple[float, float, float, float], seed: np.random.SeedSequence
                ) -> dict[str, np.ndarray]:
    """One physics run (a parallel job): its own world, an ``lattice x lattice`` grid of
    states over the arena, the goal change and the box at ``change_at``."""
    from discretize.voronoi import Discretizer
    from simlab.online.meta import make_meta_agent
    from simlab.online.physics import PhysicsChange, run_physics_online
    from simlab.physics.world import World

    with World(arena) as world:
        x0, y0, x1, y1 = world.arena.bounds
        gx = np.linspace(x0, x1, 2 * lattice + 1)[1::2]
        gy = np.linspace(y0, y1, 2 * lattice + 1)[1::2]
        disc = Discretizer(centres=np.array([(x, y) for y in gy[::-1] for x in gx]))
        agent = make_meta_agent(mf_config, mb_config, disc.n_states, 16, criterion=criterion,
                                kappa=kappa)
        rngs = [np.random.default_rng(s) for s in seed.spawn(3)]
        changes = (PhysicsChange(change_at, "goal", goal=new_goal),
                   PhysicsChange(change_at + 1, "box", box=box))
        run = run_physics_online(agent, world, disc, goal=goal, start_states=start_states,
                                 decisions=decisions, changes=changes, env_rng=rngs[0],
                                 agent_rng=rngs[1], noise_rng=rngs[2])
    cols = run.log.columns()
    cols["blocked"] = run.blocked
    cols["robot_seconds"] = np.array([run.robot_seconds])
    return cols


@runner("online.physics")
def physics(params: dict[str, Any], budget: dict[str, Any], ctx: RunContext) -> RunResult:
    """The same agents learning online in physics on the table (goal change and a box added
    at ``change_at``), then on the empirical MDP estimated from the transitions those
    physics runs made before the change (the MDP of that arena as the agents saw it).

    Metrics per arm ``A``: ``A_physics_reward`` / ``A_physics_reward_after``,
    ``A_physics_mb_share``, ``A_physics_cost_vs_mb``; ``A_mdp_reward`` / ``A_mdp_reward_after``
    on the estimated MDP; ``blocked_before`` / ``blocked_after`` (share of blocked primitives
    over all runs: the box is seen).
    """
    from simlab.data.estimate import empirical_mdp
    from simlab.data.mdp import mdp_from_arrays
    from simlab.online.command import OnlineConfig, arm_names, online

    p = dict(params)
    n, decisions = int(budget["seeds"]), int(budget["decisions"])
    change_at = int(budget.get("change_at", p.get("change_at", decisions // 2)))
    criteria = tuple(p.get("criteria", ("mb", "mf", "entropy_and_cost")))
    kappas = tuple(float(k) for k in p.get("kappas", (1.0,)))
    common = {"goal": tuple(p.get("goal", (12,))), "start_states": tuple(p.get("start_states",
                                                                               (0, 24)))}
    cfg0 = OnlineConfig(mdp="unused", criteria=criteria, kappas=kappas, **common)
    mf, mb = cfg0.expert_configs()
    arms = arm_names(criteria, kappas)
    seeds = ctx.seeds(n)
    jobs = [dict(mf_config=mf, mb_config=mb, criterion=c, kappa=k,
                 arena=str(p.get("arena", "table")), lattice=int(p.get("lattice", 5)),
                 decisions=decisions, change_at=change_at,
                 new_goal=tuple(p.get("new_goal", (2,))),
                 box=tuple(float(v) for v in p.get("box", (0.0, 0.15, 0.6, 0.05))),
                 seed=seeds[i], **common)
            for _, c, k in arms for i in range(n)]
    results = ctx.map(physics_run, jobs, desc="online physics")
    metrics: dict[str, Any] = {"seeds": n, "decisions": decisions}
    S = int(max(max(r["s"].max(), r["s_next"].max()) for r in results)) + 1
    S = max(S, int(p.get("lattice", 5)) ** 2)
    counts = np.zeros((S, 16, S), dtype=np.int64)
    blocked_b, blocked_a = [], []
    mb_backups = None
    for j, (name, _, _) in enumerate(arms):
        runs = results[j * n:(j + 1) * n]
        r = np.stack([x["reward"] for x in runs])
        metrics[f"{name}_physics_reward"] = float(r.sum(1).mean())
        metrics[f"{name}_physics_reward_after"] = float(r[:, change_at:].sum(1).mean())
        metrics[f"{name}_physics_mb_share"] = float(np.mean([x["expert"].mean() for x in runs]))
        b = float(np.mean([x["backups"].sum() for x in runs]))
        if name == "mb":
            mb_backups = b
        metrics[f"{name}_physics_backups"] = b
        for x in runs:
            np.add.at(counts, (x["s"][:change_at], x["a"][:change_at],
                               x["s_next"][:change_at]), 1)
            blocked_b.append(x["blocked"][:change_at].mean())
            blocked_a.append(x["blocked"][change_at:].mean())
    if mb_backups:
        for name, _, _ in arms:
            metrics[f"{name}_physics_cost_vs_mb"] = metrics[f"{name}_physics_backups"] / mb_backups
    metrics["blocked_before"] = float(np.mean(blocked_b))
    metrics["blocked_after"] = float(np.mean(blocked_a))
    cm = empirical_mdp(counts)
    m = mdp_from_arrays(cm.T, counts=cm.counts, visited=cm.visited, entropy=cm.entropy,
                        unvisited="self-loop")
    cfg = OnlineConfig(mdp=m, out=ctx.out / "mdp", criteria=criteria, kappas=kappas,
                       seeds=n, decisions=decisions, change="goal", change_at=change_at,
                       new_goal=tuple(p.get("new_goal", (2,))), seed=int(ctx.root_seed),
                       progress=ctx.progress, **common)
    res = online(cfg, executor=ctx.executor)
    for name, a in res.summary["arms"].items():
        metrics[f"{name}_mdp_reward"] = a["reward"]["mean"]
        metrics[f"{name}_mdp_reward_after"] = a["reward_after"]["mean"]
    notes = [f"{n} physics runs x {decisions} decisions per arm on the {p.get('arena', 'table')} "
             f"arena ({S} lattice states, 16 primitives, truth pose); at decision {change_at} "
             "the goal moves and a box is added (the MDP runs have the goal change only: the "
             "box is in no transition estimated before it).",
             "The MDP is estimated from the physics transitions before the change (all arms "
             "and runs), unvisited pairs as self-loops."]
    return RunResult(metrics=metrics, figures=[pth for k, pth in res.files.items()
                                               if k.endswith(".png")], notes=notes)
