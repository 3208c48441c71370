"""The lab's own experiment in its twin: the published online protocol on the real model and
in physics in the lab's calibrated twin, arm by arm.

Runner ``online.twin`` (``experiments/online_isir_twin.toml``):

1. **The lab.** A folder laid out as the ISIR arena's public data (Dromnelle et al. 2022;
   ``realisticNavWorld.json`` the robot's transition model as counts, the after-change
   models ``realisticNavWorld_newGoal.json`` / ``_noTrans20-21.json`` /
   ``_noTrans6-7.json``, ``mymap.yaml`` its GMapping map stored bottom row first,
   ``voronoiCenters_exp.dat`` the state centres, ``keyStates.txt`` the protocol) goes
   through the README's "your own lab" steps: ``discretize --flip-y``, ``arena-from-map
   --flip-y``, ``estimate --counts`` (8 actions counter-clockwise from East). When the
   folder is absent the *stand-in lab* is used instead: the 38-state layout of
   :mod:`simlab.online.synthetic` built as a map (0.7 m cells, the published state ids at
   the protocol's places) with its synthetic count model as the "real" robot.
2. **The twin.** ``twin = "calibrate"`` runs ``simlab calibrate`` against the real counts
   with its defaults (a budget may set ``calibrate_hours_per_candidate`` /
   ``calibrate_candidates``; its transfer report is skipped: the experiment is the
   transfer); a path takes a ``primitives.toml`` an earlier calibration wrote.
3. **The tasks**, each on the real model and in physics in the twin, with the same arms,
   seeds and protocol: ``stable`` (goal 18 throughout), ``goal`` (18 -> 34 at the change)
   and ``passages`` (the published after-change models on the real model). In the twin a
   passage closes as the published files close it (``closing = "remove"``, the default):
   its transitions are removed, a move across it taken back and drawn again
   (:mod:`simlab.online.physics`), since the real model's after-change world is the same
   model with those transitions removed and its rows renormalised, not a lab with a box
   in it; ``closing = "box"`` puts a box on the doorway instead (the physical closing,
   whose blocked and deflected moves the real files do not have; on the ISIR lab, root seed
   0, the two give the same order of the arms and rewards within a run's spread).

Metrics per task ``T`` and arm ``A``: ``T_A_real`` / ``T_A_twin`` total reward (mean over
runs) and ``T_A_twin_vs_real`` their ratio; with a change ``T_A_real_after`` /
``T_A_twin_after``; ``T_rank_agrees`` 1 when the twin orders every pair of arms that the real
model's runs separate (Welch's test at 5 %, on the post-change totals, or the totals for
``stable``) as the real model does, else 0, judged within each outcome of the change (the
passage that closed; :func:`outcome_order`), with ``T_rank_pairs_judged`` the pairs so
separated and ``T_rank_pairs_wrong`` how many of them the twin orders the other way (named
in the notes); ``T_rank_pooled_agrees`` / ``T_rank_pooled_pairs_judged`` the same check on
the totals pooled over the outcomes (:func:`order_disagreements`);
``T_outcome_split_differs`` the arms whose runs fall in the outcomes in other proportions in
the twin (:func:`outcome_split_differs`); ``T_rank_same`` 1 when the twin's mean rewards
give exactly the real model's order, pairs within noise included; ``T_twin_blocked`` the
share of blocked primitives in the twin.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base.errors import ConfigError
from simlab.experiments.context import RunContext, RunResult
from simlab.experiments.registry import runner

__all__ = ["TASKS", "LabFiles", "order_disagreements", "outcome_order", "outcome_split_differs",
           "real_lab", "stand_in_lab", "twin"]

TASKS = ("stable", "goal", "passages")
#: The ISIR arena's public files (module docstring).
MODEL = "realisticNavWorld.json"
AFTER = {"goal": ("realisticNavWorld_newGoal.json",),
         "passages": ("realisticNavWorld_noTrans20-21.json", "realisticNavWorld_noTrans6-7.json")}
#: The stand-in lab's cell side (m): the ISIR centres are about 0.7 m apart.
CELL = 0.7


@dataclass(frozen=True)
class LabFiles:
    """A lab ready for the experiment: ``name``, its ``states`` file, ``arena`` TOML, the
    real ``model`` (counts, ISIR JSON), the after-change models per task (``after``), the
    protocol's ``goal``, ``start_states``, ``new_goal``, ``passages`` (with the state
    counting the use of each: published 19 towards 20-21, 7 towards 6-7) and ``change_at``
    (0-based), and ``real_hours`` of robot time behind the model."""

    name: str
    states: Path
    arena: Path
    model: Path
    after: dict[str, tuple[Path, ...]] = field(default_factory=dict)
    goal: tuple[int, ...] = (18,)
    start_states: tuple[int, ...] = (0, 32)
    new_goal: tuple[int, ...] = (34,)
    passages: tuple[str, ...] = ("20-21", "6-7")
    use_states: tuple[int, ...] = (19, 7)
    change_at: int = 1600
    real_hours: float = 13.0


def _key_states(path: Path) -> dict[str, Any]:
    """The protocol of a ``keyStates.txt`` (``init``, ``goal``, ``new_goal``, ``del_trans``
    lines): starts, goal, new goal, the passages and the (1-based) change decision."""
    out: dict[str, Any] = {}
    for line in path.read_text().splitlines():
        words = line.split()
        if not words or words[0].startswith("#"):
            continue
        if words[0] == "init":
            out["start_states"] = tuple(int(w) for w in words[1:])
        elif words[0] == "goal":
            out["goal"] = (int(words[1]),)
        elif words[0] == "new_goal":
            out["change_at"] = int(words[1]) - 1
            out["new_goal"] = (int(words[2]),)
        elif words[0] == "del_trans":
            out["change_at"] = int(words[1]) - 1
            out["passages"] = tuple(words[2:])
    return out


def real_lab(folder: Path, out: Path) -> LabFiles:
    """The lab of a folder of the ISIR layout (module docstring), states and arena written
    into ``out`` through simlab's own commands."""
    from discretize.command import DiscretizeConfig, discretize_command
    from simlab.physics.map_arena import ArenaFromMapConfig, arena_from_map

    folder = Path(folder)
    missing = [n for n in (MODEL, "mymap.yaml", "voronoiCenters_exp.dat")
               if not (folder / n).is_file()]
    if missing:
        raise ConfigError(f"not a lab folder: {', '.join(missing)} missing", path=folder,
                          key="params.lab", fix="give the folder of the lab's public data")
    out.mkdir(parents=True, exist_ok=True)
    discretize_command(DiscretizeConfig(map=folder / "mymap.yaml", out=out / "states.json",
                                        centres=folder / "voronoiCenters_exp.dat", flip_y=True,
                                        png=None))
    arena_from_map(ArenaFromMapConfig(map_yaml=folder / "mymap.yaml", out=out / "lab.toml",
                                      states=out / "states.json", flip_y=True))
    protocol = _key_states(folder / "keyStates.txt") if (folder / "keyStates.txt").is_file() \
        else {}
    after = {k: tuple(folder / n for n in names) for k, names in AFTER.items()
             if all((folder / n).is_file() for n in names)}
    return LabFiles(name=f"ISIR arena ({folder})", states=out / "states.json",
                    arena=out / "lab.toml", model=folder / MODEL, after=after, **protocol)


def stand_in_lab(out: Path, seed: int) -> LabFiles:
    """The stand-in lab (module docstring): map, states, arena and synthetic counts in
    ``out``."""
    import json

    from discretize.gridmap import OccupancyMap
    from discretize.mapio import write_map
    from discretize.voronoi import Discretizer
    from simlab.base.io import atomic_write_text
    from simlab.online.synthetic import LAYOUT, corridor_counts, corridor_positions, isir_document
    from simlab.physics.map_arena import ArenaFromMapConfig, arena_from_map

    out.mkdir(parents=True, exist_ok=True)
    res, px, border = 0.05, round(CELL / 0.05), 2
    rows, cols = len(LAYOUT), len(LAYOUT[0])
    occ = np.full((rows * px + 2 * border, cols * px + 2 * border), 100, dtype=np.int8)
    for y, row in enumerate(LAYOUT):
        for x, c in enumerate(row):
            if c == ".":
                occ[border + y * px:border + (y + 1) * px, border + x * px:border + (x + 1) * px] = 0
    write_map(out / "map.yaml", OccupancyMap(occ, res, (0.0, 0.0, 0.0)), overwrite=True)
    xy = corridor_positions().astype(float)
    h = occ.shape[0] * res
    centres = np.column_stack([border * res + (xy[:, 0] + 0.5) * CELL,
                               h - border * res - (xy[:, 1] + 0.5) * CELL])
    Discretizer(centres=centres, method="file").save(out / "states.json")
    arena_from_map(ArenaFromMapConfig(map_yaml=out / "map.yaml", out=out / "lab.toml",
                                      states=out / "states.json", overwrite=True))
    counts = corridor_counts(np.random.default_rng(seed))
    atomic_write_text(out / MODEL, json.dumps(isir_document(
        counts, note="synthetic stand-in (simlab.online.synthetic)")))
    # the passages' counting states: the doors' own cells on the start side
    return LabFiles(name="stand-in lab (simlab.online.synthetic)", states=out / "states.json",
                    arena=out / "lab.toml", model=out / MODEL, use_states=(20, 6))


def _mdp(model: Path, out: Path) -> Path:
    from simlab.data.estimate import EstimateConfig, estimate

    estimate(EstimateConfig(counts=model, n_actions=8, convention="ccw-east", out=out,
                            plot=False))
    return out


def _twin_primitives(p: dict[str, Any], budget: dict[str, Any], lab: LabFiles,
                     ctx: RunContext) -> Path:
    twin = str(budget.get("twin", p.get("twin", "calibrate")))
    if twin == "uncalibrated":  # a smoke run: the twin's mode with simlab's defaults
        from simlab.base.io import atomic_write_text
        from simlab.physics.motion import PrimitiveParams

        path = ctx.out / "uncalibrated.toml"
        atomic_write_text(path, PrimitiveParams(mode="until_state_change").toml_text())
        return path
    if twin != "calibrate":
        path = Path(twin)
        if not path.is_file():
            raise ConfigError("no such primitives file", path=path, key="params.twin",
                              fix='give the primitives.toml of simlab calibrate, or "calibrate"')
        return path
    from simlab.calibration.command import CalibrateConfig, calibrate_command

    out = ctx.out / "calibration"
    calibrate_command(CalibrateConfig(
        real=lab.model, n_actions=8, convention="ccw-east", speed="fast",
        real_hours=lab.real_hours, states=lab.states, arena=lab.arena, out=out,
        hours_per_candidate=budget.get("calibrate_hours_per_candidate"),
        candidates=int(budget.get("calibrate_candidates", CalibrateConfig.candidates)),
        transfer_seeds=int(budget.get("calibrate_transfer_seeds", 0)),
        seed=int(ctx.root_seed), progress=ctx.progress))
    return out / "primitives.toml"


def _task_options(task: str, lab: LabFiles, *, real: bool, mdps: dict[str, Any],
                  closing: str | None = None) -> dict[str, Any]:
    """The ``simlab online`` options of one task on the real model (``real``) or in the
    twin. On the real model a change swaps in the lab's after-change models when it has
    them (the published protocol: the goal's model, or one model per passage of which the
    more used passage's happens, counted by decisions in ``use_states``); in the twin the
    goal moves, or the more used passage closes by ``closing`` (module docstring)."""
    opts: dict[str, Any] = {"change_at": lab.change_at}
    if task == "goal":
        opts.update(change="goal", new_goal=list(lab.new_goal))
        if real and "goal" in mdps:
            opts["after"] = [str(mdps["goal"][0])]
    elif task == "passages":
        opts.update(use_states=list(lab.use_states))
        if real and "passages" in mdps:
            opts.update(change="model", after=[str(p) for p in mdps["passages"]])
        else:
            opts.update(change="passages", passages=list(lab.passages))
            if closing is not None:
                opts["closing"] = closing
    return opts


def order_disagreements(real: dict[str, np.ndarray], twin: dict[str, np.ndarray], *,
                        alpha: float = 0.05) -> tuple[int, list[tuple[str, str]]]:
    """The pairs of arms the twin orders against the real model, judged where the runs can
    tell: a pair is judged when the real model's per-run totals separate its two arms
    (Welch's t-test, two-sided, ``p < alpha``; ``scipy.stats.ttest_ind``), and it disagrees
    when the twin's mean totals order the two the other way. Pairs the real model's runs
    cannot order are not judged, since with a handful of runs their exact order is a coin
    flip on the real model itself. Returns (pairs judged, pairs that disagree)."""
    from scipy.stats import ttest_ind

    arms = list(real)
    judged, wrong = 0, []
    for i, a in enumerate(arms):
        for b in arms[i + 1:]:
            ra, rb = np.asarray(real[a], float), np.asarray(real[b], float)
            if min(ra.size, rb.size) < 2 or np.ptp(np.r_[ra, rb]) == 0:
                continue
            if not ttest_ind(ra, rb, equal_var=False).pvalue < alpha:
                continue
            judged += 1
            d_twin = float(np.mean(twin[a]) - np.mean(twin[b]))
            if np.sign(d_twin) != np.sign(ra.mean() - rb.mean()):
                wrong.append((a, b))
    return judged, wrong


def _totals(logs: dict[str, list[dict[str, np.ndarray]]], at: int | None
            ) -> dict[str, np.ndarray]:
    """Per arm, each run's total reward (after the change, when there is one): the same
    sums as the summary's ``reward`` / ``reward_after`` means are taken over."""
    return {arm: np.stack([r["reward"] for r in runs]).astype(np.float64)[:, at or 0:].sum(1)
            for arm, runs in logs.items()}


def _outcomes(logs: dict[str, list[dict[str, np.ndarray]]], at: int | None
              ) -> dict[str, np.ndarray]:
    """Per arm, each run's outcome of the change: its phase at the change's decision (the
    alternative chosen by use, e.g. which passage closed; 0 for every run without one)."""
    return {arm: np.array([int(r["phase"][at]) if at is not None else 0 for r in runs])
            for arm, runs in logs.items()}


def outcome_order(real: dict[str, np.ndarray], twin: dict[str, np.ndarray],
                  real_outcome: dict[str, np.ndarray], twin_outcome: dict[str, np.ndarray],
                  *, alpha: float = 0.05) -> tuple[int, list[tuple[int, str, str]]]:
    """:func:`order_disagreements` within each outcome of the change: the runs of each arm
    that ended in outcome ``k`` (``*_outcome``, e.g. the passage that closed) on the real
    model against those that ended in it in the twin. A pair is judged in ``k`` when the
    real model's runs there separate it and the twin has runs of both arms there.

    Decision: where a change has alternatives chosen by use (the published closed
    passage: the more used of two), a run's reward after the change depends first on which
    one happened (the ISIR lab's real model, published protocol, root seed 0, MF: 24-56
    after the 20-21 passage closes against 92-126 after 6-7 closes), and which one happens
    is a draw of the runs before it (there 4 of 10 MF runs closed 6-7, 6 of 10 in the twin:
    Fisher's test cannot tell the two apart). Pooled, the arms' mean totals then order by
    how many runs each drew of the easy alternative, which says little of the twin; within
    an outcome the arms meet the same changed world. Returns (pairs judged, (outcome, arm, arm) the twin
    orders the other way)."""
    judged, wrong = 0, []
    for k in sorted({int(x) for v in real_outcome.values() for x in v}):
        present = [a for a in real if np.any(twin_outcome[a] == k)]
        n, bad = order_disagreements({a: real[a][real_outcome[a] == k] for a in present},
                                     {a: twin[a][twin_outcome[a] == k] for a in present},
                                     alpha=alpha)
        judged += n
        wrong += [(k, a, b) for a, b in bad]
    return judged, wrong


def outcome_split_differs(real_outcome: dict[str, np.ndarray],
                          twin_outcome: dict[str, np.ndarray], *, alpha: float = 0.05
                          ) -> list[str]:
    """The arms whose runs end in the change's outcomes in other proportions in the twin
    than on the real model (Fisher's exact test with two outcomes, the chi-squared test of
    the 2 x K table with more; ``scipy.stats``), at ``alpha``."""
    from scipy.stats import chi2_contingency, fisher_exact

    out = []
    for arm in real_outcome:
        ks = sorted({int(x) for x in np.r_[real_outcome[arm], twin_outcome[arm]]})
        if len(ks) < 2:
            continue
        table = np.array([[int(np.sum(o[arm] == k)) for k in ks]
                          for o in (real_outcome, twin_outcome)])
        p = (fisher_exact(table).pvalue if len(ks) == 2
             else chi2_contingency(table).pvalue)
        if p < alpha:
            out.append(arm)
    return out


def _arm_metrics(task: str, real: dict[str, Any], sim: dict[str, Any],
                 real_logs: dict[str, Any], sim_logs: dict[str, Any], change_at: int | None
                 ) -> tuple[dict[str, Any], str]:
    """The task's metrics (module docstring) and a note naming the pairs judged wrong."""
    m: dict[str, Any] = {}
    for arm, r in real["arms"].items():
        t = sim["arms"][arm]
        m[f"{task}_{arm}_real"] = r["reward"]["mean"]
        m[f"{task}_{arm}_twin"] = t["reward"]["mean"]
        m[f"{task}_{arm}_twin_vs_real"] = (t["reward"]["mean"] / r["reward"]["mean"]
                                           if r["reward"]["mean"] > 0 else None)
        if change_at is not None:
            m[f"{task}_{arm}_real_after"] = r["reward_after"]["mean"]
            m[f"{task}_{arm}_twin_after"] = t["reward_after"]["mean"]
    totals_real, totals_twin = _totals(real_logs, change_at), _totals(sim_logs, change_at)
    out_real, out_twin = _outcomes(real_logs, change_at), _outcomes(sim_logs, change_at)
    judged, wrong = outcome_order(totals_real, totals_twin, out_real, out_twin)
    m[f"{task}_rank_agrees"] = float(not wrong)
    m[f"{task}_rank_pairs_judged"] = judged
    m[f"{task}_rank_pairs_wrong"] = len(wrong)
    pooled_judged, pooled_wrong = order_disagreements(totals_real, totals_twin)
    m[f"{task}_rank_pooled_agrees"] = float(not pooled_wrong)
    m[f"{task}_rank_pooled_pairs_judged"] = pooled_judged
    split = outcome_split_differs(out_real, out_twin)
    m[f"{task}_outcome_split_differs"] = len(split)
    order_real = [totals_real[arm].mean() for arm in real["arms"]]
    order_twin = [totals_twin[arm].mean() for arm in real["arms"]]
    m[f"{task}_rank_same"] = float(np.array_equal(np.argsort(order_real, kind="stable"),
                                                  np.argsort(order_twin, kind="stable")))
    m[f"{task}_twin_blocked"] = float(np.mean([a["blocked"] for a in
                                               sim["physics"]["arms"].values()]))
    outcomes = sorted({int(x) for v in out_real.values() for x in v})
    by = " within the change's outcomes" if len(outcomes) > 1 else ""
    note = (f"{task}: the real model's runs separate {judged} pair(s) of arms{by}; the twin "
            + (f"orders {', '.join(f'{a} / {b} (outcome {k})' for k, a, b in wrong)} the "
               "other way." if wrong else "orders them all as the real model does."))
    if len(outcomes) > 1 or any(x not in outcomes for v in out_twin.values() for x in v):
        shares = "; ".join(
            f"{arm} {_split(out_real[arm])} real, {_split(out_twin[arm])} twin"
            for arm in out_real)
        note += (f" Runs per outcome (phase: runs): {shares}"
                 + (f"; the split differs (5 %) for {', '.join(split)}." if split else
                    "; no arm's split differs at 5 %.")
                 + f" Pooled over the outcomes, {pooled_judged} pair(s) are separated and "
                 + (f"{len(pooled_wrong)} ordered the other way." if pooled_wrong
                    else "all ordered as the real model does."))
    return m, note


def _split(outcome: np.ndarray) -> str:
    ks, n = np.unique(outcome, return_counts=True)
    return "/".join(f"{k}: {c}" for k, c in zip(ks, n, strict=True))


def _comparison_figure(rows: list[dict[str, Any]], path: Path) -> Path:
    """Grouped bars: each arm's reward on the real model and in the twin, per task."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    fig = Figure(figsize=(3.2 * len(rows), 3.6), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(rows), sharey=True))
    for ax, row in zip(axes, rows, strict=True):
        arms = list(row["real"]["arms"])
        x = np.arange(len(arms))
        for k, (side, colour) in enumerate((("real", "tab:blue"), ("twin", "tab:orange"))):
            arms_rec = row[side]["arms"]
            ax.bar(x + (k - 0.5) * 0.38, [arms_rec[a]["reward"]["mean"] for a in arms], 0.38,
                   yerr=[arms_rec[a]["reward"]["std"] for a in arms], color=colour,
                   label="real model" if side == "real" else "twin (physics)", capsize=2)
            if row["real"]["change"]:
                ax.scatter(x + (k - 0.5) * 0.38, [arms_rec[a]["reward_after"]["mean"]
                                                  for a in arms], color="k", marker="_", s=200,
                           zorder=3, label="after the change" if k == 0 else None)
        ax.set_xticks(x, [a.replace("entropy_and_cost_", "e&c ") for a in arms], fontsize=8)
        ax.set_title(row["task"], fontsize=10)
    axes[0].set_ylabel("total reward per run")
    axes[0].legend(fontsize=7)
    fig.savefig(path, dpi=90)
    return path


def _curves_figure(rows: list[dict[str, Any]], path: Path) -> Path:
    """Per task, each arm's mean cumulative reward on the real model (solid) and in the twin
    (dashed), the change marked."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    fig = Figure(figsize=(3.6 * len(rows), 3.4), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(rows), sharey=True))
    for ax, row in zip(axes, rows, strict=True):
        for k, arm in enumerate(row["real_logs"]):
            colour = f"C{k}"
            for side, style in (("real_logs", "-"), ("twin_logs", "--")):
                y = np.cumsum(np.stack([r["reward"] for r in row[side][arm]]), axis=1).mean(0)
                ax.plot(np.arange(1, y.size + 1), y, style, color=colour,
                        label=arm if side == "real_logs" else None)
        changes = row["real"]["task"]["changes"]
        if changes:
            ax.axvline(changes[0]["at"], color="k", lw=1, ls=":")
        ax.set_title(f"{row['task']} (solid: real model, dashed: twin)", fontsize=9)
        ax.set_xlabel("decision")
    axes[0].set_ylabel("cumulative reward")
    axes[0].legend(fontsize=7)
    fig.savefig(path, dpi=90)
    return path


@runner("online.twin")
def twin(params: dict[str, Any], budget: dict[str, Any], ctx: RunContext) -> RunResult:
    """The lab's experiment on its real model and in its twin (module docstring)."""
    from simlab.online.command import OnlineConfig, online

    p = {**params, **{k: v for k, v in budget.items() if k in ("decisions", "change_at")}}
    where = str(budget.get("lab", p.get("lab", "../shared/real-lab")))
    folder = Path(where).expanduser()
    lab = (real_lab(folder, ctx.out / "lab") if where != "stand-in" and (folder / MODEL).is_file()
           else stand_in_lab(ctx.out / "lab", int(ctx.root_seed)))
    if "change_at" in budget:
        lab = LabFiles(**{**lab.__dict__, "change_at": int(budget["change_at"])})
    primitives = _twin_primitives(p, budget, lab, ctx)
    mdps: dict[str, Any] = {"model": _mdp(lab.model, ctx.out / "mdp" / "real.npz")}
    for task, files in lab.after.items():
        mdps[task] = tuple(_mdp(f, ctx.out / "mdp" / f"{task}_{i}.npz")
                           for i, f in enumerate(files))
    common = {k: p[k] for k in ("criteria", "kappas", "protocol") if k in p}
    common.update(goal=list(lab.goal), start_states=list(lab.start_states),
                  seeds=int(budget["seeds"]), decisions=int(p.get("decisions", 3200)),
                  seed=int(ctx.root_seed), progress=ctx.progress,
                  plots=bool(budget.get("plots", True)))
    metrics: dict[str, Any] = {}
    rows, order_notes = [], []
    for task in p.get("tasks", TASKS):
        if task not in TASKS:
            raise ConfigError(f"unknown task {task!r}", key="params.tasks",
                              fix=f"choose among {', '.join(TASKS)}")
        real = online(OnlineConfig.from_mapping({
            **common, **_task_options(task, lab, real=True, mdps=mdps),
            "mdp": mdps["model"], "out": ctx.out / task / "real"}), executor=ctx.executor)
        sim = online(OnlineConfig.from_mapping({
            **common, **_task_options(task, lab, real=False, mdps=mdps,
                                      closing=str(p.get("closing", "remove"))),
            "arena": lab.arena, "states": lab.states, "primitives": primitives, "n_actions": 8,
            "convention": "ccw-east", "speed": "fast", "out": ctx.out / task / "twin"}),
            executor=ctx.executor)
        rows.append({"task": task, "real": real.summary, "twin": sim.summary,
                     "real_logs": real.logs, "twin_logs": sim.logs})
        task_metrics, note = _arm_metrics(task, real.summary, sim.summary, real.logs, sim.logs,
                                          lab.change_at if task != "stable" else None)
        metrics.update(task_metrics)
        order_notes.append(note)
    figures = [_comparison_figure(rows, ctx.out / "twin_vs_real.png"),
               _curves_figure(rows, ctx.out / "twin_vs_real_curves.png")]
    notes = [f"Lab: {lab.name}; twin: {primitives}; {common['seeds']} runs x "
             f"{common['decisions']} decisions per arm and task; change at decision "
             f"{lab.change_at + 1}.", *order_notes]
    return RunResult(metrics=metrics, figures=figures, notes=notes,
                     details={r["task"]: {"real": r["real"]["arms"], "twin": r["twin"]["arms"]}
                              for r in rows})
