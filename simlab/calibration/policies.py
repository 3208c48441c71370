"""What the calibrated twin's policies are worth on the real robot: the transfer stage.

The twin walks of a calibration are estimated into twins, one per seed, and the
shortest-path policy of each is scored on the real model
(:func:`~simlab.calibration.transfer.transfer_report`). Such a score means little alone: the
optimum of a real model estimated from a few thousand transitions is biased low, and a twin's
policy is only as good as its data. So every score is read against the **perfect-twin line**
(:func:`~simlab.calibration.transfer.score.perfect_twin_line`): what a twin equal to the real
robot scores with the same data. The stage gives

* the twin seeds' scores and the perfect twin at one seed's data (the headline), per goal;
* the **data curve**: the twin walks pooled 1, 2, 4, ... at a time (disjoint pools), each
  pool's policies scored, beside the perfect twin at the pool's data;
* the **policy data** a policy needs (:func:`data_need`; never fewer than the curve's
  smallest pool, :func:`policy_need`), and the perfect twin there;
* with ``policy_data``, that data collected with the calibrated primitives and the policy
  planned on it scored against the perfect twin at the same data;
* a warning for every figure that cannot be computed, saying why.

Reset rows (:mod:`~simlab.calibration.resets`) take the twins' own rows in the real model, so
no policy is charged for them; goals the real robot never reached are left out (warned).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.base.errors import warn

#: Resamples of the perfect-twin floor (per goal) and of each perfect-twin line. A line's
#: resampled scores cluster (on the ISIR lab at 8,012 transitions: about 1.06-1.09 and
#: 1.11-1.12 the real optimum's steps, and a tenth never arrive), so its median over 20
#: resamples moved by 0.011 (standard deviation, 8 draws) where 100 move it by 0.003, a
#: second or so of a calibration's several minutes per line.
TRANSFER_BOOT = 30
LINE_BOOT = 100

#: How close to a twin of unlimited data the recommended policy data come (steps over the
#: real optimum, absolute).
DATA_NEED_TOLERANCE = 0.01


@dataclass
class TwinTransfer:
    """The transfer stage's figures (module docstring).

    ``report``: the twin seeds on the real model; ``curve``: one row per pool size
    (``walks``, ``pools``, ``transitions`` per pool, ``mean_ratio``, ``worst_ratio``,
    ``perfect_ratio``); ``line``: the perfect twin at one seed's data; ``need``:
    :func:`data_need` of the curve; ``line_at_need``: the perfect twin at that data;
    ``policy``: the collected policy data's score (``transitions``, ``ratio``,
    ``goal_ratios``, ``line``), None without ``policy_data``; ``left_out``: goals the real
    robot never reached; ``warnings``: figures that could not be computed, and why.
    """

    report: Any
    real_model: Any
    curve: list[dict[str, Any]] = field(default_factory=list)
    line: Any = None
    need: dict[str, float] | None = None
    line_at_need: Any = None
    policy: dict[str, Any] | None = None
    left_out: list[int] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    #: how a twin's action the real robot never tried is scored (``stay`` or ``mask``,
    #: :func:`~simlab.calibration.transfer.score.transfer_report`)
    untried: str = "stay"
    #: the twin ensemble's pooled walks against as many of the winner's, each planned on
    #: and scored on the real model (:func:`ensemble_transfer`); None without an ensemble
    ensemble: dict[str, Any] | None = None
    #: when some twin seed never arrives under ``stay``: every twin seed's ratio with its
    #: policy chosen among the pairs the real robot tried (``mask``), else None
    masked: list[float] | None = None


def finite_rows(curve: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The rows of a data curve with a finite mean ratio (a size whose pools all arrive)."""
    return [r for r in curve if r["mean_ratio"] is not None and math.isfinite(r["mean_ratio"])]


def data_need(curve: list[dict[str, Any]], tolerance: float = DATA_NEED_TOLERANCE
              ) -> dict[str, float] | None:
    """How many twin transitions a policy needs, from the transfer's data curve.

    A policy planned on a model estimated from ``N`` transitions exploits that sample's
    noise; its excess over what unlimited data would give shrinks about as ``1/N`` (each
    transition probability's error variance does). Fits ``ratio(N) = limit + c / N`` by
    least squares to the curve's finite mean ratios (a size whose pools never arrive is left
    out) and returns ``limit`` (a twin with unlimited data), ``c`` and ``transitions`` =
    ``c / tolerance`` (the data at which the excess is ``tolerance``); None with fewer than
    two finite sizes or a curve that does not fall with more data (``c <= 0``).
    """
    rows = finite_rows(curve)
    if len(rows) < 2:
        return None
    x = np.array([1.0 / r["transitions"] for r in rows])
    y = np.array([r["mean_ratio"] for r in rows])
    A = np.stack([np.ones_like(x), x], axis=1)
    (limit, c), *_ = np.linalg.lstsq(A, y, rcond=None)
    if not c > 0:
        return None
    return {"limit": float(limit), "c": float(c), "tolerance": float(tolerance),
            "transitions": float(c / tolerance)}


def policy_need(curve: list[dict[str, Any]], tolerance: float = DATA_NEED_TOLERANCE
                ) -> dict[str, Any] | None:
    """The policy data to recommend: :func:`data_need` when the curve falls as ``1/N``;
    when it is flat or rises (``flat``: the policies are limited by the twin, not by its
    data), the largest measured size, whose mean ratio is the ``limit`` (``c`` 0); None
    with fewer than two finite sizes.

    Never fewer transitions than the curve's smallest size: a nearly flat curve fits a
    small ``c``, and ``c / tolerance`` then lies below every size measured, where neither
    the ``1/N`` law nor the perfect twin's line was seen (on the ISIR lab a slope of 13
    fitted at 8,012-24,036 transitions asked 1,321, where a perfect twin itself takes 1.22x
    the optimum's steps against 1.10x at 8,012). There the recommendation is the smallest
    size, already within ``tolerance`` of the limit by the fit (``below_measured``; the
    fit's own figure is ``fit_transitions``)."""
    rows = finite_rows(curve)
    need = data_need(curve, tolerance)
    if need is not None:
        smallest = float(min(r["transitions"] for r in rows))
        below = need["transitions"] < smallest
        return {**need, "flat": False, "below_measured": below,
                "fit_transitions": need["transitions"],
                "transitions": smallest if below else need["transitions"]}
    if len(rows) < 2:
        return None
    top = max(rows, key=lambda r: r["transitions"])
    return {"limit": float(top["mean_ratio"]), "c": 0.0, "tolerance": float(tolerance),
            "transitions": float(top["transitions"]), "flat": True, "below_measured": False,
            "fit_transitions": None}


def pool_sizes(n: int) -> list[int]:
    """Twin walks pooled per twin in the data curve: 1, 2, 4, ... below ``n``, then ``n``."""
    sizes, k = [], 1
    while k < n:
        sizes.append(k)
        k *= 2
    return [*sizes, n]


def real_transfer_counts(real: Any, twin_counts: list[NDArray[np.int64]]) -> NDArray[np.int64]:
    """The real counts the transfer is scored on: the real rows, and for each reset state
    the twins' own rows pooled (so no policy is charged for a reset either way)."""
    counts = np.array(real.counts, dtype=np.int64, copy=True)
    if real.reset_states and twin_counts:
        pooled = sum(twin_counts)
        for s in real.reset_states:
            counts[s] = pooled[s]
    return counts


def reached_goals(counts: NDArray[np.int64], goals: list[int]) -> tuple[list[int], list[int]]:
    """(goals some real transition from another state ends in, the others)."""
    into = counts.sum(axis=1)
    np.fill_diagonal(into, 0)
    hit = into.sum(axis=0) > 0
    return [g for g in goals if hit[g]], [g for g in goals if not hit[g]]


def transfer_stage(real: Any, twin_counts: list[NDArray[np.int64]], twin_names: list[str],
                   goals: list[int], centres: Any, rng: np.random.Generator,
                   untried: str = "stay") -> TwinTransfer | None:
    """The twin seeds' transfer, the data curve with its perfect-twin lines, the data a
    policy needs and the perfect twin there (module docstring); None without twins.
    ``rng`` draws every resample; ``untried``: how a twin's action the real robot never
    tried is scored (``stay``: it stays put; ``mask``: the twin's policy among the tried
    pairs), in every score of the stage."""
    if not twin_counts:
        return None
    from simlab.calibration.transfer import TransferModel, transfer_report
    from simlab.calibration.transfer.score import perfect_twin_line

    def model(counts: NDArray[np.int64], name: str) -> Any:
        return TransferModel.from_counts(counts, name=name, action_set=real.action_set,
                                         centres=centres)

    real_counts = real_transfer_counts(real, twin_counts)
    kept, left_out = reached_goals(real_counts, goals)
    out = TwinTransfer(report=None, real_model=model(real_counts, real.source or "real"),
                       left_out=left_out, untried=untried)
    if left_out:
        out.warnings.append(f"goal state(s) {left_out} left out of the transfer: no real "
                            "transition ends there (the real robot never reached them)")
    if not kept:
        return out
    named = {f"s{g}": [g] for g in kept}
    twins = [model(c, n) for c, n in zip(twin_counts, twin_names, strict=True)]
    out.report = transfer_report(out.real_model, twins, named, n_boot=TRANSFER_BOOT, rng=rng,
                                 untried=untried)
    if untried == "stay" and not np.isfinite(out.report.overall_ratios()).all():
        out.masked = [float(r) for r in transfer_report(out.real_model, twins, named,
                                                        untried="mask").overall_ratios()]
    out.line = perfect_twin_line(out.real_model, out.report, twin_counts[0].sum(axis=2),
                                 n_boot=LINE_BOOT, rng=rng)
    out.curve = _curve(out, twin_counts, model, named, rng)
    out.need = policy_need(out.curve)
    if out.need is not None:
        visits = np.mean([c.sum(axis=2) for c in twin_counts], axis=0)
        scale = out.need["transitions"] / max(float(visits.sum()), 1.0)
        out.line_at_need = perfect_twin_line(out.real_model, out.report,
                                             np.rint(visits * scale).astype(np.int64),
                                             n_boot=LINE_BOOT, rng=rng)
    out.warnings += transfer_warnings(out)
    return out


def _curve(out: TwinTransfer, twin_counts: list[NDArray[np.int64]], model: Any,
           named: dict[str, list[int]], rng: np.random.Generator) -> list[dict[str, Any]]:
    """The data curve: pools of 1, 2, 4, ... twin walks, each pool's policies scored and
    the perfect twin at the pool's data (mean visits over the pools)."""
    from simlab.calibration.transfer import transfer_report
    from simlab.calibration.transfer.score import perfect_twin_line

    rows = []
    for k in pool_sizes(len(twin_counts)):
        pools = [sum(twin_counts[i:i + k]) for i in range(0, len(twin_counts) - k + 1, k)]
        ratios = out.report.overall_ratios() if k == 1 else transfer_report(
            out.real_model, [model(c, f"{k} walks") for c in pools], named,
            untried=out.untried).overall_ratios()
        line = out.line if k == 1 else perfect_twin_line(
            out.real_model, out.report,
            np.rint(np.mean([c.sum(axis=2) for c in pools], axis=0)).astype(np.int64),
            n_boot=LINE_BOOT, rng=rng)
        rows.append({"walks": k, "pools": len(pools),
                     "transitions": int(sum(int(c.sum()) for c in pools) // len(pools)),
                     "mean_ratio": float(np.mean(ratios)), "worst_ratio": float(np.max(ratios)),
                     "perfect_ratio": line.median})
    return rows


def transfer_warnings(out: TwinTransfer) -> list[str]:
    """Why a figure of the transfer cannot be computed: twins that never arrive (and the
    real pairs that trap them), no perfect-twin score, no data need."""
    rep = out.report
    warned = []
    never = [t for t, r in zip(rep.twin_names, rep.overall_ratios(), strict=True)
             if not math.isfinite(r)]
    if never:
        real = out.real_model
        rows = np.arange(real.n_states)
        stuck = real.allowed & (real.T[rows, :, rows] >= 1.0)
        chosen = {(int(s), int(t.policy[s])) for g in rep.goals for t in g.twins
                  for s in np.flatnonzero(~np.isfinite(t.steps) & ~g.goal)}
        trapped = sorted(p for p in chosen if stuck[p] or not real.allowed[p])
        n = real.counts.sum(axis=2) if real.counts is not None else None
        seen = ("" if n is None or not trapped else
                f", seen {min(n[p] for p in trapped)}-{max(n[p] for p in trapped)} times each")
        masked = ("" if out.masked is None else
                  "; so planned, the twin seeds take " + ", ".join(
                      f"{r:.3f}" if math.isfinite(r) else "never" for r in out.masked)
                  + " x the real optimum's steps")
        cause = (f"their policies choose {len(trapped)} (s, a) the real robot only stayed in "
                 f"or never tried{seen}: the real data are too thin there to say it moves "
                 "(`--untried mask`, on calibrate and transfer, plans among the pairs the "
                 f"real robot tried{masked})" if trapped else
                 "their policies loop between states on the real model (the twin's data are "
                 "too few to plan there: see the pooled rows of the data curve)")
        warned.append(f"{len(never)} of {len(rep.twin_names)} twin seeds never arrive at some "
                      f"goal from some start, so their ratio and the mean have no value: "
                      f"{cause}")
    floors = [g.floor for g in rep.goals if g.floor is not None]
    bad = [f for f in floors if not math.isfinite(f.median)]
    if bad:
        warned.append(f"no perfect-twin floor for {len(bad)} of {len(floors)} goals: the "
                      "real robot's own plan never arrives on most resamples of the real "
                      "data (too few real transitions per pair)")
    if out.need is None and len(out.curve) > 1:
        warned.append("no policy-data figure: the data curve has fewer than two sizes whose "
                      "twins all arrive")
    elif out.need is not None and out.need["flat"]:
        warned.append("the twins' policies do not improve with more of their data ("
                      + ", ".join(f"{r['mean_ratio']:.3f} at {r['transitions']:,}"
                                  for r in out.curve if math.isfinite(r["mean_ratio"]))
                      + "): what is left is the twin's own difference from the robot, not its "
                      f"data; the policy data recommended are the largest pool's "
                      f"{out.need['transitions']:,.0f} transitions")
    return warned


def collect_policy_data(runner: Any, job: Any, transitions: int, workers: int,
                        seed: int) -> NDArray[np.int64]:
    """Walk ``transitions`` with ``job``'s parameters (a :class:`WalkJob` template), split
    over ``workers`` walks on fresh seeds from ``seed``; the pooled counts."""
    import dataclasses

    k = max(1, int(workers))
    share = [transitions // k + (1 if i < transitions % k else 0) for i in range(k)]
    jobs = [dataclasses.replace(job, index=i, transitions=n, hours=None, seed=seed + i)
            for i, n in enumerate(share) if n > 0]
    return sum(t.counts for t in runner.map(jobs))


def score_policy_data(out: TwinTransfer, counts: NDArray[np.int64], action_set: Any,
                      centres: Any, rng: np.random.Generator) -> dict[str, Any]:
    """The policy planned on the collected ``counts`` scored on the real model, per goal and
    overall, beside the perfect twin at the same data."""
    from simlab.calibration.transfer import TransferModel, transfer_report
    from simlab.calibration.transfer.score import perfect_twin_line

    twin = TransferModel.from_counts(counts, name="policy data", action_set=action_set,
                                     centres=centres)
    named = {g.name: g.goal for g in out.report.goals}
    rep = transfer_report(out.real_model, [twin], named, untried=out.untried)
    line = perfect_twin_line(out.real_model, out.report, counts.sum(axis=2),
                             n_boot=LINE_BOOT, rng=rng)
    goal_ratios = {g.name: float(g.twins[0].ratio) for g in rep.goals}
    return {"transitions": int(counts.sum()), "ratio": float(rep.overall_ratios()[0]),
            "goal_ratios": goal_ratios, "line": line,
            "never_goals": [n for n, r in goal_ratios.items() if not math.isfinite(r)]}


def ensemble_transfer(out: TwinTransfer, members: list[NDArray[np.int64]],
                      winner: list[NDArray[np.int64]], action_set: Any, centres: Any
                      ) -> dict[str, Any] | None:
    """Does a twin ensemble transfer better than its winner? The confirming walks of ``k``
    ensemble members pooled (domain randomisation over what the data allow) against ``k``
    of the winner's own twin walks pooled (same number of walks of the same size), each
    planned on and scored on the real model: ``members``, ``transitions`` of each pool,
    ``ensemble_ratio``, ``winner_ratio`` (steps over the real optimum's, summed over the
    goals) and ``better`` (the ensemble's ratio is lower). None with fewer than two members
    or winner walks, or no transfer report."""
    k = min(len(members), len(winner))
    if out.report is None or k < 2:
        return None
    from simlab.calibration.transfer import TransferModel, transfer_report

    pools = {"ensemble": sum(members[:k]), "winner": sum(winner[:k])}
    models = [TransferModel.from_counts(c, name=f"{name} ({k} walks)", action_set=action_set,
                                        centres=centres) for name, c in pools.items()]
    named = {g.name: g.goal for g in out.report.goals}
    ratios = transfer_report(out.real_model, models, named,
                             untried=out.untried).overall_ratios()
    e, w = float(ratios[0]), float(ratios[1])
    return {"members": k, "transitions": int(pools["ensemble"].sum()),
            "winner_transitions": int(pools["winner"].sum()),
            "ensemble_ratio": e, "winner_ratio": w,
            "better": bool(math.isfinite(e) and (not math.isfinite(w) or e < w))}


def warn_all(messages: list[str], into: list[str]) -> None:
    """Print each warning once and keep it for the report."""
    for m in messages:
        warn(m)
        into.append(m)
