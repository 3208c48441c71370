"""The seeded multi-fidelity search over a :class:`~simlab.calibration.space.ParameterSpace`.

**Why multi-fidelity.** A walk's table is noisy in proportion to its size: ranking two
candidates by one walk of a quarter of the real transitions each picks the luckier walk as
often as the better robot. So the walks are spent where they decide, by **successive
halving** (Jamieson & Talwalkar 2016, "Non-stochastic best arm identification and
hyperparameter optimization"; the synchronous bracket of Li et al. 2018, Hyperband): every
candidate walks a small walk (rung 0); the best ``1 / eta`` of them walk ``eta`` times more
(rung 1), and so on for ``rungs`` rungs; a candidate's score at a rung is that of all its
walks so far pooled into one table. The best ``confirm_top`` of the last rung, with the
starting point, go on to the confirmation (:mod:`~simlab.calibration.stages`).

**Proposals** come from Optuna (Akiba et al. 2019): its TPE sampler (Bergstra et al. 2011;
multivariate, seeded, with the constant liar for the candidates of a batch still walking) by
default, or its CMA-ES, quasi-Monte-Carlo (scrambled Sobol) or random samplers; the first
candidate is always the starting record, so the report shows where calibration started. The
sampler learns from the rung-0 scores, the fidelity all candidates share. The promotion is
synchronous (every candidate of a rung is walked before any is promoted) rather than Optuna's
asynchronous pruners, whose promotions depend on which walk finishes first: here the
outcome depends only on the seed, on one core or on a cluster.

**Batches**: candidates are asked ``batch`` at a time and walked in parallel on
:mod:`simlab.base.parallel` (local processes, or Ray with ``address``); the batch size is an
option of its own, not the number of workers, so the same seed gives the same search on any
machine.

**Common random numbers**: every candidate of a rung walks with that rung's seed, so the same
action sequence and the same noise draws; differences between candidates are the parameters,
not the luck of the draw.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.base.errors import ConfigError
from simlab.calibration.budget import screen_budget
from simlab.calibration.config import CalibrationConfig, RealTable
from simlab.calibration.metrics import TVResult, tv_distance
from simlab.calibration.objective import Reference, SignatureGap, score
from simlab.calibration.space import ParameterSpace
from simlab.calibration.walks import SimTable, WalkJob, WalkRunner, pool_tables


@dataclass(frozen=True)
class Candidate:
    """One evaluated point: ``unit`` ``(d,)`` in the unit cube, ``values`` by name.

    ``stage``: ``screen`` (rung 0), ``rung 1``, ``rung 2``, ... (the candidate's walks up to
    that rung pooled), ``confirm`` (one confirming walk), ``pooled`` (a candidate's
    confirming walks as one table) or ``twin``. ``gap``: its signature against the robot's
    (:class:`~simlab.calibration.objective.SignatureGap`)."""

    index: int
    stage: str
    unit: NDArray[np.float64]
    values: dict[str, Any]
    distance: float
    sim: SimTable
    tv: TVResult
    score: float
    seed: int = 0
    gap: SignatureGap | None = None


@dataclass
class SearchResult:
    """What :func:`search` found.

    Attributes:
        candidates: every rung-0 candidate, by index (index 0 the starting point).
        rungs: per later rung, the promoted candidates with their walks pooled.
        picks: the indices going on to the confirmation, best first.
        importance: ``{field: share}`` of the rung-0 score's variance each field explains
            (Optuna's PED-ANOVA; empty when it cannot be computed).
        sizes: ``(hours, transitions)`` of one walk at each rung.
    """

    candidates: list[Candidate]
    rungs: list[list[Candidate]] = field(default_factory=list)
    picks: list[int] = field(default_factory=list)
    importance: dict[str, float] = field(default_factory=dict)
    sizes: list[tuple[float | None, int | None]] = field(default_factory=list)

    @property
    def best(self) -> int:
        return self.picks[0]


def _base_point(space: ParameterSpace, base: Any) -> NDArray[np.float64]:
    return space.unit({n: getattr(base, n) for n in space.names})


def make_candidate(index: int, stage: str, u: NDArray[np.float64], sim: SimTable, seed: int,
                   ctx: dict[str, Any]) -> Candidate:
    cfg: CalibrationConfig = ctx["config"]
    ref: Reference = ctx["reference"]
    tv = tv_distance(sim.counts, ref.counts, unvisited=cfg.unvisited)
    d = tv.distance if math.isfinite(tv.distance) else 1.0
    value, gap = score(cfg.objective, sim.counts, ref, d, seed=cfg.seed,
                       unvisited=cfg.unvisited, weight=cfg.signature_weight)
    return Candidate(index, stage, np.asarray(u), ctx["space"].values(u), d, sim, tv, value,
                     seed, gap)


def walk_jobs(points: list[NDArray[np.float64]], seeds: list[int], start: int,
              ctx: dict[str, Any], budget: tuple[float | None, int | None]) -> list[WalkJob]:
    space: ParameterSpace = ctx["space"]
    cfg: CalibrationConfig = ctx["config"]
    hours, transitions = budget
    return [WalkJob(index=start + i, arena=ctx["arena"], states=ctx["states"],
                    params=space.apply(ctx["base"], u), hours=hours, transitions=transitions,
                    seed=seed, simulator=cfg.simulator, pose_source=cfg.pose_source,
                    action_set=ctx["real"].action_set, start_states=cfg.start_states,
                    n_states=ctx["n_states"])
            for i, (u, seed) in enumerate(zip(points, seeds, strict=True))]


def evaluate_points(runner: WalkRunner, points: list[NDArray[np.float64]], stage: str, start: int,
                    ctx: dict[str, Any], seeds: list[int] | None = None,
                    budget: tuple[float | None, int | None] | None = None) -> list[Candidate]:
    """Simulate ``points`` (on ``seeds``, default the search's walk seed, and ``budget``
    ``(hours, transitions)``, default the screening budget) and score them."""
    seeds = [ctx["walk_seed"]] * len(points) if seeds is None else seeds
    jobs = walk_jobs(points, seeds, start, ctx, ctx["screen"] if budget is None else budget)
    return [make_candidate(job.index, stage, u, sim, job.seed, ctx)
            for job, u, sim in zip(jobs, points, runner.map(jobs), strict=True)]


def walk_context(real: RealTable, arena: Any, disc: Any, space: ParameterSpace, base: Any,
                 config: CalibrationConfig, walk_seed: int,
                 screen: tuple[float | None, int | None] | None = None,
                 reference: Reference | None = None) -> dict[str, Any]:
    if screen is None:
        screen = screen_budget(config, int(real.counts.sum()))
    return {"space": space, "config": config, "arena": arena, "states": disc, "base": base,
            "walk_seed": int(walk_seed), "real": real, "n_states": int(disc.n_states),
            "screen": screen,
            "reference": Reference.build(real.counts) if reference is None else reference}


def make_sampler(name: str, seed: int, n_candidates: int, batch: int) -> Any:
    """The Optuna sampler ``name`` (:data:`~simlab.calibration.config.SAMPLERS`) seeded with ``seed``.

    TPE starts from ``max(batch, n / 3)`` quasi-random candidates (its default of 10 is
    sized for long studies; with a few dozen candidates a third explores and the rest
    exploit); CMA-ES from the same number, with a population of ``batch`` or more.

    Measured (``benchmarks/calibrate_samplers.py``, ``benchmarks/calibrate_twin.py``): on the
    ISIR lab's 11 fields with 36 candidates, CMA-ES landed at 1.87x and 1.74x the matched floor
    where TPE landed at 1.61x and 1.65x on the same seeds 0 and 1 (it gets about two generations); on a 4-field kinematic
    lab, 3 seeds, CMA-ES 1.17, QMC 1.23, random 1.22 and TPE 1.33 (median distance over the
    matched floor): TPE is the default for the many-field physics twin, not everywhere.
    """
    import optuna

    startup = max(batch, n_candidates // 3)
    with warnings.catch_warnings():  # multivariate TPE and constant liar are "experimental"
        warnings.simplefilter("ignore")
        if name == "tpe":
            return optuna.samplers.TPESampler(seed=seed, multivariate=True, constant_liar=True,
                                              n_startup_trials=startup)
        if name == "cmaes":
            try:
                import cmaes  # noqa: F401  (Optuna's CMA-ES sampler needs it)
            except ImportError:
                raise ConfigError("Optuna's CMA-ES sampler needs the cmaes package",
                                  key="calibration.sampler",
                                  fix="pip install cmaes, or use the default tpe") from None
            return optuna.samplers.CmaEsSampler(
                seed=seed, n_startup_trials=startup,
                independent_sampler=optuna.samplers.QMCSampler(
                    seed=seed, scramble=True, warn_independent_sampling=False),
                popsize=max(batch, 4 + int(3 * math.log(max(n_candidates, 2)))))
        if name == "qmc":
            # the first batch, asked before any candidate is told, draws at random (a QMC
            # design needs its search space from a finished candidate): no warning for it
            return optuna.samplers.QMCSampler(qmc_type="sobol", scramble=True, seed=seed,
                                              warn_independent_sampling=False)
        return optuna.samplers.RandomSampler(seed=seed)


def _distributions(space: ParameterSpace) -> dict[str, Any]:
    from optuna.distributions import CategoricalDistribution, FloatDistribution

    return {p.name: CategoricalDistribution(p.choices) if p.categorical
            else FloatDistribution(p.low, p.high, log=p.scale == "log") for p in space.specs}


def _study(config: CalibrationConfig, space: ParameterSpace, base: Any) -> Any:
    import optuna

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    seed = int(np.random.SeedSequence(config.seed).generate_state(1)[0])
    study = optuna.create_study(direction="minimize", sampler=make_sampler(
        config.sampler, seed, config.candidates, config.batch))
    start = space.values(np.clip(_base_point(space, base), 0.0, 1.0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        study.enqueue_trial(start, skip_if_exists=False)
    return study


def _importance(study: Any, space: ParameterSpace) -> dict[str, float]:
    """Share of the rung-0 score each field explains (PED-ANOVA, Watanabe et al. 2023),
    ``{}`` when the library cannot say (too few candidates)."""
    import optuna

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            imp = optuna.importance.get_param_importances(
                study, evaluator=optuna.importance.PedAnovaImportanceEvaluator(),
                normalize=True)
    except (RuntimeError, ValueError, ZeroDivisionError):
        return {}
    return {name: float(imp.get(name, 0.0)) for name in space.names}


def rung_budgets(screen: tuple[float | None, int | None], eta: int, rungs: int
                 ) -> list[tuple[float | None, int | None]]:
    """``(hours, transitions)`` of one walk at each rung: the screening size, then ``eta``
    times the previous."""
    hours, transitions = screen
    return [(None if hours is None else hours * eta ** k,
             None if transitions is None else int(transitions) * eta ** k)
            for k in range(rungs)]


def survivors(n: int, eta: int, keep: int) -> int:
    """Candidates promoted from a rung of ``n``: ``ceil(n / eta)``, at least ``keep``."""
    return min(n, max(keep, math.ceil(n / eta)))


def _distinct_best(cands: list[Candidate], n: int) -> list[int]:
    """Indices of the ``n`` best distinct points of ``cands`` (ties by index)."""
    picks: list[int] = []
    for c in sorted(cands, key=lambda c: (c.score, c.index)):
        if not any(np.allclose(c.unit, d.unit, atol=1e-9)
                   for d in cands if d.index in picks):
            picks.append(c.index)
        if len(picks) == n:
            break
    return picks


def search(real: RealTable, arena: Any, states: Any, *, space: ParameterSpace, base: Any,
           config: CalibrationConfig, runner: WalkRunner | None = None,
           screen: tuple[float | None, int | None] | None = None,
           reference: Reference | None = None) -> SearchResult:
    """Run the search (module docstring).

    ``arena``: an ArenaConfig (or name/path); ``states``: a discretizer object or states
    file; ``base``: the parameter record candidates modify (``PrimitiveParams`` or
    ``KinematicParams``); ``runner``: the simulation pool to use (default: one of its
    own); ``screen``: ``(hours, transitions)`` of a rung-0 walk (default from ``config``);
    ``reference``: the robot's signature (default: the real counts without regions).
    """
    from tqdm.auto import tqdm

    from simlab.physics.inputs import load_arena_config, load_discretizer

    disc = load_discretizer(states)
    ctx = walk_context(real, load_arena_config(arena), disc, space, base, config, config.seed,
                       screen, reference)
    sizes = rung_budgets(ctx["screen"], config.eta, config.rungs)
    counts = [config.candidates]
    for _ in range(1, config.rungs):
        counts.append(survivors(counts[-1], config.eta, config.confirm_top))
    own = runner is None
    runner = WalkRunner(int(config.workers), config.address) if runner is None else runner
    study = _study(config, space, base)
    dists = _distributions(space)
    cands: list[Candidate] = []
    try:
        bar = tqdm(total=config.candidates, unit="cand", disable=not config.progress,
                   desc=_rung_desc(0, config.rungs, sizes[0]))
        with bar:
            while len(cands) < config.candidates:
                n = min(config.batch, config.candidates - len(cands))
                trials = [study.ask(dists) for _ in range(n)]
                points = [space.unit(t.params) for t in trials]
                batch = evaluate_points(runner, points, "screen", len(cands), ctx,
                                        budget=sizes[0])
                for t, c in zip(trials, batch, strict=True):
                    study.tell(t, c.score)
                cands += batch
                bar.update(n)
                bar.set_postfix(best=f"{min(c.score for c in cands):.3f}")
        rungs = _promote(runner, cands, ctx, sizes, counts, config)
    finally:
        if own:
            runner.close()
    last = rungs[-1] if rungs else cands
    picks = _distinct_best(last, config.confirm_top)
    return SearchResult(candidates=cands, rungs=rungs, picks=picks,
                        importance=_importance(study, space), sizes=sizes)


def walk_size(size: tuple[float | None, int | None]) -> str:
    """One walk's ``(hours, transitions)`` in words, for the progress bars."""
    hours, transitions = size
    return f"{hours:g} h" if hours is not None else f"{transitions:,} transitions"


def _rung_desc(k: int, rungs: int, size: tuple[float | None, int | None]) -> str:
    return f"calibrate: rung {k + 1}/{rungs} ({walk_size(size)} a walk)"


def _promote(runner: WalkRunner, cands: list[Candidate], ctx: dict[str, Any],
             sizes: list[tuple[float | None, int | None]], counts: list[int],
             config: CalibrationConfig) -> list[list[Candidate]]:
    """The later rungs: the best of each rung walk the next rung's size on its seed
    (``seed + k``, common to the rung), scored on all their walks pooled."""
    from tqdm.auto import tqdm

    walks = {c.index: [c.sim] for c in cands}
    current = cands
    rungs: list[list[Candidate]] = []
    for k in range(1, len(sizes)):
        ids = _distinct_best(current, counts[k])
        by_index = {c.index: c for c in current}
        seed = config.seed + k
        bar = tqdm(total=len(ids), unit="cand", disable=not config.progress,
                   desc=_rung_desc(k, len(sizes), sizes[k]))
        out: list[Candidate] = []
        with bar:
            for i in range(0, len(ids), config.batch):
                chunk = ids[i:i + config.batch]
                jobs = walk_jobs([by_index[j].unit for j in chunk], [seed] * len(chunk), 0,
                                 ctx, sizes[k])
                for j, sim in zip(chunk, runner.map(jobs), strict=True):
                    walks[j].append(sim)
                    out.append(make_candidate(j, f"rung {k + 1}", by_index[j].unit,
                                              pool_tables(walks[j]), seed, ctx))
                bar.update(len(chunk))
                bar.set_postfix(best=f"{min(c.score for c in out):.3f}")
        rungs.append(out)
        current = out
    return rungs


def params_at(space: ParameterSpace, base: Any, unit: NDArray[np.float64]) -> Any:
    """``base`` with the fields of ``unit``; a value that only round-trips the unit cube
    back to the base's (within 1e-9) keeps the base's exact value."""
    values = space.values(unit)
    for name, v in values.items():
        b = getattr(base, name)
        if isinstance(v, float) and isinstance(b, int | float) and math.isclose(v, b,
                                                                               rel_tol=1e-9):
            values[name] = b
    return dataclasses.replace(base, **values)
