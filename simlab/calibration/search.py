"""The seeded derivative-free search over a :class:`~simlab.calibration.space.ParameterSpace`.

**Optimiser**: the first candidate is the base record (today's defaults, clipped into the
space) so the report shows where calibration started; then a scrambled Sobol design over
the unit cube fills half of the budget; the rest is local refinement in rounds of
``workers`` candidates: the minimum of a quadratic fitted by least squares to the
candidates nearest the best (it averages the walks' noise over many points), then a compass
search around the best point so far (``+- step`` along each coordinate, the step shrinking
by ``shrink`` after a full poll found nothing better).

**Common random numbers**: every candidate walks with the same seed, so the same action
sequence and the same noise draws; differences between candidates are the parameters, not
the luck of the draw.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.calibration.budget import screen_budget
from simlab.calibration.config import CalibrationConfig, RealTable
from simlab.calibration.metrics import (
    TVResult,
    cross_entropy,
    excess_distance,
    tv_distance,
)
from simlab.calibration.space import ParameterSpace
from simlab.calibration.walks import SimTable, WalkJob, WalkRunner


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


def _sobol(dim: int, n: int, rng: np.random.Generator) -> NDArray[np.float64]:
    from scipy.stats import qmc

    with warnings.catch_warnings():  # balance warning for n not a power of 2: harmless here
        warnings.simplefilter("ignore")
        return qmc.Sobol(dim, scramble=True, seed=rng).random(max(n, 0))


def _base_point(space: ParameterSpace, base: Any) -> NDArray[np.float64]:
    return space.unit({n: getattr(base, n) for n in space.names})


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


def make_candidate(index: int, stage: str, u: NDArray[np.float64], sim: SimTable, seed: int,
               ctx: dict[str, Any]) -> Candidate:
    cfg: CalibrationConfig = ctx["config"]
    tv = tv_distance(sim.counts, ctx["real"].counts, unvisited=cfg.unvisited)
    d = tv.distance if math.isfinite(tv.distance) else 1.0
    score = _score(cfg, sim.counts, ctx["real"].counts, d)
    return Candidate(index, stage, np.asarray(u), ctx["space"].values(u), d, sim, tv, score,
                     seed)


def evaluate_points(runner: WalkRunner, points: list[NDArray[np.float64]], stage: str, start: int,
              ctx: dict[str, Any], seeds: list[int] | None = None,
              budget: tuple[float | None, int | None] | None = None) -> list[Candidate]:
    """Simulate ``points`` (on ``seeds``, default the search's walk seed, and ``budget``
    ``(hours, transitions)``, default the screening budget) and score them."""
    space: ParameterSpace = ctx["space"]
    cfg: CalibrationConfig = ctx["config"]
    seeds = [ctx["walk_seed"]] * len(points) if seeds is None else seeds
    hours, transitions = ctx["screen"] if budget is None else budget
    jobs = [WalkJob(index=start + i, arena=ctx["arena"], states=ctx["states"],
                 params=space.apply(ctx["base"], u), hours=hours, transitions=transitions,
                 seed=seed, simulator=cfg.simulator, pose_source=cfg.pose_source,
                 action_set=ctx["real"].action_set, start_states=cfg.start_states,
                 n_states=ctx["n_states"])
            for i, (u, seed) in enumerate(zip(points, seeds, strict=True))]
    return [make_candidate(job.index, stage, u, sim, job.seed, ctx)
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


def walk_context(real: RealTable, arena: Any, disc: Any, space: ParameterSpace, base: Any,
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
           config: CalibrationConfig, runner: WalkRunner | None = None,
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
    ctx = walk_context(real, load_arena_config(arena), disc, space, base, config, config.seed,
                   screen)
    design, n_refine = _rounds(rng, config, space, _base_point(space, base))
    own = runner is None
    runner = WalkRunner(int(config.workers), config.address) if runner is None else runner
    bar = tqdm(total=config.candidates, desc="calibrate: screen", unit="cand",
               disable=not config.progress)
    try:
        cands: list[Candidate] = []
        for i in range(0, len(design), config.workers):
            batch = evaluate_points(runner, design[i:i + config.workers], "init", len(cands), ctx)
            cands += batch
            bar.update(len(batch))
            bar.set_postfix(best=f"{min(c.score for c in cands):.3f}")
        poll = _Poll(config.step, config.shrink, rng)
        while n_refine > 0:
            best = min(cands, key=lambda c: c.score)
            n = min(config.workers, n_refine)
            points = poll.propose(cands, best.unit, n)
            batch = evaluate_points(runner, points, "refine", len(cands), ctx)
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


