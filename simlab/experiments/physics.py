"""The physics experiments: thesis Figs. 4.8 (entropy), 4.9 (training), 4.10 (replay).

All three read the settings of :class:`~simlab.orchestration.stages.PhysicsSettings`
from their TOML and share one :class:`~simlab.orchestration.stages.PhysicsChain`
cache: map -> states -> 10-hour walk(s) -> empirical MDP -> Q-tables. The runners add
the statistics, the figures and the metrics the ``[[expect]]`` checks read. ``seeds``
is the number of independent chains (datasets with their MDP, training and replay) on
one map and one set of states; the training itself always averages ``runs`` runs per
goal (the ``simlab train`` default is 10).
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from simlab.experiments.context import RunContext, RunResult
from simlab.experiments.registry import runner
from simlab.orchestration.stages import PhysicsChain, PhysicsSettings, chain_seed

#: Transitions the thesis's robot logged in about 10 hours of random walk (3.2.5).
THESIS_TRANSITIONS_10H = 8448
#: Mean MCL position error (m) above which the 4.10 notes say the filter lost track.
MCL_LOST_M = 0.05


def _chain(ctx: RunContext, s: PhysicsSettings) -> PhysicsChain:
    return PhysicsChain(ctx.cache, s, ctx.root_seed, backend=ctx.backend_name,
                        progress=ctx.progress, log=ctx.log)


def _copy(src: Path, dst: Path) -> Path:
    shutil.copyfile(src, dst)
    return dst


def _cache_note(chain: PhysicsChain) -> str:
    """Which stages this experiment built and which it found in the shared cache."""
    parts = []
    for built, label in ((True, "built"), (False, "reused from the shared cache")):
        kinds: dict[str, int] = {}
        for st in chain.stages:
            if st.built == built:
                kind = st.path.name.split("-")[0]
                kinds[kind] = kinds.get(kind, 0) + 1
        if kinds:
            parts.append(f"{label}: " + ", ".join(k if n == 1 else f"{k} x{n}"
                                                  for k, n in kinds.items()))
    return "Physics chain stages " + "; ".join(parts) + "."


def paired_entropy_difference(entropies: list[np.ndarray], visited: list[np.ndarray]
                              ) -> tuple[float, float, int]:
    """Mean and 95 % half-width of ``H(s, d + 8) - H(s, d)`` over every state ``s`` and
    direction ``d`` (0-7) where both the slow action ``d`` and the fast action ``d + 8``
    were tried, pooled over datasets; also the number of pairs.

    Pairing by state and direction removes the between-state variation (cells near a
    wall have few successors at any speed), so the interval measures the effect of
    speed alone. Normal interval on the mean of the differences.
    """
    diffs = []
    for H, v in zip(entropies, visited, strict=True):
        both = v[:, :8] & v[:, 8:16]
        diffs.append((H[:, 8:16] - H[:, :8])[both])
    d = np.concatenate(diffs) if diffs else np.zeros(0)
    if d.size < 2:
        return (float(d.mean()) if d.size else math.nan), math.nan, int(d.size)
    return float(d.mean()), 1.96 * float(d.std(ddof=1)) / math.sqrt(d.size), int(d.size)


@runner("physics.entropy")
def entropy(params: dict[str, Any], budget: dict[str, Any], ctx: RunContext) -> RunResult:
    """Thesis Fig. 4.8: mean transition entropy per action, slow vs fast.

    Metrics: ``n_states``; ``transitions`` and ``transitions_per_10h`` (mean over
    datasets; the thesis logged 8,448 in ~10 h); ``fraction_pairs_visited``;
    ``entropy_slow_bits`` / ``entropy_fast_bits`` (mean over datasets of the mean of the
    8 per-action means, :mod:`simlab.data.estimate`); ``fast_minus_slow_bits`` and its
    paired 95 % interval ``fast_minus_slow_ci95_low`` / ``_high``
    (:func:`paired_entropy_difference`); ``directions_fast_higher`` (of the 8
    directions, how many have a higher mean entropy fast than slow);
    ``datasets_fast_higher`` (fraction of datasets with fast > slow).
    """
    from simlab.data.plots import plot_entropy_per_action

    s = PhysicsSettings.from_tables(params, budget)
    chain = _chain(ctx, s)
    states = chain.states()
    ents, vis, means, slow, fast, trans, per10, cover = [], [], [], [], [], [], [], []
    for i in range(s.seeds):
        st = chain.mdp(i)
        ds = chain.dataset(i)
        with np.load(st.path / "mdp.npz", allow_pickle=False) as z:
            ents.append(z["entropy"])
            vis.append(z["visited"])
            means.append(z["mean_entropy"])
        slow.append(float(st.summary["entropy_slow"]))
        fast.append(float(st.summary["entropy_fast"]))
        cover.append(float(st.summary["fraction_visited"]))
        n = int(st.summary["transitions"])
        trans.append(n)
        per10.append(n * 10.0 / float(ds.summary["simulated_hours"]))
    diff, half, n_pairs = paired_entropy_difference(ents, vis)
    mean_per_action = np.nanmean(np.stack(means), axis=0)
    figure = ctx.out / "entropy_per_action.png"
    plot_entropy_per_action(
        mean_per_action, figure,
        title=(f"Mean transition entropy per action ({s.seeds} x {s.hours:g} h walk): "
               f"slow {np.mean(slow):.2f}, fast {np.mean(fast):.2f} bits"))
    states_png = _copy(states.path / "states.png", ctx.out / "states.png")
    metrics = {
        "n_states": int(states.summary["n_states"]),
        "datasets": s.seeds,
        "hours_per_dataset": s.hours,
        "transitions": float(np.mean(trans)),
        "transitions_per_10h": float(np.mean(per10)),
        "fraction_pairs_visited": float(np.mean(cover)),
        "entropy_slow_bits": float(np.mean(slow)),
        "entropy_fast_bits": float(np.mean(fast)),
        "fast_minus_slow_bits": float(np.mean(fast) - np.mean(slow)),
        "fast_minus_slow_paired_bits": diff,
        "fast_minus_slow_ci95_low": diff - half,
        "fast_minus_slow_ci95_high": diff + half,
        "paired_state_directions": n_pairs,
        "directions_fast_higher": int(np.sum(mean_per_action[8:16] > mean_per_action[:8])),
        "datasets_fast_higher": float(np.mean(np.array(fast) > np.array(slow))),
    }
    notes = [
        f"Plug-in entropies of T(s, a, .) from {s.seeds} random walk(s) of {s.hours:g} robot "
        f"hours on {metrics['n_states']} Voronoi states; with few visits per (s, a) they are "
        "biased low, equally for slow and fast actions (both are drawn uniformly).",
        f"Pace: {metrics['transitions_per_10h']:,.0f} transitions per 10 robot hours "
        f"(thesis: {THESIS_TRANSITIONS_10H:,} in about 10 h).",
        _cache_note(chain),
    ]
    details = {"mean_entropy_per_action": [None if not np.isfinite(v) else float(v)
                                           for v in mean_per_action],
               "per_dataset": {"entropy_slow": slow, "entropy_fast": fast,
                               "transitions": trans, "fraction_visited": cover}}
    return RunResult(metrics=metrics, figures=[figure, states_png], notes=notes,
                     details=details)


@runner("physics.training")
def training(params: dict[str, Any], budget: dict[str, Any], ctx: RunContext) -> RunResult:
    """Thesis Fig. 4.9: VI-softmax trained on the empirical MDP of each goal.

    Metrics (over goals and datasets): ``min_ratio`` / ``mean_ratio`` (final mean reward
    per episode, exploration included, over the VI-optimal expected return),
    ``min_greedy_ratio`` (exact expected return of the learned greedy policies over the
    optimum), ``max_episodes_to_90`` (the slowest goal's first curve point at 90 % of the
    optimum; None if a goal never got there), ``goals``, ``episodes``, ``runs``,
    ``train_seconds``.
    """
    s = PhysicsSettings.from_tables(params, budget)
    chain = _chain(ctx, s)
    rows = []
    seconds = 0.0
    stages = []
    for i in range(s.seeds):
        st = chain.qtables(i)
        stages.append(st)
        seconds += float(st.summary["train_seconds"])
        rows += list(st.summary["goals"].values())
    ratios = [r["ratio"] for r in rows if r["ratio"] is not None]
    greedy = [r["greedy_ratio"] for r in rows if r["greedy_ratio"] is not None]
    to90 = [r["episodes_to_90"] for r in rows]
    figures = [_copy(stages[0].path / "curves.png", ctx.out / "learning_curves.png")]
    if (stages[0].path / "heatmaps.png").exists():
        figures.append(_copy(stages[0].path / "heatmaps.png", ctx.out / "q_heatmaps.png"))
    worst = min(rows, key=lambda r: r["ratio"] if r["ratio"] is not None else math.inf)
    metrics = {
        "goals": len(stages[0].summary["goals"]),
        "episodes": s.episodes,
        "runs": s.runs,
        "min_ratio": min(ratios) if ratios else None,
        "mean_ratio": float(np.mean(ratios)) if ratios else None,
        "min_greedy_ratio": min(greedy) if greedy else None,
        "max_episodes_to_90": None if any(v is None for v in to90) else max(to90),
        "train_seconds": seconds,
    }
    notes = [
        f"{s.agent}, {s.episodes} episodes of {s.horizon} steps per goal, {s.runs} runs "
        f"averaged, on {s.seeds} empirical MDP(s). 'ratio' is the on-policy reward (softmax "
        "exploration included) over the optimal expected return of value iteration on the "
        f"same MDP; the worst goal is {worst['goal']} ({worst['ratio']:.1%}).",
        _cache_note(chain),
    ]
    return RunResult(metrics=metrics, figures=figures, notes=notes,
                     details={"goals": rows})


def replay_job(**kwargs: Any) -> dict[str, Any]:
    """One closed-loop replay (a ``ctx.map`` job): :func:`simlab.replay.replay.replay`
    with ``kwargs``; returns its summary, the reward times (s) and the robot time (s)."""
    from simlab.replay.replay import replay

    res = replay(**kwargs)
    return {"summary": res.summary_dict, "reward_times": res.run.log.reward_times.tolist(),
            "robot_seconds": float(res.run.robot_seconds)}


def _mean_or_none(values: list[Any]) -> float | None:
    vals = [float(v) for v in values if v is not None]
    return float(np.mean(vals)) if len(vals) == len(values) and vals else None


def linearity_r2(reward_times: np.ndarray, duration: float, points: int = 200) -> float:
    """R^2 of a straight-line fit to the cumulative reward ``N(t)`` sampled at ``points``
    evenly spaced robot times in ``[0, duration]`` (1 for a perfectly steady rate).
    NaN with fewer than 2 rewards."""
    t = np.sort(np.asarray(reward_times, dtype=np.float64))
    if t.size < 2 or duration <= 0:
        return math.nan
    grid = np.linspace(0.0, duration, points)
    n = np.searchsorted(t, grid, side="right").astype(np.float64)
    slope, intercept = np.polyfit(grid, n, 1)
    ss_res = float(np.sum((n - (slope * grid + intercept)) ** 2))
    ss_tot = float(np.sum((n - n.mean()) ** 2))
    return 1.0 - ss_res / ss_tot if ss_tot > 0 else math.nan


def _replay_jobs(ctx: RunContext, s: PhysicsSettings, chain: PhysicsChain
                 ) -> list[dict[str, Any]]:
    """The ``replay_job`` keywords of every chain seed: greedy, then random (baseline)."""
    states = chain.states()
    map_yaml = chain.map().path / "map.yaml"
    jobs = []
    for i in range(s.seeds):
        q = chain.qtables(i)
        mdp = chain.mdp(i).path / "mdp.npz"
        common = {"arena": s.arena, "states": str(states.path / "states.json"),
                  "hours": s.replay_hours, "map": str(map_yaml), "mdp": str(mdp),
                  "baseline_hours": 0.0, "progress": False}
        jobs.append({**common, "qtables": str(q.path), "policy": "greedy",
                     "pose_source": s.pose_source, "seed": chain_seed(ctx.root_seed, "replay", i),
                     "out": str(ctx.out / f"replay_seed{i}"), "video": s.video and i == 0})
        jobs.append({**common, "qtables": None, "policy": "random", "pose_source": "truth",
                     "seed": chain_seed(ctx.root_seed, "baseline", i),
                     "out": str(ctx.out / f"random_seed{i}"), "video": False})
    return jobs


def _replay_metrics(s: PhysicsSettings, greedy: list[dict[str, Any]],
                    rand: list[dict[str, Any]]) -> tuple[dict[str, Any], tuple[Any, ...]]:
    """The metrics of :func:`replay_experiment` and the per-seed arrays behind them
    (``rates``, ``rand_rates``, ``predicted``, ``pred_random``, ``r2``)."""
    rates = np.array([g["summary"]["result"]["rate_per_hour"] for g in greedy])
    rand_rates = np.array([r["summary"]["result"]["rate_per_hour"] for r in rand])
    predicted = np.array([g["summary"]["comparison"].get("predicted_rate_per_hour", math.nan)
                          for g in greedy], dtype=np.float64)
    pred_random = np.array([(g["summary"].get("prediction") or {}).get("random", {})
                            .get("rate_per_hour", math.nan) for g in greedy], dtype=np.float64)
    r2 = [linearity_r2(np.array(g["reward_times"]), g["robot_seconds"]) for g in greedy]
    over = rates / predicted
    worst = float(over[np.argmax(np.abs(over - 1.0))]) if np.all(np.isfinite(over)) else None
    rate, rand_rate = float(rates.mean()), float(rand_rates.mean())
    metrics: dict[str, Any] = {
        "seeds": s.seeds,
        "replay_hours": s.replay_hours,
        "rate_per_hour": rate,
        "random_rate_per_hour": rand_rate,
        "ratio_to_random": rate / rand_rate if rand_rate > 0 else None,
        "predicted_random_rate_per_hour": float(np.mean(pred_random)),
        "ratio_to_random_mdp": rate / float(np.mean(pred_random))
        if np.mean(pred_random) > 0 else None,
        "predicted_rate_per_hour": float(np.mean(predicted)),
        "measured_over_predicted": rate / float(np.mean(predicted))
        if np.mean(predicted) > 0 else None,
        "measured_over_predicted_worst": worst,
        "linearity_r2_min": float(np.nanmin(r2)) if np.any(np.isfinite(r2)) else None,
        "rewards_over_expected": _mean_or_none(
            [g["summary"]["comparison"].get("rewards_measured_over_expected_over_horizon")
             for g in greedy]),
        "rewards": int(sum(g["summary"]["result"]["rewards"] for g in greedy)),
        "transitions": int(sum(g["summary"]["result"]["transitions"] for g in greedy)),
        "state_agrees_with_truth": float(np.mean(
            [g["summary"]["result"]["state_agrees_with_truth"] or 0.0 for g in greedy])),
    }
    if s.pose_source == "mcl":
        errs = [g["summary"]["localization"]["mcl"]["at_decisions"] for g in greedy]
        metrics["mcl_position_error_m"] = float(np.mean([e.get("position_mean_m", math.nan)
                                                         for e in errs]))

    return metrics, (rates, rand_rates, predicted, pred_random, r2)


def _replay_notes(s: PhysicsSettings, chain: PhysicsChain, greedy: list[dict[str, Any]],
                  metrics: dict[str, Any]) -> list[str]:
    """The notes of :func:`replay_experiment` (sim-to-model gap, per-seed warnings)."""
    notes = [
        f"Greedy replay of the mean-over-runs Q-tables ({s.pose_source} poses, obstacle "
        "detector, goal switching to another of the goals, no return to the start), random "
        f"policy as the baseline; {s.seeds} seed(s) of {s.replay_hours:g} robot hours each. "
        "The MDP prediction is the exact long-run reward rate of the goal-switching chain "
        "on the empirical T at the dataset's pace (seconds per transition).",
        _cache_note(chain),
    ]
    if metrics["measured_over_predicted"] is not None:
        gap = metrics["measured_over_predicted"] - 1.0
        notes.insert(1, (
            f"Measured rate {abs(gap):.0%} {'above' if gap >= 0 else 'below'} the MDP "
            "prediction: the sim-to-model gap. The empirical T averages over every pose the "
            "random walk had inside a cell; the greedy robot visits other poses, and the "
            "replay's blocked-action retries and loop watchdog are not in the model."))
    for i, g in enumerate(greedy):
        warning = g["summary"]["comparison"].get("warning")
        if warning:
            notes.append(f"Seed {i}: {warning}.")
        loc = (g["summary"]["localization"].get("mcl") or {}).get("at_decisions", {})
        err = loc.get("position_mean_m")
        if err is not None and err > MCL_LOST_M:
            notes.append(f"Seed {i}: the MCL pose was {err:.2f} m off on average (heading "
                         f"{math.degrees(loc.get('heading_mean_rad', math.nan)):.0f} deg): the "
                         "filter lost track, so the robot acted on wrong states "
                         f"({g['summary']['result']['state_agrees_with_truth']:.0%} agree "
                         "with the true state).")
    return notes


@runner("physics.replay")
def replay_experiment(params: dict[str, Any], budget: dict[str, Any], ctx: RunContext
                      ) -> RunResult:
    """Thesis Fig. 4.10: the learned Q-tables replayed in physics with goal switching.

    Per chain seed, two replays run in parallel (``ctx.map``): the greedy policy with the
    settings' pose source, and the random policy (truth poses; a random policy ignores
    them). Metrics: ``rate_per_hour`` and ``random_rate_per_hour`` (means over seeds,
    rewards per robot hour), ``ratio_to_random`` (their ratio), ``ratio_to_random_mdp``
    (over the random rate the MDP predicts), ``predicted_rate_per_hour`` (the MDP's rate
    for the greedy policy at the dataset's pace, :mod:`simlab.replay.prediction`),
    ``measured_over_predicted`` (pooled) and ``measured_over_predicted_worst`` (the seed
    farthest from 1), ``rewards_over_expected`` (rewards over the MDP's expectation for
    the same number of transitions from the start, transient included; mean over seeds),
    ``linearity_r2_min`` (:func:`linearity_r2`, worst seed),
    ``rewards``, ``transitions``, ``state_agrees_with_truth``, and with ``mcl``
    ``mcl_position_error_m`` (mean at decisions).
    """
    from simlab.replay.plots import RewardCurve, plot_cumulative_reward

    s = PhysicsSettings.from_tables(params, budget)
    chain = _chain(ctx, s)
    jobs = _replay_jobs(ctx, s, chain)
    ctx.log(f"{len(jobs)} replays of {s.replay_hours:g} robot hours on {ctx.workers} workers")
    results = ctx.map(replay_job, jobs, desc="replays")
    greedy, rand = results[0::2], results[1::2]

    metrics, (rates, rand_rates, predicted, pred_random, r2) = _replay_metrics(s, greedy, rand)

    curves = [RewardCurve(f"greedy, seed {i} ({s.pose_source}): {rates[i]:.1f} /h",
                          np.array(g["reward_times"]), g["robot_seconds"])
              for i, g in enumerate(greedy)]
    curves += [RewardCurve(f"random, seed {i}: {rand_rates[i]:.1f} /h",
                           np.array(r["reward_times"]), r["robot_seconds"])
               for i, r in enumerate(rand)]
    figure = ctx.out / "cumulative_reward.png"
    plot_cumulative_reward(
        figure, curves,
        [(f"MDP-predicted greedy: {np.mean(predicted):.1f} /h", float(np.mean(predicted))),
         (f"MDP-predicted random: {np.mean(pred_random):.1f} /h", float(np.mean(pred_random)))],
        hours=s.replay_hours,
        title=f"{s.arena}: cumulative reward over {s.replay_hours:g} h of robot time")
    figures = [figure]
    gif = ctx.out / "replay_seed0" / "replay.gif"
    if gif.exists():
        figures.append(gif)
    notes = _replay_notes(s, chain, greedy, metrics)
    details = {"per_seed": [{"rate_per_hour": float(rates[i]),
                             "random_rate_per_hour": float(rand_rates[i]),
                             "predicted_rate_per_hour": float(predicted[i]),
                             "linearity_r2": r2[i],
                             "comparison": g["summary"]["comparison"]}
                            for i, g in enumerate(greedy)]}
    return RunResult(metrics=metrics, figures=figures, notes=notes, details=details)
