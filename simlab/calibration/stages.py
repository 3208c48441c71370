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
(:func:`~simlab.calibration.budget.size_budgets`): the first rung's walks have
``screen_share`` of the real transitions (cheap and noisy), the confirming walks the
smallest multiple of them whose *matched floor* (the distance at which a perfect simulator
with that many transitions would still lie from the real table) is within 35 % of the
bootstrap floor of the real table itself; the report prints the whole table of budgets.

**Search** (:mod:`~simlab.calibration.search`): Optuna proposes the candidates, successive
halving promotes the best of each rung to longer walks on the rung's common seed, and the
objective (:mod:`~simlab.calibration.objective`) holds the robot's signature beside the
distance.

**Confirmation** (``confirm``): the ``confirm_top`` best candidates of the search's last
rung and the starting point are re-simulated in physics on ``confirm_seeds`` fresh seeds at
the confirming budget; the **winner** is the one with the lowest mean score there (the
search's best is flattered by its own seeds), and the distance reported is that of its
pooled confirming walks, free of the selection's luck. The confirmed candidates within
sampling of the winner form the **twin ensemble** (``CalibrationResult.ensemble``). The
winner's confirming walks, plus fresh ones up to ``transfer_seeds``, are the twin seeds of
the transfer report (:mod:`simlab.calibration.transfer`).

**Decision latency** does not change T, only the rate of transitions; when the real table's
duration is known (``real.hours``) the calibrated latency is set in closed form so that the
simulated transitions per hour match: ``latency = 3600 * hours / n_real - mean duration``.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.base.errors import ConfigError
from simlab.calibration.budget import Budgets, size_budgets
from simlab.calibration.config import CalibrationConfig, RealTable
from simlab.calibration.contradictions import Contradictions, contradicted_pairs
from simlab.calibration.metrics import (
    Floor,
    argmax_agreement,
    bootstrap_floor,
    entropy_per_action,
    perfect_twin_floor,
    table_summary,
)
from simlab.calibration.objective import Reference
from simlab.calibration.policies import (
    DATA_NEED_TOLERANCE,
    TRANSFER_BOOT,
    TwinTransfer,
    collect_policy_data,
    data_need,
    ensemble_transfer,
    score_policy_data,
    transfer_stage,
    warn_all,
)
from simlab.calibration.profile import profile_stage
from simlab.calibration.regions import pair_regions, region_signature
from simlab.calibration.resets import reset_warning, resolve_reset_states, without_rows
from simlab.calibration.search import (
    Candidate,
    SearchResult,
    evaluate_points,
    make_candidate,
    params_at,
    search,
    walk_context,
    walk_size,
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
from simlab.calibration.walks import SimTable, WalkJob, WalkRunner, pool_tables

__all__ = ["DATA_NEED_TOLERANCE", "TRANSFER_BOOT", "CalibrationResult", "calibrate",
           "data_need", "default_base"]


@dataclass(frozen=True)
class CalibrationResult:
    """Everything the reports need (see :mod:`simlab.calibration.report`).

    ``params`` is the calibrated record (the confirmed winner, latency fitted when
    possible); ``final`` the winner's confirming walks pooled (or its screening walk
    without confirm). ``floor``: bootstrap floor of the real counts; ``matched_floor``: the
    same for a perfect simulator with ``final``'s visit counts (the plug-in, which reads
    low); ``perfect_floor``: that distance without the plug-in's bias
    (:func:`~simlab.calibration.metrics.perfect_twin_floor`), the reference of the level
    the reports state. ``confirmed``: every
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
    #: the transfer stage (:class:`~simlab.calibration.policies.TwinTransfer`): perfect-twin
    #: lines, policy data; None without twins
    twin_transfer: Any = None
    #: the signature per region, real and twin side by side
    #: (:func:`~simlab.calibration.regions.region_signature`)
    regions: list[dict[str, Any]] = field(default_factory=list)
    #: the search: its rungs, picks and the share of the score each field explains
    search: SearchResult | None = None
    #: the confirmed candidates within sampling of the winner (the winner first): the twin
    #: ensemble, and how sure the twin is field by field
    ensemble: list[Candidate] = field(default_factory=list)
    #: each searched field moved alone from the winner (``profile_step``), or None
    profile: Any = None
    #: the real pairs where the twin's walks contradict the robot beyond sampling
    #: (:mod:`~simlab.calibration.contradictions`)
    contradictions: Contradictions | None = None
    #: the arena the twin walked and the state centres (the contradictions' figure)
    arena: Any = None
    centres: Any = None
    #: the distance a twin equal to the robot would show at ``final``'s visits
    #: (:func:`~simlab.calibration.metrics.perfect_twin_floor`)
    perfect_floor: Floor | None = None



def _fit_latency(params: Any, real: RealTable, sim: SimTable) -> tuple[Any, bool]:
    if real.hours is None or not math.isfinite(sim.mean_duration):
        return params, False
    per_transition = real.hours * 3600.0 / float(real.counts.sum())
    latency = per_transition - sim.mean_duration
    if latency < 0:
        return params, False
    return dataclasses.replace(params, decision_latency=float(latency)), True



def _picks(found: SearchResult) -> list[int]:
    """The search's picks for the confirmation, then the starting point (index 0)."""
    return found.picks + ([0] if 0 not in found.picks else [])



def _pooled(runs: list[Candidate], index: int, ctx: dict[str, Any]) -> Candidate:
    return make_candidate(index, "pooled", runs[0].unit, pool_tables([r.sim for r in runs]),
                      runs[0].seed, ctx)



def _confirm(runner: WalkRunner, found: SearchResult, ctx: dict[str, Any],
             budget: tuple[float | None, int | None], bar: Any
             ) -> tuple[int, dict[int, list[Candidate]]]:
    """Re-simulate the picks on the fresh seeds; the winner has the lowest mean score."""
    cfg: CalibrationConfig = ctx["config"]
    cands = found.candidates
    picks = _picks(found)
    seeds = [cfg.seed + cfg.rungs + k for k in range(cfg.confirm_seeds)]
    jobs = [(i, seed) for seed in seeds for i in picks]
    runs: dict[int, list[Candidate]] = {i: [] for i in picks}
    for k in range(0, len(jobs), cfg.batch):  # chunks for the progress bar only: the
        chunk = jobs[k:k + cfg.batch]           # runner keeps every worker busy anyway
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
        seeds = [cfg.seed + cfg.rungs + cfg.confirm_seeds + k for k in range(extra)]
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
    setup = prepare_calibration(real, arena, states, space, base, config)
    real = setup.real
    rng = np.random.default_rng(np.random.SeedSequence(config.seed).spawn(2)[1])
    floor = bootstrap_floor(real.counts, rng, n_boot=config.n_boot)
    budgets = size_budgets(real, config, floor, rng)
    screen = (budgets.screen_hours, budgets.screen_transitions)
    reference = setup.reference()
    runner = WalkRunner(int(config.workers), config.address)
    try:
        found = search(real, setup.arena, setup.disc, space=setup.space, base=setup.base,
                       config=config, runner=runner, screen=screen, reference=reference)
        cands, screen_best = found.candidates, found.best
        ctx = walk_context(real, setup.arena, setup.disc, setup.space, setup.base, config,
                           config.seed, screen, reference)
        last = found.rungs[-1] if found.rungs else cands
        done = _Confirmed(best=screen_best, final=next(c for c in last if c.index == screen_best))
        if config.confirm:
            done = _confirm_stage(runner, found, ctx,
                                  (budgets.confirm_hours, budgets.confirm_transitions))
        params, fitted = _fit_latency(params_at(setup.space, setup.base,
                                                cands[done.best].unit), real, done.final.sim)
        twin = _twin_stage(runner, real, done, setup, config, params)
        profile = None
        if config.profile_step:  # the config refuses it without the confirmation
            walks = done.twins or [c for c in done.confirmed if c.index == done.best]
            profile = profile_stage(runner, cands[done.best], walks, ctx,
                                    (budgets.confirm_hours, budgets.confirm_transitions),
                                    config.profile_step, config.profile_pairs,
                                    done.confirmed)
    finally:
        runner.close()
    final = done.final
    matched = bootstrap_floor(real.counts, rng, n_boot=config.n_boot,
                              other_n=final.sim.counts.sum(axis=2))
    # its own stream: the level's reference adds no draw to the ones after it
    perfect = perfect_twin_floor(
        real.counts, np.random.default_rng(np.random.SeedSequence(config.seed, spawn_key=(19,))),
        final.sim.counts.sum(axis=2), n_boot=config.n_boot)
    ensemble = _ensemble(done, matched, twin, real.action_set, setup.disc.centres)
    sim_hours = final.sim.hours
    if fitted:
        sim_hours = final.sim.rows * (final.sim.mean_duration + params.decision_latency) / 3600
    sim_counts = without_rows(final.sim.counts, real.reset_states)
    sim_summary = table_summary(sim_counts, hours=sim_hours, blocked=final.sim.blocked)
    late = None if config.simulator != "physics" else self_share_warning(
        setup.signature.self_share, float(sim_summary["self_transition_share"]))
    warn_all([late] if late is not None else [], setup.warnings)
    if twin is not None:
        warn_all(twin.warnings, setup.warnings)
    return CalibrationResult(
        config=config, space=setup.space, base=setup.base, params=params, candidates=cands,
        best=done.best, final=final, floor=floor, matched_floor=matched,
        perfect_floor=perfect, real=real,
        real_summary=table_summary(real.counts, hours=real.hours, blocked=real.blocked),
        sim_summary=sim_summary,
        agreement=argmax_agreement(sim_counts, real.counts),
        entropy_real=entropy_per_action(real.counts),
        entropy_sim=entropy_per_action(sim_counts),
        latency_fitted=fitted, wall_seconds=time.perf_counter() - t0, notes=done.notes,
        start_confirmed=done.start, signature=setup.signature, budgets=budgets,
        confirmed=done.confirmed, twins=done.twins,
        transfer=None if twin is None else twin.report,
        transfer_curve=[] if twin is None else twin.curve, warnings=setup.warnings,
        screen_best=screen_best, twin_transfer=twin, search=found,
        ensemble=ensemble, profile=profile,
        regions=_region_rows(setup, real, final),
        contradictions=_contradictions(real, done, config, setup.regions),
        arena=setup.arena, centres=setup.disc.centres,
    )


def _contradictions(real: RealTable, done: _Confirmed, config: CalibrationConfig,
                    regions: NDArray[np.int64] | None) -> Contradictions:
    """The real pairs the winner's walks contradict: its twin walks pooled (its confirming
    walks pooled when there are none), reset rows left out."""
    walks = [t.sim.counts for t in done.twins] or [done.final.sim.counts]
    rng = np.random.default_rng(np.random.SeedSequence(config.seed, spawn_key=(17,)))
    return contradicted_pairs(real.counts, sum(walks), rng,
                              skip_states=list(real.reset_states or ()), regions=regions)


def _twin_stage(runner: WalkRunner, real: RealTable, done: _Confirmed, setup: CalibrationSetup,
                config: CalibrationConfig, params: Any) -> TwinTransfer | None:
    """The transfer stage of the twin walks
    (:func:`~simlab.calibration.policies.transfer_stage`), then with ``policy_data`` the
    recommended data collected with the calibrated ``params`` and scored."""
    rng = np.random.default_rng(np.random.SeedSequence(config.seed, spawn_key=(11,)))
    twin = transfer_stage(real, [t.sim.counts for t in done.twins],
                          [f"twin seed {t.seed}" for t in done.twins], setup.goals,
                          setup.disc.centres, rng, untried=config.untried)
    if twin is None or twin.report is None or not config.policy_data:
        return twin
    if twin.need is None:
        twin.warnings.append("--policy-data: nothing collected, the transfer gives no "
                             "policy-data figure")
        return twin
    job = WalkJob(index=0, arena=setup.arena, states=setup.disc, params=params, hours=None,
                  transitions=1, seed=0, simulator=config.simulator,
                  pose_source=config.pose_source, action_set=real.action_set,
                  start_states=config.start_states, n_states=int(setup.disc.n_states))
    counts = collect_policy_data(runner, job, round(twin.need["transitions"]),
                                 config.workers, config.seed + 1000)
    twin.policy = score_policy_data(twin, counts, real.action_set, setup.disc.centres, rng)
    return twin


def _ensemble(done: _Confirmed, matched: Floor, twin: TwinTransfer | None, action_set: Any,
              centres: Any) -> list[Candidate]:
    """The confirmed candidates (each pooled over its confirming walks) whose distance lies
    within sampling of the winner's: no more than the matched floor's 95 % half-width
    (``high - median``) above it; the winner first. Empty without confirmation. With a
    transfer stage, its ``ensemble`` figure is set: the members' walks against as many of
    the winner's (:func:`~simlab.calibration.policies.ensemble_transfer`)."""
    if not done.pooled:
        return []
    width = matched.high - matched.median if math.isfinite(matched.high) else 0.0
    others = sorted((c for c in done.pooled if c.index != done.best),
                    key=lambda c: (c.distance, c.index))
    members = [done.final] + [c for c in others if c.distance <= done.final.distance + width]
    if twin is not None:
        twin.ensemble = ensemble_transfer(twin, [c.sim.counts for c in members],
                                          [t.sim.counts for t in done.twins], action_set,
                                          centres)
    return members


def _region_rows(setup: CalibrationSetup, real: RealTable, final: Candidate
                 ) -> list[dict[str, Any]]:
    """Real and twin signatures per region (:mod:`~simlab.calibration.regions`) side by
    side: ``region``, then ``real`` and ``sim`` dicts and the region's ``tv``."""
    if setup.regions is None:
        return []
    heads = real.action_set.headings()
    centres = setup.disc.centres
    r = region_signature(real.counts, setup.regions, centres, heads,
                         final.tv.per_pair, real.counts.sum(axis=2))
    s = region_signature(without_rows(final.sim.counts, real.reset_states), setup.regions,
                         centres, heads)
    return [{"region": a["region"], "tv": a.pop("tv"), "real": a, "sim": b}
            for a, b in zip(r, s, strict=True)]



@dataclass
class CalibrationSetup:
    """What :func:`calibrate` checked and derived before any simulation: ``real`` is the
    real table without its reset rows; ``regions`` (S, A) the region of each real pair
    (:mod:`~simlab.calibration.regions`; None without physics)."""

    arena: Any
    disc: Any
    goals: list[int]
    signature: Signature
    base: Any
    space: ParameterSpace
    warnings: list[str]
    real: RealTable
    regions: NDArray[np.int64] | None = None

    def reference(self) -> Reference:
        """The robot's signature every candidate's score is measured against."""
        return Reference.build(self.real.counts, self.regions, self.disc.centres,
                               self.real.action_set.headings())



def prepare_calibration(real: RealTable, arena: Any, states: Any,
                        space: ParameterSpace | None, base: Any,
                        config: CalibrationConfig) -> CalibrationSetup:
    """Check the inputs (ConfigError before any simulation), read the real signature, and
    pick the start and the space from it; warn where the space cannot reach the table."""
    from simlab.base.statecheck import check_centres_in_arena
    from simlab.calibration.space import default_space
    from simlab.data.collect import parse_start_states
    from simlab.data.walkers import check_pose_source
    from simlab.physics.inputs import load_arena_config, load_discretizer

    check_pose_source(config.pose_source, config.simulator)
    arena_cfg = load_arena_config(arena)
    disc = load_discretizer(states)
    check_centres_in_arena(disc.centres, arena_cfg,
                           source=str(states) if isinstance(states, str | os.PathLike) else None)
    if int(disc.n_states) != real.counts.shape[0]:
        raise ConfigError(f"the states file has {disc.n_states} states, the real table "
                          f"{real.counts.shape[0]}", key="states",
                          fix="use the centres the real robot's states were numbered by")
    parse_start_states(config.start_states, int(disc.n_states))
    goals = _goal_states(config, int(disc.n_states))
    aset = real.action_set
    resets = resolve_reset_states(config.reset_states, real.counts, disc.centres)
    warned: list[str] = []
    if resets:
        warn_all([reset_warning(resets, real.counts, disc.centres,
                                "the distance and the transfer")], warned)
        left = without_rows(real.counts, resets)
        real = dataclasses.replace(real, counts=left, reset_states=resets,
                                   reset_counts=int(real.counts.sum() - left.sum()))
    sig = real_signature(real.counts, disc.centres)
    if base is None:
        base = default_base(config.simulator)
        if config.simulator == "physics":
            base = signature_base(base, sig, aset)
    if space is None:
        space = default_space(aset.primitives(), config.simulator, cell_size=sig.cell_size,
                              speed_fields=used_speed_field(aset) if aset.n_actions == 8
                              else (), mode=getattr(base, "mode", None))
    space.check_fields(base)
    warn_all(reach_warnings(sig, space, base, aset), warned)
    regions = None
    if config.simulator == "physics" and math.isfinite(sig.cell_size):
        regions = pair_regions(arena_cfg, disc.centres, aset.headings(), sig.cell_size)
    return CalibrationSetup(arena_cfg, disc, goals, sig, base, space, warned, real, regions)



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
    #: every confirmed candidate's confirming walks pooled
    pooled: list[Candidate] = field(default_factory=list)



def _confirm_stage(runner: WalkRunner, found: SearchResult, ctx: dict[str, Any],
                   budget: tuple[float | None, int | None]) -> _Confirmed:
    """Confirm the best screened candidates and the start on fresh seeds, pick the winner
    there, then walk its twin seeds (one progress bar over all these walks)."""
    from tqdm.auto import tqdm

    cfg: CalibrationConfig = ctx["config"]
    cands = found.candidates
    n_picks = len(_picks(found))
    extra = max(cfg.transfer_seeds - cfg.confirm_seeds, 0)
    bar = tqdm(total=n_picks * cfg.confirm_seeds + extra,
               desc=f"calibrate: confirm ({walk_size(budget)} a walk)",
               unit="walk", disable=not cfg.progress)
    try:
        best, runs = _confirm(runner, found, ctx, budget, bar)
        twins = _twins(runner, cands[best], runs[best], ctx, budget, bar) \
            if cfg.transfer_seeds else []
    finally:
        bar.close()
    pooled = {i: _pooled(runs[i], i, ctx) for i in runs}
    return _Confirmed(best=best, final=pooled[best], start=pooled[0],
                      pooled=list(pooled.values()),
                      confirmed=[c for i in runs for c in runs[i]], twins=twins,
                      notes=[_confirm_note(cands, runs, best, found.best)])



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
        text += (f", not the search's best #{screen_best} (distance "
                 f"{cands[screen_best].distance:.4f} on its rung-1 walk)")
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

