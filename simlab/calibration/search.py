"""Search the simulator's primitive parameters that bring its T closest to a real one.

Each **candidate** is a point of a :class:`~simlab.calibration.space.ParameterSpace`. It is
evaluated by a random walk with :func:`simlab.data.collect.collect` into a temporary
directory, in the **real** table's action set (the walk draws only the primitives of the
real actions, :meth:`ActionSet.primitives`, and records them in the real numbering) and,
by default, from every state's centre in turn (``start_states = "all"``: one walk per
state, the budget split evenly), so that the walk covers the lab as the real data do.
Every real ``(s, a)`` pair counts in the distance: a pair the walk never tried is a full
miss (``unvisited = "max"``), so a candidate cannot win by covering less.

**Budgets** are sized from the real table (:func:`size_budgets`): the screening walks have
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
import tempfile
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.base import validation
from simlab.base.actions import SIMLAB16, ActionSet
from simlab.base.errors import ConfigError, warn
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
from simlab.calibration.signature import (
    Signature,
    reach_warnings,
    real_signature,
    self_share_warning,
    signature_base,
    used_speed_field,
)
from simlab.calibration.space import ParameterSpace


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
        hours_per_candidate: simulated hours of each screening walk (> 0); None (default)
            sizes it from the real table: ``screen_share`` of its transitions.
        candidates: number of candidates screened (>= 2), the starting point included.
        workers: walks simulated at once, one process each (1 = in this process).
            The refinement rounds have this many candidates, so the search is identical
            for the same (seed, workers), like ``collect``; the initial design is not
            affected.
        seed: the walks' seed (common to all candidates) and the optimiser's seed; the
            confirming and twin walks use ``seed + 1``, ``seed + 2``, ...
        simulator: ``"physics"`` or ``"kinematic"`` (physics-free dry runs and tests).
        pose_source: pose source of the walks (``truth``, ``odometry``, ``mcl``); the
            localization error of a real robot's states is searched as ``pose_noise_xy``.
        shrink: factor of the refinement step per round (0 < shrink <= 1).
        step: initial refinement step, in unit-cube coordinates (> 0).
        n_boot: bootstrap resamples of the sampling floor.
        unvisited: real pairs the simulation never tried: ``"max"`` (default: a full miss,
            TV = 1, so covering less never pays) or ``"report"`` (left out of the mean and
            counted in the report).
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
        confirm: re-simulate the best candidates on fresh seeds and pick the winner there.
        progress: tqdm bar over candidates.
        screen_share: screening walk size as a share of the real transitions (> 0; used
            when ``hours_per_candidate`` is None).
        confirm_hours: simulated hours of each confirming walk; None (default) sizes it
            from the matched floor (:func:`size_budgets`).
        confirm_top: screened candidates confirmed (>= 1), besides the starting point.
        confirm_seeds: fresh seeds each confirmed candidate walks (>= 1).
        transfer_seeds: twin seeds of the transfer report (0 = no transfer report).
        start_states: where the walks start: ``"all"`` (default: one walk per state),
            a list of states, or None (the arena's start pose).
        address: Ray cluster address: the walks run as Ray tasks there (default: local
            processes).
        goal_states: goal states of the transfer report (default: every state).
    """

    hours_per_candidate: float | None = None
    candidates: int = 16
    workers: int = 2
    seed: int = 0
    simulator: str = "physics"
    pose_source: str = "truth"
    shrink: float = 0.6
    step: float = 0.15
    n_boot: int = 200
    unvisited: str = "max"
    objective: str = "excess"
    confirm: bool = True
    progress: bool = True
    screen_share: float = 0.25
    confirm_hours: float | None = None
    confirm_top: int = 2
    confirm_seeds: int = 1
    transfer_seeds: int = 5
    start_states: Any = "all"
    address: str | None = None
    goal_states: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        k = "calibration."
        if self.hours_per_candidate is not None:
            validation.positive(self.hours_per_candidate, k + "hours_per_candidate")
        if self.confirm_hours is not None:
            validation.positive(self.confirm_hours, k + "confirm_hours")
        validation.positive(self.screen_share, k + "screen_share")
        validation.whole(self.candidates, k + "candidates", minimum=2)
        validation.whole(self.workers, k + "workers", minimum=1)
        validation.whole(self.seed, k + "seed", minimum=0)
        validation.choice(self.simulator, ("physics", "kinematic"), k + "simulator")
        validation.number(self.shrink, k + "shrink", low=0.0, low_open=True, high=1.0)
        validation.positive(self.step, k + "step")
        validation.whole(self.n_boot, k + "n_boot", minimum=1)
        validation.choice(self.unvisited, ("report", "max"), k + "unvisited")
        validation.choice(self.objective, OBJECTIVES, k + "objective")
        validation.whole(self.confirm_top, k + "confirm_top", minimum=1)
        validation.whole(self.confirm_seeds, k + "confirm_seeds", minimum=1)
        validation.whole(self.transfer_seeds, k + "transfer_seeds", minimum=0)
        if self.start_states is not None:
            from simlab.data.collect import parse_start_states

            parse_start_states(self.start_states, None)
        if self.goal_states is not None:
            object.__setattr__(self, "goal_states", tuple(
                validation.whole(g, k + "goal_states", minimum=0) for g in self.goal_states))


@dataclass(frozen=True)
class _Job:
    index: int
    arena: Any
    states: Any
    params: Any
    hours: float | None
    transitions: int | None
    seed: int
    simulator: str
    pose_source: str
    action_set: ActionSet
    start_states: Any
    n_states: int


@dataclass(frozen=True)
class SimTable:
    """A candidate's walk, in the real action set.

    Attributes:
        counts: ``(S, A_real, S)`` counts.
        rows: transitions of the walk; ``walk_rows`` the same (the walk draws only the
            real actions' primitives).
        blocked: blocked transitions.
        mean_duration: mean stepped duration (s) of a transition (no idle time).
        hours: time of the walk with the decision latency (h).
        wall_seconds: wall time of the evaluation.
    """

    counts: NDArray[np.int64]
    rows: int
    walk_rows: int
    blocked: int
    mean_duration: float
    hours: float
    wall_seconds: float


def _action_set_options(aset: ActionSet) -> dict[str, Any]:
    """``collect``'s action-set fields for ``aset`` (none for simlab's 16)."""
    if aset == SIMLAB16:
        return {}
    return {"n_actions": aset.n_actions, "speed": aset.speed,
            "convention": ",".join(str(d) for d in aset.directions)}


def simulate_table(job: _Job) -> SimTable:
    """Collect one walk into a temporary directory and count it (runs in a worker)."""
    from simlab.data.collect import collect
    from simlab.data.dataset import read_dataset
    from simlab.data.estimate import count_transitions

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="simlab-cal-") as tmp:
        collect(job.arena, job.states, out=Path(tmp) / "walk", hours=job.hours,
                transitions=job.transitions, seed=job.seed, workers=1,
                simulator=job.simulator, pose_source=job.pose_source, params=job.params,
                start_states=job.start_states, progress=False,
                **_action_set_options(job.action_set))
        table = read_dataset(Path(tmp) / "walk", validate=False)
        s = table.column("s").to_numpy()
        a = table.column("a").to_numpy()
        s_next = table.column("s_next").to_numpy()
        blocked = table.column("blocked").to_numpy(zero_copy_only=False)
        duration = table.column("duration").to_numpy()
    counts = count_transitions(s, a, s_next, job.n_states, job.action_set.n_actions)
    latency = float(job.params.decision_latency)
    rows = int(a.size)
    return SimTable(counts=counts, rows=rows, walk_rows=rows, blocked=int(blocked.sum()),
                    mean_duration=float(duration.mean()) if rows else float("nan"),
                    hours=float((duration + latency).sum()) / 3600.0,
                    wall_seconds=time.perf_counter() - t0)


def simulate_counts(arena: Any, states: Any, params: Any, *, hours: float | None = None,
                    transitions: int | None = None, seed: int, action_set: ActionSet,
                    simulator: str = "physics", pose_source: str = "truth",
                    start_states: Any = None) -> SimTable:
    """One walk of ``hours`` simulated hours (or ``transitions``) in ``action_set``, in
    this process.

    What a candidate's evaluation does; also a way to make a synthetic "real" table with
    hidden parameters (tests, benchmarks).
    """
    from simlab.physics.inputs import load_arena_config, load_discretizer

    disc = load_discretizer(states)
    return simulate_table(_Job(index=0, arena=load_arena_config(arena), states=disc,
                               params=params, hours=None if hours is None else float(hours),
                               transitions=None if transitions is None else int(transitions),
                               seed=int(seed), simulator=simulator, pose_source=pose_source,
                               action_set=action_set, start_states=start_states,
                               n_states=int(disc.n_states)))


def pool_tables(tables: list[SimTable]) -> SimTable:
    """The walks of ``tables`` as one table (counts and rows summed)."""
    rows = sum(t.rows for t in tables)
    dur = sum(t.mean_duration * t.rows for t in tables if t.rows)
    return SimTable(counts=sum(t.counts for t in tables), rows=rows,
                    walk_rows=sum(t.walk_rows for t in tables),
                    blocked=sum(t.blocked for t in tables),
                    mean_duration=dur / rows if rows else float("nan"),
                    hours=sum(t.hours for t in tables),
                    wall_seconds=sum(t.wall_seconds for t in tables))


@dataclass(frozen=True)
class Candidate:
    """One evaluated point: ``unit`` ``(d,)`` in the unit cube, ``values`` by name.
    ``stage``: ``init``/``refine`` (screening), ``confirm`` (one confirming walk),
    ``pooled`` (a candidate's confirming walks as one table) or ``twin``."""

    index: int
    stage: str
    unit: NDArray[np.float64]
    values: dict[str, Any]
    distance: float
    sim: SimTable
    tv: TVResult
    score: float
    seed: int = 0


@dataclass(frozen=True)
class Budgets:
    """Walk sizes of a calibration (:func:`size_budgets`).

    Attributes:
        screen_hours, screen_transitions: one screening walk (one of the two is None).
        confirm_hours, confirm_transitions: one confirming (and twin) walk.
        multiple: confirming transitions / real transitions (None with ``confirm_hours``).
        table: ``[(multiple of the real transitions, matched floor median)]``: the distance
            a perfect simulator would show with that many transitions.
    """

    screen_hours: float | None
    screen_transitions: int | None
    confirm_hours: float | None
    confirm_transitions: int | None
    multiple: float | None
    table: list[tuple[float, float]]

    def to_json(self) -> dict[str, Any]:
        return {"screen_hours": self.screen_hours,
                "screen_transitions": self.screen_transitions,
                "confirm_hours": self.confirm_hours,
                "confirm_transitions": self.confirm_transitions,
                "confirm_multiple_of_real": self.multiple,
                "matched_floor_by_multiple": [
                    {"multiple": m, "matched_floor": None if not math.isfinite(f) else f}
                    for m, f in self.table]}


#: Multiples of the real transitions tried for the confirming budget, and the tolerance:
#: the smallest multiple whose matched floor is within 35 % of the real bootstrap floor.
#: (On a 38-state lab with 5,300 real transitions: 1.5 x, matched floor 1.32 x the floor; a
#: 25 % tolerance asks 2 x, which doubles the confirming and twin walks for 7 % less floor.)
BUDGET_MULTIPLES = (0.25, 0.5, 1.0, 1.5, 2.0, 3.0)
BUDGET_TOLERANCE = 1.35


def screen_budget(config: CalibrationConfig, real_transitions: int
                  ) -> tuple[float | None, int | None]:
    """``(hours, transitions)`` of a screening walk: ``hours_per_candidate`` when given,
    else ``screen_share`` of the real transitions."""
    if config.hours_per_candidate is not None:
        return config.hours_per_candidate, None
    return None, max(1, round(config.screen_share * real_transitions))


def size_budgets(real: RealTable, config: CalibrationConfig, floor: Floor,
                 rng: np.random.Generator) -> Budgets:
    """Walk sizes from the real table (module docstring).

    A perfect simulator run for ``m`` times the real transitions (each real pair visited
    ``m`` times as often) lies at the matched floor from the real table; the confirming
    walks take the smallest ``m`` of :data:`BUDGET_MULTIPLES` (at least 1) whose matched
    floor is within :data:`BUDGET_TOLERANCE` of the bootstrap floor, so that a good twin
    can be told from a perfect one only by differences larger than sampling.
    """
    n = real.counts.sum(axis=2)
    total = int(n.sum())
    table = []
    for m in BUDGET_MULTIPLES:
        other = np.where(n > 0, np.maximum(np.rint(n * m), 1), 0).astype(np.int64)
        mf = bootstrap_floor(real.counts, rng, n_boot=min(config.n_boot, 40), other_n=other)
        table.append((m, mf.median))
    good = [m for m, f in table if m >= 1.0 and f <= BUDGET_TOLERANCE * floor.median]
    multiple = good[0] if good else BUDGET_MULTIPLES[-1]
    screen_h, screen_n = screen_budget(config, total)
    if config.confirm_hours is not None:
        return Budgets(screen_h, screen_n, config.confirm_hours, None, None, table)
    return Budgets(screen_h, screen_n, None, max(1, round(multiple * total)), multiple, table)


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


class _Runner:
    """Simulates candidate tables on the one parallel layer (:mod:`simlab.base.parallel`): in
    this process for one worker, else a pool of ``workers`` processes (one arena per
    process, workers exit with us), or Ray tasks on ``address``; tables come back in job
    order."""

    def __init__(self, workers: int, address: str | None = None) -> None:
        from simlab.base.parallel import make_executor

        if address is not None:
            self._executor = make_executor("ray", address=address)
        else:
            self._executor = make_executor("local", workers=workers)

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
    return space.unit({n: getattr(base, n) for n in space.names})


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


def _candidate(index: int, stage: str, u: NDArray[np.float64], sim: SimTable, seed: int,
               ctx: dict[str, Any]) -> Candidate:
    cfg: CalibrationConfig = ctx["config"]
    tv = tv_distance(sim.counts, ctx["real"].counts, unvisited=cfg.unvisited)
    d = tv.distance if math.isfinite(tv.distance) else 1.0
    score = _score(cfg, sim.counts, ctx["real"].counts, d)
    return Candidate(index, stage, np.asarray(u), ctx["space"].values(u), d, sim, tv, score,
                     seed)


def _evaluate(runner: _Runner, points: list[NDArray[np.float64]], stage: str, start: int,
              ctx: dict[str, Any], seeds: list[int] | None = None,
              budget: tuple[float | None, int | None] | None = None) -> list[Candidate]:
    """Simulate ``points`` (on ``seeds``, default the search's walk seed, and ``budget``
    ``(hours, transitions)``, default the screening budget) and score them."""
    space: ParameterSpace = ctx["space"]
    cfg: CalibrationConfig = ctx["config"]
    seeds = [ctx["walk_seed"]] * len(points) if seeds is None else seeds
    hours, transitions = ctx["screen"] if budget is None else budget
    jobs = [_Job(index=start + i, arena=ctx["arena"], states=ctx["states"],
                 params=space.apply(ctx["base"], u), hours=hours, transitions=transitions,
                 seed=seed, simulator=cfg.simulator, pose_source=cfg.pose_source,
                 action_set=ctx["real"].action_set, start_states=cfg.start_states,
                 n_states=ctx["n_states"])
            for i, (u, seed) in enumerate(zip(points, seeds, strict=True))]
    return [_candidate(job.index, stage, u, sim, job.seed, ctx)
            for job, u, sim in zip(jobs, points, runner.map(jobs), strict=True)]


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
             config: CalibrationConfig, walk_seed: int,
             screen: tuple[float | None, int | None] | None = None) -> dict[str, Any]:
    if screen is None:
        screen = screen_budget(config, int(real.counts.sum()))
    return {"space": space, "config": config, "arena": arena, "states": disc, "base": base,
            "walk_seed": int(walk_seed), "real": real, "n_states": int(disc.n_states),
            "screen": screen}


def _rounds(rng: np.random.Generator, cfg: CalibrationConfig, space: ParameterSpace,
            base_u: NDArray[np.float64]) -> tuple[list[NDArray[np.float64]], int]:
    """The base point plus the Sobol design: ``(points, n_refine)``."""
    n_init = max(1, cfg.candidates // 2 - 1)
    design = [np.clip(base_u, 0.0, 1.0), *_sobol(space.dim, n_init, rng)]
    return design, cfg.candidates - len(design)


def search(real: RealTable, arena: Any, states: Any, *, space: ParameterSpace, base: Any,
           config: CalibrationConfig, runner: _Runner | None = None,
           screen: tuple[float | None, int | None] | None = None
           ) -> tuple[list[Candidate], int]:
    """Run the optimiser (module docstring); returns all candidates and the best's index.

    ``arena``: an ArenaConfig (or name/path); ``states``: a discretizer object or states
    file; ``base``: the parameter record candidates modify (``PrimitiveParams`` or
    ``KinematicParams``); ``runner``: the simulation pool to use (default: one of its
    own); ``screen``: ``(hours, transitions)`` of a walk (default from ``config``).
    """
    from tqdm.auto import tqdm

    from simlab.physics.inputs import load_arena_config, load_discretizer

    rng = np.random.default_rng(np.random.SeedSequence(config.seed).spawn(1)[0])
    disc = load_discretizer(states)
    ctx = _context(real, load_arena_config(arena), disc, space, base, config, config.seed,
                   screen)
    design, n_refine = _rounds(rng, config, space, _base_point(space, base))
    own = runner is None
    runner = _Runner(int(config.workers), config.address) if runner is None else runner
    bar = tqdm(total=config.candidates, desc="calibrate: screen", unit="cand",
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
        if own:
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
    return _candidate(index, "pooled", runs[0].unit, pool_tables([r.sim for r in runs]),
                      runs[0].seed, ctx)


def _confirm(runner: _Runner, cands: list[Candidate], ctx: dict[str, Any],
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
        done = _evaluate(runner, [cands[i].unit for i, _ in chunk], "confirm", 0, ctx,
                         seeds=[seed for _, seed in chunk], budget=budget)
        for (i, _), c in zip(chunk, done, strict=True):
            runs[i].append(dataclasses.replace(c, index=i))
        bar.update(len(chunk))
    mean = {i: float(np.mean([c.score for c in runs[i]])) for i in picks}
    return min(picks, key=lambda i: (mean[i], i)), runs


def _twins(runner: _Runner, winner: Candidate, confirmed: list[Candidate],
           ctx: dict[str, Any], budget: tuple[float | None, int | None], bar: Any
           ) -> list[Candidate]:
    """The transfer report's twin walks: the winner's confirming walks, then fresh seeds."""
    cfg: CalibrationConfig = ctx["config"]
    twins = [dataclasses.replace(c, stage="twin") for c in confirmed][:cfg.transfer_seeds]
    extra = cfg.transfer_seeds - len(twins)
    if extra > 0:
        seeds = [cfg.seed + 1 + cfg.confirm_seeds + k for k in range(extra)]
        done = _evaluate(runner, [winner.unit] * extra, "twin", winner.index, ctx,
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
    runner = _Runner(int(config.workers), config.address)
    try:
        cands, screen_best = search(real, setup.arena, setup.disc, space=setup.space,
                                    base=setup.base, config=config, runner=runner,
                                    screen=screen)
        ctx = _context(real, setup.arena, setup.disc, setup.space, setup.base, config,
                       config.seed, screen)
        done = _Confirmed(best=screen_best, final=cands[screen_best])
        if config.confirm:
            done = _confirm_stage(runner, cands, screen_best, ctx,
                                  (budgets.confirm_hours, budgets.confirm_transitions))
    finally:
        runner.close()
    params, fitted = _fit_latency(_params_at(setup.space, setup.base, cands[done.best].unit),
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


def _confirm_stage(runner: _Runner, cands: list[Candidate], screen_best: int,
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
    model is biased low); and the transfer against the twins' own data
    (:func:`_data_curve`)."""
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
        ratios = transfer_report(real_model, [model(c, f"{k} walks") for c in counts],
                                 goals).overall_ratios()
        curve.append({"walks": k, "pools": len(pools),
                      "transitions": int(sum(int(c.sum()) for c in counts) // len(counts)),
                      "mean_ratio": float(np.mean(ratios)),
                      "worst_ratio": float(np.max(ratios))})
    return report, curve


def _pool_sizes(n: int) -> list[int]:
    """Twin walks pooled per twin in the data curve: 1, 2, 4, ... below ``n``, then ``n``."""
    sizes, k = [], 1
    while k < n:
        sizes.append(k)
        k *= 2
    return [*sizes, n]


#: Resamples of the transfer report's perfect-twin floor (per goal).
TRANSFER_BOOT = 30


def _params_at(space: ParameterSpace, base: Any, unit: NDArray[np.float64]) -> Any:
    """``base`` with the fields of ``unit``; a value that only round-trips the unit cube
    back to the base's (within 1e-9) keeps the base's exact value."""
    values = space.values(unit)
    for name, v in values.items():
        b = getattr(base, name)
        if isinstance(v, float) and isinstance(b, int | float) and math.isclose(v, b,
                                                                               rel_tol=1e-9):
            values[name] = b
    return dataclasses.replace(base, **values)


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
