"""Search the simulator's primitive parameters that bring its T closest to a real one.

Each **candidate** is a point of a :class:`~simlab.calibration.space.ParameterSpace`. It is
evaluated by a random walk of ``hours_per_candidate`` simulated hours with
:func:`simlab.data.collect.collect` into a temporary directory, whose ``(s, a, s')`` rows
are counted in the **real** table's action set: the real action set says which simlab
primitive executes each real action (:meth:`ActionSet.to_primitive`). Decision: ``collect``
draws uniformly over all 16 primitives and has no option to restrict the walk, so rows of
primitives the real robot never had are dropped (an 8-action slow table uses half the
walk). The conditional T(s, a, .) of the kept actions is unchanged by that; only the visit
frequencies differ, and the distance weighs pairs by the *real* visits anyway.

**Common random numbers**: every candidate walks with the same seed, so the same action
sequence and the same noise draws; differences between candidates are the parameters, not
the luck of the draw.

**Optimiser** (derivative-free, seeded): the first candidate is the base record (today's
defaults, clipped into the space) so the report shows where calibration started; then a
scrambled Sobol design over the unit cube fills half of the budget; the rest is local
refinement in rounds of ``workers`` candidates: the minimum of a quadratic fitted by least
squares to the candidates nearest the best (it averages the walks' noise over many points),
then a compass search around the best point so far (``+- step`` along each coordinate, the
step shrinking by ``shrink`` after a full poll found nothing better). Candidates of a round run in parallel (one
process each, ``spawn``). The winner is then re-simulated with a fresh seed (``confirm``):
the distance reported for it is that independent run, free of the selection's luck.

**Decision latency** does not change T, only the rate of transitions; when the real table's
duration is known (``real.hours``) the calibrated latency is set in closed form so that the
simulated transitions per hour match: ``latency = 3600 * hours / n_real - mean duration``.
"""

from __future__ import annotations

import dataclasses
import math
import tempfile
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab import validation
from simlab.actions import ActionSet
from simlab.calibration.metrics import (
    Floor,
    TVResult,
    argmax_agreement,
    bootstrap_floor,
    cross_entropy,
    entropy_per_action,
    excess_distance,
    table_summary,
    tv_distance,
)
from simlab.calibration.space import ParameterSpace
from simlab.errors import ConfigError


@dataclass(frozen=True)
class RealTable:
    """The real robot's counts and what is known about them.

    Attributes:
        counts: ``(S, A, S)`` counts, ``A = action_set.n_actions``.
        action_set: meaning of the real actions.
        hours: duration the counts cover (h), if known (gives transitions per hour).
        blocked: number of blocked transitions, if the data records it.
        source: where the counts came from (for the report).
    """

    counts: NDArray[np.int64]
    action_set: ActionSet
    hours: float | None = None
    blocked: int | None = None
    source: str = ""

    def __post_init__(self) -> None:
        c = np.asarray(self.counts)
        if c.ndim != 3 or c.shape[0] != c.shape[2]:
            raise ConfigError(f"expected (S, A, S) counts, got shape {c.shape}", key="real")
        if c.shape[1] != self.action_set.n_actions:
            raise ConfigError(f"{c.shape[1]} actions in the counts, the action set has "
                              f"{self.action_set.n_actions}", key="real",
                              fix="give --n-actions matching the table")
        if c.sum() <= 0:
            raise ConfigError("the real table has no transition", key="real")
        if self.hours is not None and not (math.isfinite(self.hours) and self.hours > 0):
            raise ConfigError(f"must be > 0, got {self.hours}", key="real.hours")


@dataclass(frozen=True)
class CalibrationConfig:
    """Options of a calibration.

    Attributes:
        hours_per_candidate: simulated hours of each candidate's walk (> 0).
        candidates: number of candidates evaluated (>= 2), the base record included.
        workers: candidates simulated at once, one process each (1 = in this process).
            The refinement rounds have this many candidates, so the search is identical
            for the same (seed, workers), like ``collect``; the initial design is not
            affected.
        seed: the walks' seed (common to all candidates) and the optimiser's seed.
        simulator: ``"physics"`` or ``"kinematic"`` (physics-free dry runs and tests).
        pose_source: pose source of the walks (``truth``, ``odometry``, ``mcl``).
        shrink: factor of the refinement step per round (0 < shrink <= 1).
        step: initial refinement step, in unit-cube coordinates (> 0).
        n_boot: bootstrap resamples of the sampling floor.
        unvisited: rule for real pairs the simulation never tried (``report``/``max``).
        objective: what the search minimises: ``"excess"`` (default: the visit-weighted
            TV distance minus what sampling alone gives if the candidate were the truth,
            :func:`~simlab.calibration.metrics.excess_distance`), ``"tv"`` (the plain
            distance; with a few real visits per pair it favours too-certain simulators:
            on a 36-state kinematic lattice with 365 and 1,167 real transitions, two seeds
            each, hidden drive time 0.8 s was found at 0.45-0.64 s by ``tv`` and at
            0.65-1.17 s by ``excess``: no longer biased low, but as spread) or ``"loglik"``
            (bits per real transition under the simulated T,
            :func:`~simlab.calibration.metrics.cross_entropy`). The report always gives the
            plain TV distance.
        confirm: re-simulate the winner with another seed for the reported distance.
        progress: tqdm bar over candidates.
    """

    hours_per_candidate: float = 2.0
    candidates: int = 16
    workers: int = 2
    seed: int = 0
    simulator: str = "physics"
    pose_source: str = "truth"
    shrink: float = 0.6
    step: float = 0.15
    n_boot: int = 200
    unvisited: str = "report"
    objective: str = "excess"
    confirm: bool = True
    progress: bool = True

    def __post_init__(self) -> None:
        k = "calibration."
        validation.positive(self.hours_per_candidate, k + "hours_per_candidate")
        validation.whole(self.candidates, k + "candidates", minimum=2)
        validation.whole(self.workers, k + "workers", minimum=1)
        validation.whole(self.seed, k + "seed", minimum=0)
        validation.choice(self.simulator, ("physics", "kinematic"), k + "simulator")
        validation.number(self.shrink, k + "shrink", low=0.0, low_open=True, high=1.0)
        validation.positive(self.step, k + "step")
        validation.whole(self.n_boot, k + "n_boot", minimum=1)
        validation.choice(self.unvisited, ("report", "max"), k + "unvisited")
        validation.choice(self.objective, OBJECTIVES, k + "objective")


@dataclass(frozen=True)
class _Job:
    index: int
    arena: Any
    states: Any
    params: Any
    hours: float
    seed: int
    simulator: str
    pose_source: str
    primitives: tuple[int, ...]
    n_states: int


@dataclass(frozen=True)
class SimTable:
    """A candidate's walk counted in the real action set.

    Attributes:
        counts: ``(S, A_real, S)`` counts of the kept rows.
        rows: kept rows (actions the real set has); ``walk_rows`` all rows of the walk.
        blocked: blocked rows among the kept ones.
        mean_duration: mean stepped duration (s) of the kept rows (no idle time).
        hours: time of the kept rows with the decision latency (h): the duration of a
            walk that used only the real actions.
        wall_seconds: wall time of the evaluation.
    """

    counts: NDArray[np.int64]
    rows: int
    walk_rows: int
    blocked: int
    mean_duration: float
    hours: float
    wall_seconds: float


def simulate_table(job: _Job) -> SimTable:
    """Collect one walk into a temporary directory and count it (runs in a worker)."""
    from simlab.data.collect import collect
    from simlab.data.dataset import read_dataset
    from simlab.data.estimate import count_transitions

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="simlab-cal-") as tmp:
        collect(job.arena, job.states, out=Path(tmp) / "walk", hours=job.hours, seed=job.seed,
                workers=1, simulator=job.simulator, pose_source=job.pose_source,
                params=job.params, progress=False)
        table = read_dataset(Path(tmp) / "walk", validate=False)
        s = table.column("s").to_numpy()
        a = table.column("a").to_numpy()
        s_next = table.column("s_next").to_numpy()
        blocked = table.column("blocked").to_numpy(zero_copy_only=False)
        duration = table.column("duration").to_numpy()
    to_real = np.full(16, -1, dtype=np.int64)
    to_real[list(job.primitives)] = np.arange(len(job.primitives))
    real_a = to_real[a]
    keep = real_a >= 0
    counts = count_transitions(s[keep], real_a[keep], s_next[keep], job.n_states,
                               len(job.primitives))
    latency = float(job.params.decision_latency)
    kept = int(keep.sum())
    return SimTable(counts=counts, rows=kept, walk_rows=int(a.size),
                    blocked=int(blocked[keep].sum()),
                    mean_duration=float(duration[keep].mean()) if kept else float("nan"),
                    hours=float((duration[keep] + latency).sum()) / 3600.0,
                    wall_seconds=time.perf_counter() - t0)


def simulate_counts(arena: Any, states: Any, params: Any, *, hours: float, seed: int,
                    action_set: ActionSet, simulator: str = "physics",
                    pose_source: str = "truth") -> SimTable:
    """One walk of ``hours`` simulated hours counted in ``action_set`` (in this process).

    What a candidate's evaluation does; also a way to make a synthetic "real" table with
    hidden parameters (tests, benchmarks).
    """
    from simlab.physics.inputs import load_arena_config, load_discretizer

    disc = load_discretizer(states)
    return simulate_table(_Job(index=0, arena=load_arena_config(arena), states=disc,
                               params=params, hours=float(hours), seed=int(seed),
                               simulator=simulator, pose_source=pose_source,
                               primitives=tuple(int(p) for p in action_set.primitives()),
                               n_states=int(disc.n_states)))


@dataclass(frozen=True)
class Candidate:
    """One evaluated point: ``unit`` ``(d,)`` in the unit cube, ``values`` by name."""

    index: int
    stage: str
    unit: NDArray[np.float64]
    values: dict[str, float]
    distance: float
    sim: SimTable
    tv: TVResult
    score: float


@dataclass(frozen=True)
class CalibrationResult:
    """Everything the reports need (see :mod:`simlab.calibration.report`).

    ``params`` is the calibrated record (best candidate, latency fitted when possible);
    ``final`` the confirming run of it (or the best candidate's own run without confirm).
    ``floor``: bootstrap floor of the real counts; ``matched_floor``: the same for a
    perfect simulator with ``final``'s visit counts.
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
    #: the starting point re-simulated on the confirmation seed (None without ``confirm``)
    start_confirmed: Candidate | None = None


class _Runner:
    """Simulates candidate tables on the one parallel layer: in this process for one
    worker, else a :class:`~simlab.parallel.LocalExecutor` pool (one arena per process,
    workers exit with us); tables come back in job order."""

    def __init__(self, workers: int) -> None:
        from simlab.parallel import LocalExecutor

        self._executor = LocalExecutor(workers)

    def map(self, jobs: list[_Job]) -> list[SimTable]:
        return self._executor.map(simulate_table, [{"job": j} for j in jobs])

    def close(self) -> None:
        self._executor.close()


def _sobol(dim: int, n: int, rng: np.random.Generator) -> NDArray[np.float64]:
    from scipy.stats import qmc

    with warnings.catch_warnings():  # balance warning for n not a power of 2: harmless here
        warnings.simplefilter("ignore")
        return qmc.Sobol(dim, scramble=True, seed=rng).random(max(n, 0))


def _base_point(space: ParameterSpace, base: Any) -> NDArray[np.float64]:
    return space.unit({n: float(getattr(base, n)) for n in space.names})


#: What the search may minimise (:class:`CalibrationConfig.objective`).
OBJECTIVES = ("tv", "excess", "loglik")


def _score(cfg: CalibrationConfig, sim: NDArray[np.int64], real: NDArray[np.int64],
           distance: float) -> float:
    if cfg.objective == "tv":
        return distance
    if cfg.objective == "loglik":
        return cross_entropy(sim, real)
    # excess: every candidate's resamples draw from the same seeded stream (common random
    # numbers, as for the walks: differences between candidates are parameters, not noise)
    rng = np.random.default_rng(np.random.SeedSequence(cfg.seed, spawn_key=(7,)))
    e = excess_distance(sim, real, rng, unvisited=cfg.unvisited, n_boot=64)
    return e if math.isfinite(e) else 1.0


def _evaluate(runner: _Runner, points: list[NDArray[np.float64]], stage: str, start: int,
              ctx: dict[str, Any]) -> list[Candidate]:
    space: ParameterSpace = ctx["space"]
    cfg: CalibrationConfig = ctx["config"]
    jobs = [_Job(index=start + i, arena=ctx["arena"], states=ctx["states"],
                 params=space.apply(ctx["base"], u), hours=cfg.hours_per_candidate,
                 seed=ctx["walk_seed"], simulator=cfg.simulator, pose_source=cfg.pose_source,
                 primitives=ctx["primitives"], n_states=ctx["n_states"]) for i, u in
            enumerate(points)]
    out = []
    for job, u, sim in zip(jobs, points, runner.map(jobs), strict=True):
        tv = tv_distance(sim.counts, ctx["real"].counts, unvisited=cfg.unvisited)
        d = tv.distance if math.isfinite(tv.distance) else 1.0
        score = _score(cfg, sim.counts, ctx["real"].counts, d)
        out.append(Candidate(job.index, stage, np.asarray(u), space.values(u), d, sim, tv,
                             score))
    return out


def _quadratic_features(u: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(n, 1 + d + d(d+1)/2)`` features of a full quadratic in the unit coordinates."""
    d = u.shape[1]
    cols = [np.ones(len(u))] + [u[:, i] for i in range(d)]
    cols += [u[:, i] * u[:, j] for i in range(d) for j in range(i, d)]
    return np.stack(cols, axis=1)


def _surrogate_minimum(cands: list[Candidate], rng: np.random.Generator
                       ) -> NDArray[np.float64] | None:
    """Minimum of a least-squares quadratic fitted to the candidates nearest the best.

    Averages the walks' noise over many points, which a single best point cannot. Fitted
    to the ``3 p`` candidates nearest the best (``p`` quadratic terms), minimised over 2,000
    seeded points of their bounding box; None until there are enough candidates.
    """
    u = np.array([c.unit for c in cands])
    y = np.array([c.score for c in cands])
    p = _quadratic_features(u[:1]).shape[1]
    if len(cands) < p + 2:
        return None
    best = u[int(np.argmin(y))]
    near = np.argsort(np.linalg.norm(u - best, axis=1))[:3 * p]
    coef, *_ = np.linalg.lstsq(_quadratic_features(u[near]), y[near], rcond=None)
    lo, hi = u[near].min(axis=0), u[near].max(axis=0)
    cloud = lo + (hi - lo) * rng.random((2000, u.shape[1]))
    return cloud[int(np.argmin(_quadratic_features(cloud) @ coef))]


class _Poll:
    """Compass search around the best point, with the surrogate's minimum first.

    Each round takes the surrogate minimum (if new) and then the next of the ``2 d`` poll
    points ``best +- step e_i`` (in a seeded order). A new best restarts the poll around it;
    a full poll without improvement multiplies ``step`` by ``shrink``.
    """

    def __init__(self, step: float, shrink: float, rng: np.random.Generator) -> None:
        self.step, self.shrink, self.rng = float(step), float(shrink), rng
        self.centre: NDArray[np.float64] | None = None
        self.queue: list[NDArray[np.float64]] = []

    def _refill(self, best: NDArray[np.float64]) -> None:
        if self.centre is not None and np.array_equal(self.centre, best):
            self.step *= self.shrink  # the whole poll failed: look closer
        self.centre = best.copy()
        d = best.size
        moves = [s * self.step * np.eye(d)[i] for i in range(d) for s in (1.0, -1.0)]
        order = self.rng.permutation(len(moves))
        self.queue = [np.clip(best + moves[k], 0.0, 1.0) for k in order]

    def propose(self, cands: list[Candidate], best: NDArray[np.float64],
                n: int) -> list[NDArray[np.float64]]:
        if self.centre is None or not np.array_equal(self.centre, best):
            self.centre = None
            self._refill(best)
        seen = [c.unit for c in cands]
        points: list[NDArray[np.float64]] = []
        surrogate = _surrogate_minimum(cands, self.rng)
        if surrogate is not None and not any(np.allclose(surrogate, u, atol=1e-3)
                                             for u in seen):
            points.append(surrogate)
        while len(points) < n:
            if not self.queue:
                self._refill(best)
            q = self.queue.pop(0)
            if not any(np.allclose(q, u, atol=1e-9) for u in seen + points):
                points.append(q)
        return points


def _context(real: RealTable, arena: Any, disc: Any, space: ParameterSpace, base: Any,
             config: CalibrationConfig, walk_seed: int) -> dict[str, Any]:
    return {"space": space, "config": config, "arena": arena, "states": disc, "base": base,
            "walk_seed": int(walk_seed), "real": real, "n_states": int(disc.n_states),
            "primitives": tuple(int(p) for p in real.action_set.primitives())}


def _rounds(rng: np.random.Generator, cfg: CalibrationConfig, space: ParameterSpace,
            base_u: NDArray[np.float64]) -> tuple[list[NDArray[np.float64]], int]:
    """The base point plus the Sobol design: ``(points, n_refine)``."""
    n_init = max(1, cfg.candidates // 2 - 1)
    design = [np.clip(base_u, 0.0, 1.0), *_sobol(space.dim, n_init, rng)]
    return design, cfg.candidates - len(design)


def search(real: RealTable, arena: Any, states: Any, *, space: ParameterSpace, base: Any,
           config: CalibrationConfig) -> tuple[list[Candidate], int]:
    """Run the optimiser (module docstring); returns all candidates and the best's index.

    ``arena``: an ArenaConfig (or name/path); ``states``: a discretizer object or states
    file; ``base``: the parameter record candidates modify (``PrimitiveParams`` or
    ``KinematicParams``).
    """
    from tqdm.auto import tqdm

    from simlab.physics.inputs import load_arena_config, load_discretizer

    rng = np.random.default_rng(np.random.SeedSequence(config.seed).spawn(1)[0])
    disc = load_discretizer(states)
    ctx = _context(real, load_arena_config(arena), disc, space, base, config, config.seed)
    design, n_refine = _rounds(rng, config, space, _base_point(space, base))
    runner = _Runner(int(config.workers))
    bar = tqdm(total=config.candidates, desc="calibrate", unit="cand",
               disable=not config.progress)
    try:
        cands: list[Candidate] = []
        for i in range(0, len(design), config.workers):
            batch = _evaluate(runner, design[i:i + config.workers], "init", len(cands), ctx)
            cands += batch
            bar.update(len(batch))
            bar.set_postfix(best=f"{min(c.score for c in cands):.3f}")
        poll = _Poll(config.step, config.shrink, rng)
        while n_refine > 0:
            best = min(cands, key=lambda c: c.score)
            n = min(config.workers, n_refine)
            points = poll.propose(cands, best.unit, n)
            batch = _evaluate(runner, points, "refine", len(cands), ctx)
            cands += batch
            n_refine -= n
            bar.update(n)
            bar.set_postfix(best=f"{min(c.score for c in cands):.3f}")
    finally:
        bar.close()
        runner.close()
    best_index = min(range(len(cands)), key=lambda i: (cands[i].score, i))
    return cands, best_index


def _fit_latency(params: Any, real: RealTable, sim: SimTable) -> tuple[Any, bool]:
    if real.hours is None or not math.isfinite(sim.mean_duration):
        return params, False
    per_transition = real.hours * 3600.0 / float(real.counts.sum())
    latency = per_transition - sim.mean_duration
    if latency < 0:
        return params, False
    return dataclasses.replace(params, decision_latency=float(latency)), True


def calibrate(real: RealTable, arena: Any, states: Any, *, space: ParameterSpace | None = None,
              base: Any = None, config: CalibrationConfig | None = None) -> CalibrationResult:
    """Calibrate the primitive parameters against ``real`` (module docstring).

    Args:
        real: the real counts and their action set.
        arena: built-in arena name, TOML path or ArenaConfig.
        states: states file (JSON of ``simlab discretize``) or a discretizer object; its
            number of states must equal the real table's S.
        space: searched fields (default :func:`~simlab.calibration.space.default_space`).
        base: record the candidates modify (default: the simulator's default record).
        config: :class:`CalibrationConfig` (defaults if None).

    Raises:
        ConfigError: inconsistent inputs, before any simulation.
    """
    from simlab.calibration.space import default_space
    from simlab.data.walkers import check_pose_source
    from simlab.physics.inputs import load_arena_config, load_discretizer

    config = CalibrationConfig() if config is None else config
    t0 = time.perf_counter()
    check_pose_source(config.pose_source, config.simulator)
    arena_cfg = load_arena_config(arena)
    disc = load_discretizer(states)
    if int(disc.n_states) != real.counts.shape[0]:
        raise ConfigError(f"the states file has {disc.n_states} states, the real table "
                          f"{real.counts.shape[0]}", key="states",
                          fix="use the centres the real robot's states were numbered by")
    base = default_base(config.simulator) if base is None else base
    space = default_space(real.action_set.primitives(), config.simulator) if space is None \
        else space
    space.check_fields(base)
    cands, best = search(real, arena_cfg, disc, space=space, base=base, config=config)
    params = space.apply(base, cands[best].unit)
    final = cands[best]
    start = None
    notes = []
    if config.confirm:
        # the winner of a noisy search is flattered by its own seed: re-simulate it AND the
        # starting point on a fresh seed, and keep the start unless the winner beats it there
        ctx = _context(real, arena_cfg, disc, space, base, config, config.seed + 1)
        units = [cands[best].unit] + ([cands[0].unit] if best != 0 else [])
        runner = _Runner(min(len(units), config.workers))
        try:
            confirmed = _evaluate(runner, units, "confirm", len(cands), ctx)
        finally:
            runner.close()
        final, start = confirmed[0], confirmed[-1]
        notes.append(f"distance of the best candidate on the search seed "
                     f"{cands[best].distance:.4f}; on a fresh seed {final.distance:.4f} "
                     f"(the starting point there: {start.distance:.4f})")
        if best != 0 and start.score <= final.score:
            notes.append("on the fresh seed the starting point scores at least as well as "
                         "the search's best: the search found no better parameters, the "
                         "starting point is kept")
            best, final = 0, start
            params = space.apply(base, cands[0].unit)
    params, fitted = _fit_latency(params, real, final.sim)
    rng = np.random.default_rng(np.random.SeedSequence(config.seed).spawn(2)[1])
    floor = bootstrap_floor(real.counts, rng, n_boot=config.n_boot)
    matched = bootstrap_floor(real.counts, rng, n_boot=config.n_boot,
                              other_n=final.sim.counts.sum(axis=2))
    sim_hours = final.sim.hours
    if fitted:
        sim_hours = final.sim.rows * (final.sim.mean_duration + params.decision_latency) / 3600
    return CalibrationResult(
        config=config, space=space, base=base, params=params, candidates=cands, best=best,
        final=final, floor=floor, matched_floor=matched, real=real,
        real_summary=table_summary(real.counts, hours=real.hours, blocked=real.blocked),
        sim_summary=table_summary(final.sim.counts, hours=sim_hours, blocked=final.sim.blocked),
        agreement=argmax_agreement(final.sim.counts, real.counts),
        entropy_real=entropy_per_action(real.counts),
        entropy_sim=entropy_per_action(final.sim.counts),
        latency_fitted=fitted, wall_seconds=time.perf_counter() - t0, notes=notes,
        start_confirmed=start,
    )


def default_base(simulator: str) -> Any:
    """Default parameter record of a simulator (``PrimitiveParams``/``KinematicParams``)."""
    if simulator == "kinematic":
        from simlab.data.walkers import KinematicParams

        return KinematicParams()
    from simlab.physics.motion import PrimitiveParams

    return PrimitiveParams()
