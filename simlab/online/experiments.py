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
from dataclasses import dataclass
from typing import Any

import numpy as np

from simlab.base.errors import ConfigError
from simlab.experiments.context import RunContext, RunResult
from simlab.experiments.registry import runner

__all__ = ["PhysicsArm", "lab_map_arena", "lattice_states", "model_mdp", "navigation",
           "physics", "physics_run", "random_walk_mdp"]

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


# ----------------------------------------------------------------------------- physics
@dataclass(frozen=True)
class PhysicsArm:
    """One physics job's settings (they travel together to the worker): the experts'
    agent configs, the :class:`~simlab.online.meta.Arbitration`, the ``arena`` (built-in
    name or TOML path), ``lattice`` (states: a ``lattice x lattice`` grid of centres over
    the arena) and the :class:`~simlab.online.physics.PhysicsTask`."""

    mf_config: Any
    mb_config: Any
    arbitration: Any
    arena: str
    lattice: int
    task: Any


def lattice_states(arena: Any, lattice: int) -> Any:
    """A :class:`~discretize.voronoi.Discretizer` of ``lattice x lattice`` centres evenly
    over ``arena.bounds`` (state 0 top left, row-major, y decreasing)."""
    from discretize.voronoi import Discretizer

    x0, y0, x1, y1 = arena.bounds
    gx = np.linspace(x0, x1, 2 * lattice + 1)[1::2]
    gy = np.linspace(y0, y1, 2 * lattice + 1)[1::2]
    return Discretizer(centres=np.array([(x, y) for y in gy[::-1] for x in gx]))


def physics_run(arm: PhysicsArm, seed: np.random.SeedSequence) -> dict[str, np.ndarray]:
    """One physics run (a parallel job): its own world and states, the arm's task."""
    from simlab.online.physics import PhysicsLab, RunStreams, run_physics_online
    from simlab.physics.arena import load_arena
    from simlab.physics.motion import PrimitiveParams

    arena = load_arena(arm.arena)
    lab = PhysicsLab(arena, lattice_states(arena, arm.lattice), PrimitiveParams())
    agent = arm.arbitration.agent(arm.mf_config, arm.mb_config, lab.n_states, lab.n_actions)
    run = run_physics_online(agent, lab, arm.task, RunStreams.from_seed(seed))
    cols = run.columns()
    cols["robot_seconds"] = np.array([run.robot_seconds])
    return cols


def random_walk_mdp(arena: Any, lattice: int, transitions: int, seed: int, folder: Any) -> Any:
    """The empirical MDP of ``arena`` on its lattice states, estimated from a random-walk
    ``simlab collect`` of ``transitions`` transitions (a walk from every state's centre,
    truth poses) written to ``folder`` (the arena's MDP as ``simlab estimate`` makes it
    from any dataset: unvisited pairs as self-loops)."""
    from simlab.data.collect import CollectConfig, collect
    from simlab.data.estimate import EstimateConfig, estimate
    from simlab.data.mdp import load_mdp
    from simlab.physics.arena import load_arena

    cfg_arena = load_arena(arena)
    disc = lattice_states(cfg_arena, lattice)
    collect(CollectConfig(arena=cfg_arena, states=disc, out=folder / "walk",
                          transitions=int(transitions), start_states="all", seed=int(seed),
                          progress=False))
    estimate(EstimateConfig(dataset=folder / "walk", out=folder / "mdp.npz", states=disc,
                            unvisited="self-loop", plot=False))
    return load_mdp(folder / "mdp.npz")


def lab_map_arena(folder: Any) -> Any:
    """A map-built arena (``simlab arena-from-map``) of a small two-room lab written into
    ``folder``: a 3 x 2 m room (0.05 m pixels, x and y from 0) split by a 0.1 m wall at
    x = 1.15-1.25 m with two gaps, y < 0.5 m and y > 1.5 m (between the columns of the
    5 x 5 lattice's centres); returns the arena TOML's path. A box across the top gap
    leaves the bottom one: the detour of a closed passage."""
    from discretize.gridmap import OccupancyMap
    from discretize.mapio import write_map
    from simlab.physics.map_arena import ArenaFromMapConfig, arena_from_map

    res = 0.05
    occ = np.full((48, 68), 100, dtype=np.int8)  # 0.1 m of wall round the room
    occ[4:44, 4:64] = 0
    occ[14:34, 27:29] = 100  # rows from the top: y 1.5-0.5 m; columns x 1.15-1.25 m
    write_map(folder / "lab.yaml", OccupancyMap(occ, res, (-0.2, -0.2, 0.0)), overwrite=True)
    return arena_from_map(ArenaFromMapConfig(map_yaml=folder / "lab.yaml",
                                             out=folder / "lab.toml", overwrite=True))


def _physics_arms(p: dict[str, Any], n: int, decisions: int, change_at: int, arena: str
                  ) -> tuple[list[tuple[str, str, float]], list[PhysicsArm]]:
    from simlab.online.command import OnlineConfig, arm_names
    from simlab.online.physics import PhysicsChange, PhysicsTask

    criteria = tuple(p.get("criteria", ("mb", "mf", "entropy_and_cost")))
    kappas = tuple(float(k) for k in p.get("kappas", (1.0,)))
    cfg0 = OnlineConfig(mdp="unused", criteria=criteria, kappas=kappas)
    mf, mb = cfg0.expert_configs()
    box = tuple(float(v) for v in p.get("box", (0.0, 0.15, 0.6, 0.05)))
    changes = (PhysicsChange(change_at, "goal", goal=tuple(p.get("new_goal", (2,)))),
               PhysicsChange(change_at + 1, "box", box=box))
    task = PhysicsTask(tuple(p.get("goal", (12,))), tuple(p.get("start_states", (0, 24))),
                       decisions, changes, pose_source=str(p.get("pose_source", "truth")),
                       mcl_map=str(p.get("mcl_map", "updated")))
    arms = arm_names(criteria, kappas)
    return arms, [PhysicsArm(mf, mb, cfg0.arbitration(c, k), arena, int(p.get("lattice", 5)),
                             task) for _, c, k in arms]


def _physics_metrics(arms: list[tuple[str, str, float]], results: list[dict[str, np.ndarray]],
                     n: int, change_at: int) -> dict[str, Any]:
    metrics: dict[str, Any] = {}
    blocked_b, blocked_a = [], []
    for j, (name, _, _) in enumerate(arms):
        runs = results[j * n:(j + 1) * n]
        r = np.stack([x["reward"] for x in runs])
        metrics[f"{name}_physics_reward"] = float(r.sum(1).mean())
        metrics[f"{name}_physics_reward_after"] = float(r[:, change_at:].sum(1).mean())
        metrics[f"{name}_physics_mb_share"] = float(np.mean([x["expert"].mean() for x in runs]))
        metrics[f"{name}_physics_backups"] = float(np.mean([x["backups"].sum() for x in runs]))
        blocked_b += [x["blocked"][:change_at].mean() for x in runs]
        blocked_a += [x["blocked"][change_at:].mean() for x in runs]
    mb = metrics.get("mb_physics_backups")
    for name, _, _ in arms:
        if mb:
            metrics[f"{name}_physics_cost_vs_mb"] = metrics[f"{name}_physics_backups"] / mb
    metrics["blocked_before"] = float(np.mean(blocked_b))
    metrics["blocked_after"] = float(np.mean(blocked_a))
    return metrics


@runner("online.physics")
def physics(params: dict[str, Any], budget: dict[str, Any], ctx: RunContext) -> RunResult:
    """The same agents learning online in physics (goal change and a box added at
    ``change_at``) on the table or on a map-built arena (``arena = "lab-map"``: the
    two-room lab of :func:`lab_map_arena`), then on the empirical MDP of that arena
    estimated from a random-walk collection (:func:`random_walk_mdp`, budget
    ``mdp_transitions``), with the goal change.

    Metrics per arm ``A``: ``A_physics_reward`` / ``A_physics_reward_after``,
    ``A_physics_mb_share``, ``A_physics_cost_vs_mb``; ``A_mdp_reward`` / ``A_mdp_reward_after``
    on the estimated MDP; ``blocked_before`` / ``blocked_after`` (share of blocked primitives
    over all runs: the box is seen); ``mdp_states_visited`` of the walk.
    """
    from simlab.online.command import OnlineConfig, online

    p = dict(params)
    n, decisions = int(budget["seeds"]), int(budget["decisions"])
    change_at = int(budget.get("change_at", p.get("change_at", decisions // 2)))
    arena = str(p.get("arena", "table"))
    if arena == "lab-map":
        arena = str(lab_map_arena(ctx.out))
    arms, jobs = _physics_arms(p, n, decisions, change_at, arena)
    seeds = ctx.seeds(n)
    results = ctx.map(physics_run, [dict(arm=arm, seed=seeds[i]) for arm in jobs
                                    for i in range(n)], desc="online physics")
    metrics: dict[str, Any] = {"seeds": n, "decisions": decisions,
                               **_physics_metrics(arms, results, n, change_at)}
    walk = int(budget.get("mdp_transitions", p.get("mdp_transitions", 2000)))
    m = random_walk_mdp(arena, jobs[0].lattice, walk, int(ctx.root_seed), ctx.out)
    metrics["mdp_states_visited"] = int(np.asarray(m.visited).any(axis=1).sum())
    task = jobs[0].task
    cfg = OnlineConfig(mdp=m, out=ctx.out / "mdp", criteria=tuple(p.get(
        "criteria", ("mb", "mf", "entropy_and_cost"))), kappas=tuple(float(k) for k in p.get(
            "kappas", (1.0,))), seeds=n, decisions=decisions, change="goal",
        change_at=change_at, goal=task.goal, start_states=task.start_states,
        new_goal=task.changes[0].goal, seed=int(ctx.root_seed), progress=ctx.progress)
    res = online(cfg, executor=ctx.executor)
    for name, a in res.summary["arms"].items():
        metrics[f"{name}_mdp_reward"] = a["reward"]["mean"]
        metrics[f"{name}_mdp_reward_after"] = a["reward_after"]["mean"]
    notes = [f"{n} physics runs x {decisions} decisions per arm on the {p.get('arena', 'table')}"
             f" arena ({m.n_states} lattice states, 16 primitives, {task.pose_source} pose); at "
             f"decision {change_at} the goal moves and a box is added (the MDP runs have the "
             "goal change only: the box is in no transition of the walk).",
             f"The MDP is estimated from a {walk}-transition random walk of the same arena "
             "(simlab collect from every state's centre, simlab estimate, unvisited pairs as "
             "self-loops), not from the agents' own transitions."]
    return RunResult(metrics=metrics, figures=[pth for k, pth in res.files.items()
                                               if k.endswith(".png")], notes=notes)


# The twin experiment's runner lives in its own module; importing it registers it.
from simlab.online import twin as _twin  # noqa: E402, F401
