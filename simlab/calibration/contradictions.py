"""Where the twin contradicts the robot: the (s, a) pairs whose moves differ beyond sampling.

A distance over the whole lab says how far a twin is, and the signature by region
(:mod:`~simlab.calibration.regions`) in what kind of place; neither says *which* moves the
twin gets wrong, which is what a user checks the map and the arena against. So each real
``(s, a)`` pair is tested on its own: are the robot's next states and the twin's two samples
of one distribution? The test is a two-sample permutation test of the total-variation
distance between the two samples' next-state shares (``scipy.stats.permutation_test``,
independent samples, one-sided: a larger distance than the relabelled samples give; exact
when the relabellings are fewer than the resamples), which needs no large-count
approximation: a real pair holds 5-40 transitions. Over the hundreds of pairs of a lab some
tests pass the 5 % level by chance alone (5 % of them), so the pairs are read with the
Benjamini-Hochberg procedure (Benjamini & Hochberg 1995, "Controlling the false discovery
rate", JRSS B 57(1), section 3; ``scipy.stats.false_discovery_control``): the listed pairs
have a q-value under ``alpha``, so that on average at most a share ``alpha`` of them are
false alarms.

What the count says: a handful of listed pairs carrying much of the distance points at a
place (a wall the map misses, a door narrower than drawn); a count of raw 5 % passes near
5 % of the pairs tested means the twin differs from the robot nowhere in particular, and
many raw passes with few listed pairs that it differs a little almost everywhere.

Pairs with fewer than :data:`MIN_TRANSITIONS` real or twin transitions are not tested (a
single move cannot differ beyond sampling); reset rows are left out by the caller (they are
not moves).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Default false-discovery rate of the listed pairs.
ALPHA = 0.05
#: Relabellings of each pair's permutation test (exact below this many).
RESAMPLES = 1999
#: Fewest transitions on each side for a pair to be tested.
MIN_TRANSITIONS = 2


@dataclass(frozen=True)
class Contradictions:
    """The pairs where the twin contradicts the robot (module docstring).

    ``tested``: pairs tested; ``untested``: real pairs with too few transitions on either
    side (the twin's untried pairs among them, ``twin_untried``); ``raw``: pairs with p <
    ``alpha`` before the correction, beside ``expected`` = ``alpha x tested``, what chance
    alone gives; ``pairs``: the listed pairs (q < ``alpha``), most certain first, each a dict
    of ``state``, ``action``, ``real`` and ``twin`` transitions, ``stay_real``,
    ``stay_twin``, the most likely next state and its share on each side (``next_real``,
    ``share_real``, ``next_twin``, ``share_twin``), ``tv`` (between the pair's two rows),
    ``p``, ``q`` and the pair's ``region`` (None without regions); ``visit_share``: the
    listed pairs' share of the real transitions tested; ``distance_share``: their share of
    the visit-weighted TV distance over the tested pairs.
    """

    alpha: float
    tested: int
    untested: int
    twin_untried: int
    raw: int
    pairs: list[dict[str, Any]] = field(default_factory=list)
    visit_share: float = 0.0
    distance_share: float = 0.0
    resamples: int = RESAMPLES

    @property
    def expected(self) -> float:
        return self.alpha * self.tested

    def to_json(self) -> dict[str, Any]:
        return {"alpha": self.alpha, "method": "permutation test of the next-state TV per "
                "(s, a), Benjamini-Hochberg across pairs", "resamples": self.resamples,
                "tested": self.tested, "untested": self.untested,
                "twin_untried": self.twin_untried, "raw": self.raw,
                "expected_by_chance": self.expected, "visit_share": self.visit_share,
                "distance_share": self.distance_share, "pairs": self.pairs}

    @classmethod
    def from_json(cls, doc: dict[str, Any]) -> Contradictions:
        return cls(alpha=float(doc["alpha"]), tested=int(doc["tested"]),
                   untested=int(doc["untested"]), twin_untried=int(doc["twin_untried"]),
                   raw=int(doc["raw"]), pairs=list(doc["pairs"]),
                   visit_share=float(doc["visit_share"]),
                   distance_share=float(doc["distance_share"]),
                   resamples=int(doc.get("resamples", RESAMPLES)))

    def summary(self) -> str:
        """One line: how many pairs, against what chance gives."""
        n = len(self.pairs)
        where = (f"{n} of {self.tested} real (s, a) pairs" if n else
                 f"none of {self.tested} real (s, a) pairs")
        tail = (f", {100 * self.visit_share:.0f} % of the real transitions tested and "
                f"{100 * self.distance_share:.0f} % of the distance" if n else "")
        return (f"the twin contradicts the robot beyond sampling at {where} (false-discovery "
                f"rate {100 * self.alpha:.0f} %){tail}; {self.raw} pass the raw "
                f"{100 * self.alpha:.0f} % test, {self.expected:.0f} by chance alone")


def _tv_statistic(k: int) -> Any:
    """The TV between two label samples' shares over ``k`` categories, vectorised over the
    leading axes (the resamples)."""
    cats = np.arange(k)

    def stat(x: NDArray[np.int64], y: NDArray[np.int64], axis: int = -1) -> NDArray[np.float64]:
        fx = (np.moveaxis(x, axis, -1)[..., None] == cats).mean(axis=-2)
        fy = (np.moveaxis(y, axis, -1)[..., None] == cats).mean(axis=-2)
        return 0.5 * np.abs(fx - fy).sum(axis=-1)

    return stat


def pair_pvalue(real_row: ArrayLike, twin_row: ArrayLike, rng: np.random.Generator,
                resamples: int = RESAMPLES) -> float:
    """p-value of "the two rows of next-state counts are samples of one distribution"
    (module docstring). Both rows need :data:`MIN_TRANSITIONS` counts or more."""
    from scipy import stats

    r = np.asarray(real_row, dtype=np.int64)
    t = np.asarray(twin_row, dtype=np.int64)
    seen = (r + t) > 0
    r, t = r[seen], t[seen]
    if seen.sum() < 2:  # one next state on both sides: the same distribution, nothing to test
        return 1.0
    labels = np.arange(r.size)
    res = stats.permutation_test((np.repeat(labels, r), np.repeat(labels, t)),
                                 _tv_statistic(r.size), permutation_type="independent",
                                 vectorized=True, n_resamples=resamples,
                                 alternative="greater", random_state=rng)
    return float(res.pvalue)


def contradicted_pairs(real: ArrayLike, twin: ArrayLike, rng: np.random.Generator, *,
                       alpha: float = ALPHA, resamples: int = RESAMPLES,
                       skip_states: tuple[int, ...] | list[int] = (),
                       regions: NDArray[np.int64] | None = None) -> Contradictions:
    """Test every real ``(s, a)`` pair of ``real`` (S, A, S) counts against ``twin``'s
    (the twin's walks pooled) and list those with a q-value under ``alpha`` (module
    docstring). ``skip_states``: rows left out (reset rows); ``regions``: the (S, A) region
    index of each pair (:func:`~simlab.calibration.regions.pair_regions`), named in each
    listed pair as ``region``. ``rng`` draws the relabellings."""
    from scipy import stats

    from simlab.calibration.metrics import tv_distance
    from simlab.calibration.regions import REGIONS

    if not 0 < alpha < 1:
        raise ValueError(f"alpha must be in (0, 1), got {alpha}")
    R = np.asarray(real, dtype=np.int64)
    T = np.asarray(twin, dtype=np.int64)
    if R.shape != T.shape:
        raise ValueError(f"real counts {R.shape} and twin counts {T.shape} differ in shape")
    nr, nt = R.sum(axis=2), T.sum(axis=2)
    skip = np.zeros(R.shape[0], dtype=bool)
    skip[list(skip_states)] = True
    real_pairs = (nr > 0) & ~skip[:, None]
    testable = real_pairs & (nr >= MIN_TRANSITIONS) & (nt >= MIN_TRANSITIONS)
    where = np.argwhere(testable)
    p = np.array([pair_pvalue(R[s, a], T[s, a], rng, resamples) for s, a in where])
    q = stats.false_discovery_control(p) if p.size else p
    w = nr[testable].astype(float)
    tv = tv_distance(T, R).per_pair[testable]   # argwhere's order, as ``where``
    listed = np.flatnonzero(q < alpha) if p.size else np.zeros(0, dtype=np.int64)
    rows = []
    for i in listed:
        s, a = (int(v) for v in where[i])
        rows.append({"state": s, "action": a, "real": int(nr[s, a]), "twin": int(nt[s, a]),
                     "stay_real": float(R[s, a, s] / nr[s, a]),
                     "stay_twin": float(T[s, a, s] / nt[s, a]),
                     "next_real": int(R[s, a].argmax()),
                     "share_real": float(R[s, a].max() / nr[s, a]),
                     "next_twin": int(T[s, a].argmax()),
                     "share_twin": float(T[s, a].max() / nt[s, a]),
                     "tv": float(tv[i]), "p": float(p[i]), "q": float(q[i]),
                     "region": None if regions is None else REGIONS[int(regions[s, a])]})
    rows.sort(key=lambda r: (r["q"], -r["real"], r["state"], r["action"]))
    weighted = float((w * tv).sum())
    return Contradictions(
        alpha=float(alpha), tested=int(where.shape[0]),
        untested=int((real_pairs & ~testable).sum()),
        twin_untried=int((real_pairs & (nt == 0)).sum()),
        raw=int((p < alpha).sum()), pairs=rows,
        visit_share=float(w[listed].sum() / w.sum()) if w.sum() else 0.0,
        distance_share=float((w * tv)[listed].sum() / weighted) if weighted > 0 else 0.0,
        resamples=int(resamples))


def common_pairs(runs: list[Contradictions]) -> list[tuple[int, int]]:
    """The pairs every run lists: where the twin is wrong whatever its fields, across
    calibrations that landed on different points (sorted)."""
    if not runs:
        return []
    sets = [{(r["state"], r["action"]) for r in c.pairs} for c in runs]
    return sorted(set.intersection(*sets))


def direction(row: dict[str, Any], margin: float = 0.1) -> str:
    """How a listed pair differs: ``stays more`` / ``stays less`` (the twin's stay share
    beyond the robot's by ``margin``), else ``moves elsewhere``."""
    d = row["stay_twin"] - row["stay_real"]
    if math.isfinite(d) and d >= margin:
        return "stays more"
    if math.isfinite(d) and d <= -margin:
        return "stays less"
    return "moves elsewhere"
