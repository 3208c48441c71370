"""The social pipeline: train the social module on the grid (tabular)
and/or on the empirical social MDP of a physics walk, run the combined architecture closed
loop on the table against a random policy, write the results.

``module`` (decision): ``"grid"`` (default), ``"empirical"`` or ``"both"``. The default
stays ``"grid"`` because the empirical module needs a physics social walk first
(``walk_steps`` decisions, default 8,000 least-tried in 4 segments: 75-95 wall s with 2
workers on a loaded 2-core box; below 8,000 decisions the empirical module did not beat
random, from 8,000 on it did by ~10x: the table in :mod:`simlab.social.empirical`), which
does not fit the CI-small budgets of the existing pipeline and CLI tests that run with the
defaults; the ``social_table_closed_loop`` experiment asks for ``"both"``. ``"empirical"``
collects a social walk (:func:`simlab.social.walk.social_walk`, seed ``seed``, the walk's
seed rules, the paper's ``redraw_p`` 0.2, the loop's GO_TO_HUMAN offsets; ``walk_segments``
independent segments of the ``walk_policy`` behaviour, run by ``workers`` processes, or
by the ``executor`` a Python caller passes, e.g. ``simlab reproduce``'s: the data do not
depend on where they ran), estimates the sparse MDP and plans on it
(:func:`simlab.social.empirical.train_empirical`), then runs the closed loop with that
Q-table on the same seeds as the others.

:func:`social_pipeline` writes into ``out`` (one output transaction, :mod:`simlab.base.io`):

* ``summary.json`` — settings, the grid training's plateau, per-run figures
  (:meth:`~simlab.social.closedloop.ClosedLoopRun.summary`) of the combined loop and the
  random baseline, pooled goals per simulated hour and their ratio, and the tabular
  prediction (below);
* ``cumulative_goals.png`` — goals reached with the human vs simulated hours, per run;
* ``closed_loop.gif`` — the first ``gif_decisions`` decisions of the first combined run;
* ``social_q.npy`` — the trained grid social Q-table ``(2560, 30)`` (module grid/both);
* ``social_q_empirical.npy`` — the empirical Q-table ``(2560, 22)``, ``-inf`` where masked
  (module empirical/both).

``summary.json``'s ``goals_per_hour`` sets grid-trained, empirical-trained and random side by
side (pooled over the runs; ``pooled`` keeps the per-policy figures, ``combined`` being the
grid-trained policy as before).

Decision (the grid variant): the social module is trained on the grid's ``"paper"``
variant by default. The physics perception follows that variant's continuous-bearing
rules (:mod:`simlab.social.perception`), and its tables lead the human far better on the
table than ``"thesis"`` tables of the same or twice the budget (measured with the greedy
loop, epsilon 0: 22 goals in 6 x 0.25 h with 40,000 paper trials, 14 and 8 with 40,000
and 80,000 thesis trials; random 4; with the default epsilon 0.05: paper 41, thesis 19).
It is also 8x faster to train (40,000 trials in
about 4 s).

Measured (``social_pipeline(out=...)`` with the defaults: 3 runs x 0.5 h, easy human,
40,000 paper trials): combined 32 goals (15, 5, 12), random 4 (0, 2, 2), ratio 8.0;
social reward per decision 0.168 in physics vs 0.50 per step on the grid.

Measured with the empirical module (``simlab social-pipeline --out DIR
--module both --workers 2 --runs 6 --hours 0.5 --seed S``, the default walk: 8,000
least-tried decisions in 4 segments), goals per simulated hour, empirical / grid /
random: seed 0: 31.6 (95 goals) / 20.3 (61) / 2.0 (6); seed 1: 25.0 (75) / 11.0 (33) /
2.0 (6). The empirical module beats random by 12-16x. Cost: the walk 33 wall s (idle
box) to 95 s (loaded), planning 0.3 s, the 18 closed-loop runs 44 s; predicted (renewal
model) empirical 34.0 and 44.0, grid 8.4 and 13.3, random 0 (a drift model: module
:mod:`simlab.social.empirical`).

Tabular prediction: the grid training's plateau social reward per step (the human moved
in the required direction while at level 7) is set beside the physics loop's social
reward per decision. The predicted *goal* rate (``tabular_prediction.goals_per_hour``) is
the renewal model of :func:`simlab.social.empirical.predict_goal_rate` on the empirical
MDP for the empirical module's greedy policy (and, under ``predicted_goals_per_hour``, for
the grid module's greedy policy on the same empirical MDP), set beside the measured rates;
it needs the walk, so it is None for ``module="grid"``.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base import validation as v
from simlab.base.errors import ConfigError
from simlab.base.io import atomic_write, atomic_write_json, output_transaction, write_npy
from simlab.base.options import CommandConfig, command, option
from simlab.social.closedloop import (
    ClosedLoopConfig,
    ClosedLoopRun,
    closed_loop_frames,
    goal_rate_ratio,
    run_closed_loop,
    write_closed_loop_gif,
)
from simlab.social.task import SocialConfig, SocialTable
from simlab.social.walk import WALK_POLICIES

FILES = ("summary.json", "cumulative_goals.png", "closed_loop.gif", "social_q.npy",
         "social_q_empirical.npy")

#: Values of :attr:`SocialPipelineConfig.module`.
MODULES = ("grid", "empirical", "both")


@dataclass(frozen=True, kw_only=True)
class SocialPipelineConfig(CommandConfig):
    """Options of :func:`social_pipeline` (times in simulated hours)."""

    COMMAND = "social-pipeline"

    out: Path = option(help="output directory", metavar="DIR")
    seed: int = option(0, "root seed: training seed, and runs use seed, seed+1, ...")
    hours: float = option(0.5, "simulated hours per closed-loop run")
    runs: int = option(3, "closed-loop runs (seeds) of each policy")
    human: str = option("easy", "human preset (simlab.visitlab.humans)")
    arena: str = option("table", "built-in arena name or .toml path (with >= 2 goal areas)")
    goals: tuple[str, ...] = option((), "goal area names to lead through (default: all)")
    agent: str = option("mb-egreedy", "agent that trains the grid social module")
    trials: int = option(40_000, "grid social training trials (small budget: 10000)")
    variant: str = option("paper", "grid variant of the training: paper or thesis",
                          choices=("paper", "thesis"))
    module: str = option("grid", "social module(s) to train and run: grid (tabular), "
                         "empirical (a physics walk's sparse MDP) or both", choices=MODULES)
    walk_steps: int = option(8000, "decisions of the physics social walk of the empirical "
                             "module (all segments together)")
    walk_policy: str = option("least-tried", "behaviour policy of the walk: uniform or "
                              "least-tried (coverage-seeking)", choices=WALK_POLICIES)
    walk_segments: int = option(4, "independent seeded walk segments (walk_steps split "
                                "evenly, rounded up); the data depend on it, not on workers")
    workers: int = option(1, "processes that run the walk's segments (simlab.base.parallel)")
    gif_decisions: int = option(120, "decisions shown in the GIF (0: no GIF)")
    gif_fps: float = option(4.0, "GIF frames per second")
    overwrite: bool = option(False, "replace existing outputs")

    def validate(self) -> None:
        v.whole(self.seed, "seed")
        v.positive(self.hours, "hours")
        v.whole(self.runs, "runs", minimum=1)
        v.whole(self.trials, "trials", minimum=1)
        v.choice(self.module, MODULES, "module")
        v.whole(self.walk_steps, "walk_steps", minimum=1)
        v.choice(self.walk_policy, WALK_POLICIES, "walk_policy")
        v.whole(self.walk_segments, "walk_segments", minimum=1)
        v.whole(self.workers, "workers", minimum=1)
        v.whole(self.gif_decisions, "gif_decisions", minimum=0)
        v.positive(self.gif_fps, "gif_fps")

    def closed_loop(self) -> ClosedLoopConfig:
        """The closed loop's settings."""
        base = ClosedLoopConfig().social
        social = SocialConfig(arena=self.arena, human=self.human,
                              gth_offsets_deg=base.gth_offsets_deg)
        return ClosedLoopConfig(social=social, goals=self.goals)

    @property
    def policies(self) -> tuple[str, ...]:
        """Closed-loop policies run: ``combined`` (grid), ``empirical``, ``random``."""
        return {"grid": ("combined", "random"), "empirical": ("empirical", "random"),
                "both": ("combined", "empirical", "random")}[self.module]


@dataclass
class SocialPipelineResult:
    """What :func:`social_pipeline` ran: the runs of each policy (``combined`` the
    grid-trained one, empty for ``module="empirical"``), the Q-tables (``q`` the grid's,
    None without it; ``q_empirical``), the summary (as written to ``summary.json``) and the
    paths written."""

    combined: list[ClosedLoopRun]
    random: list[ClosedLoopRun]
    q: np.ndarray | None
    summary: dict[str, Any]
    paths: dict[str, Path]
    empirical: list[ClosedLoopRun] = field(default_factory=list)
    q_empirical: np.ndarray | None = None


def train_social(cfg: SocialPipelineConfig) -> tuple[np.ndarray, dict[str, Any]]:
    """Grid social Q-table ``(2560, 30)`` of one seed and the training's figures."""
    from simlab.visitlab.training import train

    res = train("social", cfg.agent, trials=cfg.trials, seeds=1, seed=cfg.seed,
                variant=cfg.variant, progress=False, human=cfg.human)
    tail = max(1, cfg.trials // 10)
    plateau = float(res.returns[0, -tail:].mean())
    return res.q[0], {"agent": cfg.agent, "variant": cfg.variant, "trials": cfg.trials,
                      "max_steps": res.config["max_steps"],
                      "plateau_return": round(plateau, 4),
                      "plateau_reward_per_step": round(plateau / res.config["max_steps"], 6),
                      "wall_s": round(res.wall_time_s, 2)}


def _pooled(runs: list[ClosedLoopRun]) -> dict[str, float]:
    hours = sum(r.hours for r in runs)
    goals = sum(r.goals_reached for r in runs)
    decisions = sum(int(r.time.size) for r in runs)
    social = sum(r.social_reward for r in runs)
    return {"goals": goals, "hours": round(hours, 6),
            "goals_per_hour": round(goals / hours, 4) if hours else 0.0,
            "social_reward_per_decision": round(social / decisions, 6) if decisions else 0.0}


_COLOURS = {"combined": ("C0", "grid-trained"), "empirical": ("C2", "empirical-trained"),
            "random": ("C3", "random")}


def plot_cumulative(runs: dict[str, list[ClosedLoopRun]], path: Path) -> None:
    """PNG of the goals reached with the human vs simulated hours (one step line per run),
    for each policy of ``runs`` (``combined``, ``empirical``, ``random``)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 4))
    ax = fig.add_subplot()
    for policy, policy_runs in runs.items():
        colour, name = _COLOURS[policy]
        for k, r in enumerate(policy_runs):
            t = np.concatenate([[0.0], r.goal_times, [r.hours * 3600.0]]) / 3600.0
            n = np.concatenate([[0], np.arange(1, r.goals_reached + 1), [r.goals_reached]])
            ax.step(t, n, where="post", color=colour, alpha=0.8,
                    label=name if k == 0 else None)
    ax.set_xlabel("simulated time (h)")
    ax.set_ylabel("goal areas reached with the human")
    ax.set_title(" vs ".join(_COLOURS[p][1] for p in runs) + ", same seeds")
    ax.legend()
    fig.tight_layout()
    with atomic_write(path, "wb") as fh:
        fig.savefig(fh, format="png", dpi=100)


def train_empirical_module(cfg: SocialPipelineConfig, executor: Any | None = None
                           ) -> tuple[Any, list[Any], dict[str, Any]]:
    """The empirical module (module docstring): ``(EmpiricalSocial, walks, figures)``; the
    walk's segments run on ``executor`` when given (``cfg.workers`` must then be 1)."""
    from simlab.social.empirical import rule_agreement, train_empirical
    from simlab.social.walk import WalkConfig, social_walk

    start = time.perf_counter()
    social = replace(cfg.closed_loop().social, redraw_p=0.2)
    per_segment = -(-cfg.walk_steps // cfg.walk_segments)
    walks = social_walk(WalkConfig(steps=per_segment, workers=cfg.walk_segments, seed=cfg.seed,
                                   social=social, policy=cfg.walk_policy),
                        processes=cfg.workers, executor=executor)
    walk_s = time.perf_counter() - start
    emp = train_empirical(walks, redraw_p=social.redraw_p)
    info = {**emp.summary(), "walk_steps": per_segment * cfg.walk_segments,
            "walk_segments": cfg.walk_segments, "walk_policy": cfg.walk_policy,
            "walk_workers": cfg.workers if executor is None else int(executor.workers),
            "redraw_p": social.redraw_p,
            "walk_simulated_hours": round(sum(w.simulated_hours for w in walks), 6),
            "walk_rewards": int(sum(w.reward.sum() for w in walks)),
            "rule_reward_agreement": round(rule_agreement(walks), 6),
            "walk_wall_s": round(walk_s, 2),
            "plan_wall_s": round(time.perf_counter() - start - walk_s, 2)}
    return emp, walks, info


@command(SocialPipelineConfig, extras=("executor",))
def social_pipeline(cfg: SocialPipelineConfig, executor: Any | None = None
                    ) -> SocialPipelineResult:
    """Train the social module(s) (``module``), run the closed loop with each and the random
    baseline for ``runs`` seeds of ``hours`` simulated hours each, write the outputs
    (module docstring).

    Takes a :class:`SocialPipelineConfig` or its fields
    (``social_pipeline(out="runs/social", hours=0.25, trials=10000)``). Same seed -> the
    same runs and summary (apart from the wall-clock figures and ``walk_workers``), whether
    the walk ran here, on ``workers`` processes or on ``executor`` (a
    :mod:`simlab.base.parallel` executor the caller owns, run-time only: not an option).
    """
    if executor is not None and cfg.workers != 1:
        raise ConfigError("give either workers or an executor for the walk", key="workers",
                          fix="drop workers: the executor's workers run the walk")
    out = Path(cfg.out)
    wanted = {"social_q.npy": "combined" in cfg.policies,
              "social_q_empirical.npy": "empirical" in cfg.policies,
              "closed_loop.gif": bool(cfg.gif_decisions)}
    finals = tuple(out / f for f in FILES if wanted.get(f, True))
    loop = cfg.closed_loop()
    with output_transaction(out, finals, overwrite=cfg.overwrite,
                            what="social pipeline output") as txn:
        q, training = train_social(cfg) if "combined" in cfg.policies else (None, {})
        emp, walks, emp_info = (train_empirical_module(cfg, executor)
                                if "empirical" in cfg.policies
                                else (None, [], None))
        tables = {"combined": q, "empirical": None if emp is None else emp.q, "random": None}
        start = time.perf_counter()
        with SocialTable(loop.social) as table:
            seeds = [cfg.seed + k for k in range(cfg.runs)]
            runs = {p: [run_closed_loop(tables[p], s, cfg.hours, loop, table) for s in seeds]
                    for p in cfg.policies}
        for p in runs:
            for r in runs[p]:
                r.policy = p
        wall = time.perf_counter() - start
        summary = _summary(cfg, runs, training, emp, walks, emp_info, loop, q)
        summary["physics_wall_s"] = round(wall, 2)
        summary["simulated_hours_per_wall_s"] = round(
            len(runs) * cfg.runs * cfg.hours / max(wall, 1e-9), 4)
        paths = {"summary": out / "summary.json", "plot": out / "cumulative_goals.png"}
        for key, name, table_q in (("q", "social_q.npy", q),
                                   ("q_empirical", "social_q_empirical.npy",
                                    None if emp is None else emp.q)):
            if table_q is not None:
                paths[key] = out / name
                with atomic_write(txn.path(paths[key]), "wb") as fh:
                    write_npy(fh, table_q)
        plot_cumulative(runs, txn.path(paths["plot"]))
        if cfg.gif_decisions:
            paths["gif"] = out / "closed_loop.gif"
            first = runs.get("combined") or runs["empirical"]
            frames = closed_loop_frames(first[0], loop, count=cfg.gif_decisions + 1)
            write_closed_loop_gif(frames, txn.path(paths["gif"]), cfg.gif_fps)
        atomic_write_json(txn.path(paths["summary"]), summary)
    return SocialPipelineResult(runs.get("combined", []), runs["random"], q, summary, paths,
                                empirical=runs.get("empirical", []),
                                q_empirical=None if emp is None else emp.q)


def _summary(cfg: SocialPipelineConfig, runs: dict[str, list[ClosedLoopRun]],
             training: dict[str, Any], emp: Any, walks: list[Any],
             emp_info: dict[str, Any] | None, loop: ClosedLoopConfig,
             q_grid: np.ndarray | None) -> dict[str, Any]:
    """``summary.json`` without the wall-clock figures of the loop (module docstring)."""
    pooled = {p: _pooled(r) for p, r in runs.items()}
    learned = "combined" if "combined" in runs else "empirical"
    ratio = goal_rate_ratio(runs[learned], runs["random"])
    names = {"combined": "grid", "empirical": "empirical", "random": "random"}
    predicted, note = None, ("the prediction needs the empirical MDP of a physics walk: "
                             "run with module empirical or both")
    if emp is not None:
        predicted = _predictions(emp, walks, runs, loop, q_grid)
        note = ("renewal model on the empirical social MDP under the greedy policy "
                "(simlab.social.empirical.predict_goal_rate): decisions to engage by an "
                "absorbing-chain solve, loss probability and reward per engaged decision, "
                "lead distance between goal centres at the walk's rewarded human step, "
                "decision durations of the walk")
    return {
        "config": json.loads(json.dumps(cfg.to_dict(), default=str)),
        "training": training,
        "empirical_training": emp_info,
        "runs": {p: [r.summary() for r in rr] for p, rr in runs.items()},
        "pooled": pooled,
        "goals_per_hour": {names[p]: pooled[p]["goals_per_hour"] for p in runs},
        "goal_rate_ratio": None if not np.isfinite(ratio) else round(ratio, 4),
        "empirical_goal_rate_ratio": (
            None if "empirical" not in runs or learned == "empirical" or not np.isfinite(
                r := goal_rate_ratio(runs["empirical"], runs["random"])) else round(r, 4)),
        "predicted_goals_per_hour": predicted,
        "tabular_prediction": {
            "social_reward_per_step_grid": training.get("plateau_reward_per_step"),
            "social_reward_per_decision_physics": pooled[learned]["social_reward_per_decision"],
            "goals_per_hour": None if predicted is None
            else predicted["empirical"]["goals_per_hour"],
            "measured_goals_per_hour": pooled[learned if emp is None else "empirical"][
                "goals_per_hour"],
            "note": note,
        },
    }


def _predictions(emp: Any, walks: list[Any], runs: dict[str, list[ClosedLoopRun]],
                 loop: ClosedLoopConfig, q_grid: np.ndarray | None) -> dict[str, Any]:
    """The renewal model's figures for the empirical (and grid) greedy policies."""
    from simlab.physics.arena import load_arena
    from simlab.social.actions import grid_q_to_physics
    from simlab.social.closedloop import select_goals
    from simlab.social.empirical import loop_factors, pooled_progress, predict_goal_rate

    goals = select_goals(load_arena(loop.social.arena), loop.goals)
    tables = {"empirical": emp.q, "random": None}
    if q_grid is not None:  # the grid module's greedy policy on the same empirical MDP
        tables["grid"] = grid_q_to_physics(q_grid)
    key = {"empirical": "empirical", "random": "random", "grid": "combined"}
    progress = pooled_progress(walks)
    out: dict[str, Any] = {}
    for name, q in tables.items():
        out[name] = predict_goal_rate(emp.planned_P, q, emp.R, walks, goals,
                                      visited=emp.planned_visited, epsilon=loop.epsilon,
                                      progress=progress).to_json()
        out[name]["measured_goals_per_hour"] = _pooled(runs[key[name]])["goals_per_hour"]
        out[name]["measured"] = {k: (round(v, 6) if np.isfinite(v) else None)
                                 for k, v in loop_factors(runs[key[name]], goals).items()}
    return out
