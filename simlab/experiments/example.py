"""A tiny example runner: the bias of a coin, estimated over independent seeds.

It shows every part of the contract (:mod:`simlab.experiments`) in a few lines, with
``simlab/experiments/example.toml``::

    simlab reproduce --experiments simlab/experiments/example.toml --out /tmp/coin

* the work of one seed is a **module-level** function (:func:`flip_coins`) taking its
  own :class:`numpy.random.SeedSequence`, so ``ctx.map`` can run it in another process or
  on Ray and the numbers do not depend on the backend;
* ``ctx.seeds(n)`` gives the per-seed SeedSequences;
* the figure goes under ``ctx.out`` and is listed in the result;
* ``metrics`` are plain numbers the ``[[expect]]`` checks read.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from simlab.base import validation
from simlab.base.io import atomic_write
from simlab.experiments.context import RunContext, RunResult
from simlab.experiments.registry import runner


def flip_coins(p: float, flips: int, seed: np.random.SeedSequence) -> float:
    """Fraction of heads in ``flips`` tosses of a coin with P(heads) = ``p``."""
    rng = np.random.default_rng(seed)
    return float((rng.random(flips) < p).mean())


@runner("example.coin")
def coin(params: dict[str, Any], budget: dict[str, Any], ctx: RunContext) -> RunResult:
    """Estimate ``params["p"]`` from ``budget["seeds"]`` runs of ``budget["flips"]`` tosses.

    Metrics: ``p_hat`` (mean over seeds), ``ci95`` (half-width of its 95 % confidence
    interval over seeds: Student's t for ``seeds - 1`` degrees of freedom, since the spread
    is estimated from those few seeds), ``p_true``, ``seeds``.
    """
    p = validation.probability(params.get("p"), "params.p")
    flips = validation.whole(budget.get("flips"), "budget.flips", minimum=1)
    n = int(budget["seeds"])
    estimates = np.array(ctx.map(flip_coins, [{"p": float(p), "flips": flips, "seed": s}
                                              for s in ctx.seeds(n)], desc="coin seeds"))
    p_hat = float(estimates.mean())
    ci95 = float("nan")
    if n > 1:
        from scipy.stats import t as student_t

        ci95 = float(student_t.ppf(0.975, n - 1) * estimates.std(ddof=1) / math.sqrt(n))
    ctx.log(f"p_hat = {p_hat:.4f} over {n} seeds")

    from matplotlib.figure import Figure

    fig = Figure(figsize=(4, 3), layout="constrained")
    ax = fig.add_subplot()
    ax.hist(estimates, bins=min(20, max(1, n)), color="#4477aa")
    ax.axvline(p, color="k", linestyle="--", label=f"p = {p}")
    ax.set_xlabel("fraction of heads per seed")
    ax.set_ylabel("seeds")
    ax.legend()
    path = ctx.out / "estimates.png"
    with atomic_write(path, "wb") as fh:
        fig.savefig(fh, format="png", dpi=80)
    return RunResult(
        metrics={"p_hat": p_hat, "ci95": ci95, "p_true": float(p), "seeds": n},
        figures=[path],
        notes=[f"{n} seeds x {flips} flips."],
        details={"estimates": estimates.tolist()},
    )
