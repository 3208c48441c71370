"""Calibrate: the stages that bring the simulator's T closest to a real one.

Each **candidate** is a point of a :class:`~simlab.calibration.space.ParameterSpace`. It is
evaluated by a random walk with :func:`simlab.data.collect.collect` into a temporary
directory, in the **real** table's action set (the walk draws only the primitives of the
real actions, :meth:`ActionSet.primitives`, and records them in the real numbering) and,
by default, from every state's centre in turn (``start_states = "all"``: one walk per
state, the budget split evenly), so that the walk covers the lab as the real data do.
Every real ``(s, a)`` pair counts in the distance: a pair the walk never tried is a full
miss (``unvisited = "max"``), so a candidate cannot win by covering less.

**Budgets** are sized from the real table
(:func:`~simlab.calibration.budget.size_budgets`): the screening walks have
``screen_share`` of the real transitions (cheap and noisy), the confirming walks the
smallest multiple of them whose *matched floor* (the distance at which a perfect simulator
with that many transitions would still lie from the real table) is within 35 % of the
bootstrap floor of the real table itself; the report prints the whole table of budgets.

**Common random numbers**: every candidate walks with the same seed, so the same action
sequence and the same noise draws; differences between candidates are the parameters, not
the luck of the draw.

**Optimiser** (derivative-free, seeded): the first candidate is the base record (today's
defaults, clipped into the space) so the report shows where calibration started; then a
scrambled Sobol design over the unit cube fills half of the budget; the rest is local
refinement in rounds of ``workers`` candidates: the minimum of a quadratic fitted by least
squares to the candidates nearest the best (it averages the walks' noise over many points),
then a compass search around the best point so far (``+- step`` along each coordinate, the
step shrinking by ``shrink`` after a full poll found nothing better). Candidates of a round
run in parallel on :mod:`simlab.base.parallel` (local processes, or Ray with ``address``).

**Confirmation** (``confirm``): the ``confirm_top`` best distinct screened candidates and
the starting point are re-simulated in physics on ``confirm_seeds`` fresh seeds at the
confirming budget; the **winner** is the one with the lowest mean score there (the screening
best is flattered by its own seed), and the distance reported is that of its pooled
confirming walks, free of the selection's luck. The winner's confirming walks, plus fresh
ones up to ``transfer_seeds``, are the twin seeds of the transfer report
(:mod:`simlab.calibration.transfer`).

**Decision latency** does not change T, only the rate of transitions; when the real table's
duration is known (``real.hours``) the calibrated latency is set in closed form so that the
simulated transitions per hour match: ``latency = 3600 * hours / n_real - mean duration``.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.base.errors import ConfigError, warn
from simlab.calibration.budget import Budgets, size_budgets
from simlab.calibration.config import CalibrationConfig, RealTable
from simlab.calibration.metrics import (
    Floor,
    argmax_agreement,
    bootstrap_floor,
    entropy_per_action,
    table_summary,
)
from simlab.calibration.search import (
    Candidate,
    evaluate_points,
    make_candidate,
    params_at,
    search,
    walk_context,
)
from simlab.calibration.signature import (
    Signature,
    reach_warnings,
    real_signature,
    self_share_warning,
    signature_base,
    used_speed_field,
)
from simlab.calibration.space import ParameterSpace
from simlab.calibration.walks import SimTable, WalkRunner, pool_tables


@dataclass(frozen=True)
class CalibrationResult:
    """Everything the reports need (see :mod:`simlab.calibration.report`).

    ``params`` is the calibrated record (the confirmed winner, latency fitted when
    possible); ``final`` the winner's confirming walks pooled (or its screening walk
    without confirm). ``floor``: bootstrap floor of the real counts; ``matched_floor``: the
    same for a perfect simulator with ``final``'s visit counts. ``confirmed``: every
    confirming walk; ``twins``: the twin walks of the transfer report (the winner's
    confirming walks first); ``transfer``: that report (None without twins).
    """

    config: CalibrationConfig
    space: ParameterSpace
    base: Any
    params: Any
    candidates: list[Candidate]
    best: int
    final: Candidate
    floor: Floor
    matched_floor: Floor
    real: RealTable
    real_summary: dict[str, Any]
    sim_summary: dict[str, Any]
    agreement: float
    entropy_real: NDArray[np.float64]
    entropy_sim: NDArray[np.float64]
    latency_fitted: bool
    wall_seconds: float
    notes: list[str] = field(default_factory=list)
    #: the starting point's confirming walks pooled (None without ``confirm``)
    start_confirmed: Candidate | None = None
    signature: Signature | None = None
    budgets: Budgets | None = None
    confirmed: list[Candidate] = field(default_factory=list)
    twins: list[Candidate] = field(default_factory=list)
    transfer: Any = None
    #: transfer against the twin's data: the twin walks pooled 1, 2, ... at a time, each
    #: pool's policies scored on the real model (``walks``, ``pools``, ``transitions`` per
    #: pool, ``mean_ratio``, ``worst_ratio`` of summed steps over the optimum's)
    transfer_curve: list[dict[str, Any]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    #: the screening's own best (its winner before confirmation)
    screen_best: int = 0



def _fit_latency(params: Any, real: RealTable, sim: SimTable) -> tuple[Any, bool]:
    if real.hours is None or not math.isfinite(sim.mean_duration):
        return params, False
    per_transition = real.hours * 3600.0 / float(real.counts.sum())
    latency = per_transition - sim.mean_duration
    if latency < 0:
        return params, False
    return dataclasses.replace(params, decision_latency=float(latency)), True



def _picks(cands: list[Candidate], top: int) -> list[int]:
    """The ``top`` best distinct screened candidates, then the starting point (index 0)."""
    picks: list[int] = []
    for i in sorted(range(len(cands)), key=lambda i: (cands[i].score, i)):
        if not any(np.allclose(cands[i].unit, cands[j].unit, atol=1e-9) for j in picks):
            picks.append(i)
        if len(picks) == top:
            break
    return picks + ([0] if 0 not in picks else [])



def _pooled(runs: list[Candidate], index: int, ctx: dict[str, Any]) -> Candidate:
    return make_candidate(index, "pooled", runs[0].unit, pool_tables([r.sim for r in runs]),
                      runs[0].seed, ctx)



def _confirm(runner: WalkRunner, cands: list[Candidate], ctx: dict[str, Any],
             budget: tuple[float | None, int | None], bar: Any
             ) -> tuple[int, dict[int, list[Candidate]]]:
    """Re-simulate the picks on the fresh seeds; the winner has the lowest mean score."""
    cfg: CalibrationConfig = ctx["config"]
    picks = _picks(cands, cfg.confirm_top)
    seeds = [cfg.seed + 1 + k for k in range(cfg.confirm_seeds)]
    jobs = [(i, seed) for seed in seeds for i in picks]
    runs: dict[int, list[Candidate]] = {i: [] for i in picks}
    for k in range(0, len(jobs), max(cfg.workers, 1)):
        chunk = jobs[k:k + max(cfg.workers, 1)]
        done = evaluate_points(runner, [cands[i].unit for i, _ in chunk], "confirm", 0, ctx,
                         seeds=[seed for _, seed in chunk], budget=budget)
        for (i, _), c in zip(chunk, done, strict=True):
            runs[i].append(dataclasses.replace(c, index=i))
        bar.update(len(chunk))
    mean = {i: float(np.mean([c.score for c in runs[i]])) for i in picks}
    return min(picks, key=lambda i: (mean[i], i)), runs



def _twins(runner: WalkRunner, winner: Candidate, confirmed: list[Candidate],
           ctx: dict[str, Any], budget: tuple[float | None, int | None], bar: Any
           ) -> list[Candidate]:
    """The transfer report's twin walks: the winner's confirming walks, then fresh seeds."""
    cfg: CalibrationConfig = ctx["config"]
    twins = [dataclasses.replace(c, stage="twin") for c in confirmed][:cfg.transfer_seeds]
    extra = cfg.transfer_seeds - len(twins)
    if extra > 0:
        seeds = [cfg.seed + 1 + cfg.confirm_seeds + k for k in range(extra)]
        done = evaluate_points(runner, [winner.unit] * extra, "twin", winner.index, ctx,
                         seeds=seeds, budget=budget)
        twins += [dataclasses.replace(c, index=winner.index) for c in done]
        bar.update(extra)
    return twins



def calibrate(real: RealTable, arena: Any, states: Any, *, space: ParameterSpace | None = None,
              base: Any = None, config: CalibrationConfig | None = None) -> CalibrationResult:
    """Calibrate the primitive parameters against ``real`` (module docstring).

    Args:
        real: the real counts and their action set.
        arena: built-in arena name, TOML path or ArenaConfig.
        states: states file (JSON of ``simlab discretize``) or a discretizer object; its
            number of states must equal the real table's S.
        space: searched fields (default :func:`~simlab.calibration.space.default_space`,
            sized from the real table's :mod:`~simlab.calibration.signature`).
        base: record the candidates modify (default: the simulator's default record; in
            physics switched to the mode the real signature asks for,
            :func:`~simlab.calibration.signature.signature_base`).
        config: :class:`CalibrationConfig` (defaults if None).

    Raises:
        ConfigError: inconsistent inputs, before any simulation.
    """
    config = CalibrationConfig() if config is None else config
    t0 = time.perf_counter()
    setup = _setup(real, arena, states, space, base, config)
    rng = np.random.default_rng(np.random.SeedSequence(config.seed).spawn(2)[1])
    floor = bootstrap_floor(real.counts, rng, n_boot=config.n_boot)
    budgets = size_budgets(real, config, floor, rng)
    screen = (budgets.screen_hours, budgets.screen_transitions)
    runner = WalkRunner(int(config.workers), config.address)
    try:
        cands, screen_best = search(real, setup.arena, setup.disc, space=setup.space,
                                    base=setup.base, config=config, runner=runner,
                                    screen=screen)
        ctx = walk_context(real, setup.arena, setup.disc, setup.space, setup.base, config,
                       config.seed, screen)
        done = _Confirmed(best=screen_best, final=cands[screen_best])
        if config.confirm:
            done = _confirm_stage(runner, cands, screen_best, ctx,
                                  (budgets.confirm_hours, budgets.confirm_transitions))
    finally:
        runner.close()
    params, fitted = _fit_latency(params_at(setup.space, setup.base, cands[done.best].unit),
                                  real, done.final.sim)
    final = done.final
    matched = bootstrap_floor(real.counts, rng, n_boot=config.n_boot,
                              other_n=final.sim.counts.sum(axis=2))
    sim_hours = final.sim.hours
    if fitted:
        sim_hours = final.sim.rows * (final.sim.mean_duration + params.decision_latency) / 3600
    sim_summary = table_summary(final.sim.counts, hours=sim_hours, blocked=final.sim.blocked)
    late = None if config.simulator != "physics" else self_share_warning(
        setup.signature.self_share, float(sim_summary["self_transition_share"]))
    if late is not None:
        warn(late)
        setup.warnings.append(late)
    transfer, curve = _transfer(real, done.twins, setup, config)
    return CalibrationResult(
        config=config, space=setup.space, base=setup.base, params=params, candidates=cands,
        best=done.best, final=final, floor=floor, matched_floor=matched, real=real,
        real_summary=table_summary(real.counts, hours=real.hours, blocked=real.blocked),
        sim_summary=sim_summary,
        agreement=argmax_agreement(final.sim.counts, real.counts),
        entropy_real=entropy_per_action(real.counts),
        entropy_sim=entropy_per_action(final.sim.counts),
        latency_fitted=fitted, wall_seconds=time.perf_counter() - t0, notes=done.notes,
        start_confirmed=done.start, signature=setup.signature, budgets=budgets,
        confirmed=done.confirmed, twins=done.twins, transfer=transfer,
        transfer_curve=curve, warnings=setup.warnings, screen_best=screen_best,
    )



@dataclass
class _Setup:
    """What :func:`calibrate` checked and derived before any simulation."""

    arena: Any
    disc: Any
    goals: list[int]
    signature: Signature
    base: Any
    space: ParameterSpace
    warnings: list[str]



def _setup(real: RealTable, arena: Any, states: Any, space: ParameterSpace | None, base: Any,
           config: CalibrationConfig) -> _Setup:
    """Check the inputs (ConfigError before any simulation), read the real signature, and
    pick the start and the space from it; warn where the space cannot reach the table."""
    from simlab.calibration.space import default_space
    from simlab.data.collect import parse_start_states
    from simlab.data.walkers import check_pose_source
    from simlab.physics.inputs import load_arena_config, load_discretizer

    check_pose_source(config.pose_source, config.simulator)
    arena_cfg = load_arena_config(arena)
    disc = load_discretizer(states)
    if int(disc.n_states) != real.counts.shape[0]:
        raise ConfigError(f"the states file has {disc.n_states} states, the real table "
                          f"{real.counts.shape[0]}", key="states",
                          fix="use the centres the real robot's states were numbered by")
    parse_start_states(config.start_states, int(disc.n_states))
    goals = _goal_states(config, int(disc.n_states))
    aset = real.action_set
    sig = real_signature(real.counts, disc.centres)
    if base is None:
        base = default_base(config.simulator)
        if config.simulator == "physics":
            base = signature_base(base, sig, aset)
    if space is None:
        space = default_space(aset.primitives(), config.simulator, cell_size=sig.cell_size,
                              speed_fields=used_speed_field(aset) if aset.n_actions == 8
                              else ())
    space.check_fields(base)
    warned = reach_warnings(sig, space, base, aset)
    for w in warned:
        warn(w)
    return _Setup(arena_cfg, disc, goals, sig, base, space, warned)



@dataclass(frozen=True)
class _Confirmed:
    """The outcome of the confirmation: the winner's index, its pooled confirming walks
    (``final``), the start's, every confirming walk, the twins and the notes."""

    best: int
    final: Candidate
    start: Candidate | None = None
    confirmed: list[Candidate] = field(default_factory=list)
    twins: list[Candidate] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)



def _confirm_stage(runner: WalkRunner, cands: list[Candidate], screen_best: int,
                   ctx: dict[str, Any], budget: tuple[float | None, int | None]
                   ) -> _Confirmed:
    """Confirm the best screened candidates and the start on fresh seeds, pick the winner
    there, then walk its twin seeds (one progress bar over all these walks)."""
    from tqdm.auto import tqdm

    cfg: CalibrationConfig = ctx["config"]
    n_picks = len(_picks(cands, cfg.confirm_top))
    extra = max(cfg.transfer_seeds - cfg.confirm_seeds, 0)
    bar = tqdm(total=n_picks * cfg.confirm_seeds + extra, desc="calibrate: confirm",
               unit="walk", disable=not cfg.progress)
    try:
        best, runs = _confirm(runner, cands, ctx, budget, bar)
        twins = _twins(runner, cands[best], runs[best], ctx, budget, bar) \
            if cfg.transfer_seeds else []
    finally:
        bar.close()
    return _Confirmed(best=best, final=_pooled(runs[best], best, ctx),
                      start=_pooled(runs[0], 0, ctx),
                      confirmed=[c for i in runs for c in runs[i]], twins=twins,
                      notes=[_confirm_note(cands, runs, best, screen_best)])



def _transfer(real: RealTable, twins: list[Candidate], setup: _Setup,
              config: CalibrationConfig) -> tuple[Any, list[dict[str, Any]]]:
    """The transfer report of the twin walks on the real model (None without twins), every
    goal of ``setup.goals`` with its perfect-twin floor (the real optimum of an estimated
    model is biased low); and the transfer against the twins' own data: the twin walks
    pooled k = 1, 2, 4, ... at a time (disjoint pools), each pool's policies scored the
    same way (:meth:`~simlab.calibration.transfer.TransferResult.overall_ratios`)."""
    if not twins:
        return None, []
    from simlab.calibration.transfer import TransferModel, transfer_report

    def model(counts: NDArray[np.int64], name: str) -> TransferModel:
        return TransferModel.from_counts(counts, name=name, action_set=real.action_set,
                                         centres=setup.disc.centres)

    real_model = model(real.counts, real.source or "real")
    goals = {f"s{g}": [g] for g in setup.goals}
    report = transfer_report(
        real_model, [model(t.sim.counts, f"twin seed {t.seed}") for t in twins], goals,
        n_boot=TRANSFER_BOOT,
        rng=np.random.default_rng(np.random.SeedSequence(config.seed, spawn_key=(11,))))
    curve = []
    for k in _pool_sizes(len(twins)):
        pools = [twins[i:i + k] for i in range(0, len(twins) - k + 1, k)]
        counts = [sum(t.sim.counts for t in pool) for pool in pools]
        ratios = report.overall_ratios() if k == 1 else transfer_report(
            real_model, [model(c, f"{k} walks") for c in counts], goals).overall_ratios()
        curve.append({"walks": k, "pools": len(pools),
                      "transitions": int(sum(int(c.sum()) for c in counts) // len(counts)),
                      "mean_ratio": float(np.mean(ratios)),
                      "worst_ratio": float(np.max(ratios))})
    return report, curve


#: How close to a twin of unlimited data the recommended policy data come (steps over the
#: real optimum, absolute).
DATA_NEED_TOLERANCE = 0.01


def data_need(curve: list[dict[str, Any]], tolerance: float = DATA_NEED_TOLERANCE
              ) -> dict[str, float] | None:
    """How many twin transitions a policy needs, from the transfer's data curve.

    A policy planned on a model estimated from ``N`` transitions exploits that sample's
    noise; its excess over what unlimited data would give shrinks about as ``1/N`` (each
    transition probability's error variance does). Fits ``ratio(N) = limit + c / N`` by
    least squares to the curve's mean ratios and returns ``limit`` (a twin with unlimited
    data), ``c`` and ``transitions`` = ``c / tolerance`` (the data at which the excess is
    ``tolerance``); None with fewer than two sizes, a non-finite ratio, or a curve that
    does not fall with more data (``c <= 0``).
    """
    rows = [r for r in curve if math.isfinite(r["mean_ratio"])]
    if len(rows) < 2 or len(rows) < len(curve):
        return None
    x = np.array([1.0 / r["transitions"] for r in rows])
    y = np.array([r["mean_ratio"] for r in rows])
    A = np.stack([np.ones_like(x), x], axis=1)
    (limit, c), *_ = np.linalg.lstsq(A, y, rcond=None)
    if not c > 0:
        return None
    return {"limit": float(limit), "c": float(c), "tolerance": float(tolerance),
            "transitions": float(c / tolerance)}


def _pool_sizes(n: int) -> list[int]:
    """Twin walks pooled per twin in the data curve: 1, 2, 4, ... below ``n``, then ``n``."""
    sizes, k = [], 1
    while k < n:
        sizes.append(k)
        k *= 2
    return [*sizes, n]



#: Resamples of the transfer report's perfect-twin floor (per goal).
TRANSFER_BOOT = 30



def _goal_states(config: CalibrationConfig, n_states: int) -> list[int]:
    goals = list(range(n_states)) if config.goal_states is None else list(config.goal_states)
    bad = [g for g in goals if not 0 <= g < n_states]
    if bad:
        raise ConfigError(f"goal state {bad[0]} is not one of the {n_states} states",
                          key="goal_states", fix=f"use states 0..{n_states - 1}")
    return goals



def _confirm_note(cands: list[Candidate], runs: dict[int, list[Candidate]], best: int,
                  screen_best: int) -> str:
    parts = [f"#{i}: {np.mean([c.distance for c in runs[i]]):.4f}" for i in runs]
    text = (f"confirmed on {len(next(iter(runs.values())))} fresh seed(s) (mean distance "
            f"per candidate: {', '.join(parts)}); the winner is #{best}")
    if best != screen_best:
        text += (f", not the screening's best #{screen_best} (distance "
                 f"{cands[screen_best].distance:.4f} on the screening seed)")
    if best == 0:
        text += ": no screened candidate beat the starting point on the fresh seeds"
    return text



def default_base(simulator: str) -> Any:
    """Default parameter record of a simulator (``PrimitiveParams``/``KinematicParams``)."""
    if simulator == "kinematic":
        from simlab.data.walkers import KinematicParams

        return KinematicParams()
    from simlab.physics.motion import PrimitiveParams

    return PrimitiveParams()

