"""Distances and summaries of transition count tables ``n(s, a, s')`` (pure numpy).

All functions take count arrays of shape ``(S, A, S)`` (non-negative integers). The two
tables compared must have the same shape and the same meaning of ``a`` (the caller maps the
simulator's primitives onto the real action set first).

**Visit-weighted total variation** (the headline number)::

    D = sum_{(s,a) in C} n_real(s, a) * TV(s, a) / sum_{(s,a) in C} n_real(s, a)
    TV(s, a) = 1/2 * sum_s' |T_sim(s, a, s') - T_real(s, a, s')|

over the set ``C`` of pairs visited in **both** tables. Decision: pairs visited in only one
table have no defined distance; they are not silently dropped but counted and reported
(:class:`TVResult`: ``real_only``, ``sim_only`` and the share of the real visits that fall
on pairs the simulation never tried, ``real_weight_uncovered``). With ``unvisited="max"``
they instead enter the mean with TV = 1 (the largest possible), weighted by ``n_real``.

**Bootstrap sampling floor**: how far a table with exactly the real visit counts would lie
from the real one by sampling alone. Each resample draws ``n_real(s, a)`` next states from
``T_real(s, a, .)`` (multinomial per pair, seeded Generator) and the distance of the resample
to the real table is recorded; the floor is their median with a 95 % band. A simulated table
cannot be expected to come closer to the real one than this. ``other_n`` gives a second,
*matched* floor: the distance between two independent samples from ``T_real``, one of the
real sizes and one of the simulated sizes ``other_n(s, a)`` — the expected distance of a
perfect simulator run for that budget, *as estimated by the plug-in*: drawn from the real
table's own shares, which on sparse rows (a few visits each) lack the rare next states the
robot has, so it reads low (the synthetic lab's hidden robot, walked afresh, lies 1.14-1.20x
its matched floor over three real tables).

**Perfect-twin floor** (:func:`perfect_twin_floor`): the matched floor drawn instead from
coverage-adjusted shares (:func:`coverage_adjusted`): each row's observed shares scaled by
its sample coverage ``C = 1 - f1 / n`` (``f1`` next states seen once; Good 1953,
Biometrika 40, the estimate Chao & Shen 2003, Environ. Ecol. Stat. 10, use against the
plug-in entropy's bias), the missing ``1 - C`` given to the next states the row has not
seen in proportion to how often the state's other moves reached them. The distance a twin equal to the robot would show, estimated without
that bias (the hidden robot reads 0.98-1.02x it on the same three tables).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from simlab.base.errors import ConfigError


def _counts(x: ArrayLike, name: str) -> NDArray[np.int64]:
    arr = np.asarray(x)
    if arr.ndim != 3 or arr.shape[0] != arr.shape[2]:
        raise ConfigError(f"expected an (S, A, S) count array, got shape {arr.shape}", key=name)
    if arr.size and (arr.min() < 0 or not np.all(np.isfinite(arr))):
        raise ConfigError("counts must be finite and >= 0", key=name)
    return arr.astype(np.int64)


def _probabilities(counts: NDArray[np.int64]) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    n = counts.sum(axis=2)
    T = counts / np.maximum(n, 1)[:, :, None]
    return T, n


@dataclass(frozen=True)
class TVResult:
    """Visit-weighted total variation between a simulated and a real table.

    Attributes:
        distance: the weighted mean TV in [0, 1] (NaN when no pair is in both tables).
        per_pair: ``(S, A)`` TV of every pair visited in both (NaN elsewhere).
        common: pairs visited in both tables.
        real_only: pairs visited in the real table only (no simulated estimate).
        sim_only: pairs visited in the simulation only.
        real_weight_uncovered: share of the real visits lying on ``real_only`` pairs.
        unvisited: the rule used for ``real_only`` pairs (``"report"`` or ``"max"``).
    """

    distance: float
    per_pair: NDArray[np.float64]
    common: int
    real_only: int
    sim_only: int
    real_weight_uncovered: float
    unvisited: str

    def to_json(self) -> dict[str, object]:
        return {"distance": _float(self.distance), "common_pairs": self.common,
                "real_only_pairs": self.real_only, "sim_only_pairs": self.sim_only,
                "real_weight_uncovered": _float(self.real_weight_uncovered),
                "unvisited_rule": self.unvisited}


def _float(x: float) -> float | None:
    return None if not np.isfinite(x) else float(x)


def tv_distance(sim: ArrayLike, real: ArrayLike, *, unvisited: str = "report") -> TVResult:
    """Visit-weighted total variation of ``sim`` from ``real`` (see the module docstring).

    Args:
        sim, real: ``(S, A, S)`` counts of the same shape.
        unvisited: ``"report"`` (pairs visited only in ``real`` are counted, not averaged)
            or ``"max"`` (they enter the mean with TV = 1).
    """
    sim_c, real_c = _counts(sim, "sim"), _counts(real, "real")
    if sim_c.shape != real_c.shape:
        raise ConfigError(f"shapes differ: sim {sim_c.shape}, real {real_c.shape}", key="counts")
    if unvisited not in ("report", "max"):
        raise ConfigError(f"must be 'report' or 'max', got {unvisited!r}", key="unvisited")
    Ts, ns = _probabilities(sim_c)
    Tr, nr = _probabilities(real_c)
    common = (ns > 0) & (nr > 0)
    real_only = (nr > 0) & (ns == 0)
    per_pair = np.full(ns.shape, np.nan)
    per_pair[common] = 0.5 * np.abs(Ts - Tr).sum(axis=2)[common]
    w = nr.astype(np.float64)
    num = float((w * np.nan_to_num(per_pair))[common].sum())
    den = float(w[common].sum())
    if unvisited == "max":
        num += float(w[real_only].sum())
        den += float(w[real_only].sum())
    total = float(w.sum())
    return TVResult(
        distance=num / den if den > 0 else float("nan"),
        per_pair=per_pair,
        common=int(common.sum()),
        real_only=int(real_only.sum()),
        sim_only=int(((ns > 0) & (nr == 0)).sum()),
        real_weight_uncovered=float(w[real_only].sum() / total) if total > 0 else float("nan"),
        unvisited=unvisited,
    )


@dataclass(frozen=True)
class Floor:
    """Bootstrap distribution of the distance due to sampling alone.

    Attributes:
        median: median distance over the resamples.
        low, high: 2.5 % and 97.5 % quantiles.
        samples: ``(B,)`` all resampled distances.
    """

    median: float
    low: float
    high: float
    samples: NDArray[np.float64]

    def to_json(self) -> dict[str, object]:
        return {"median": _float(self.median), "low_2.5": _float(self.low),
                "high_97.5": _float(self.high), "resamples": int(self.samples.size)}


def _resample(T: NDArray[np.float64], n: NDArray[np.int64],
              rng: np.random.Generator) -> NDArray[np.int64]:
    out = np.zeros(T.shape, dtype=np.int64)
    for s, a in zip(*np.nonzero(n), strict=True):
        out[s, a] = rng.multinomial(int(n[s, a]), T[s, a])
    return out


def bootstrap_floor(real: ArrayLike, rng: np.random.Generator, *, n_boot: int = 200,
                    other_n: ArrayLike | None = None) -> Floor:
    """Sampling floor of :func:`tv_distance` for the real counts (module docstring).

    Args:
        real: ``(S, A, S)`` real counts.
        rng: the Generator all resamples draw from (same seed -> same floor).
        n_boot: number of resamples (>= 1).
        other_n: ``(S, A)`` visit counts of the other table; if given, the *matched*
            floor (distance of a sample of these sizes to a fresh sample of the real sizes).
    """
    real_c = _counts(real, "real")
    return _floor(real_c, _probabilities(real_c)[0], rng, n_boot, other_n)


def _floor(real_c: NDArray[np.int64], T: NDArray[np.float64], rng: np.random.Generator,
           n_boot: int, other_n: ArrayLike | None) -> Floor:
    """The floor of ``real_c`` with every resample drawn from the shares ``T``: against the
    real table itself, or (``other_n``) two samples, of those sizes and of the real ones."""
    if int(n_boot) < 1:
        raise ConfigError(f"must be >= 1, got {n_boot}", key="n_boot")
    n = real_c.sum(axis=2)
    m = None if other_n is None else np.asarray(other_n, dtype=np.int64)
    if m is not None and m.shape != n.shape:
        raise ConfigError(f"expected shape {n.shape}, got {m.shape}", key="other_n")
    d = np.empty(int(n_boot))
    for b in range(int(n_boot)):
        if m is None:
            d[b] = tv_distance(_resample(T, n, rng), real_c).distance
        else:
            d[b] = tv_distance(_resample(T, m, rng), _resample(T, n, rng)).distance
    finite = d[np.isfinite(d)]
    if finite.size == 0:  # no pair in both samples (e.g. a simulation that tried none)
        return Floor(median=math.nan, low=math.nan, high=math.nan, samples=d)
    return Floor(median=float(np.median(finite)), low=float(np.quantile(finite, 0.025)),
                 high=float(np.quantile(finite, 0.975)), samples=d)


def coverage_adjusted(counts: ArrayLike) -> NDArray[np.float64]:
    """``(S, A, S)`` next-state shares of ``counts`` with the mass the sample missed restored
    (module docstring): per visited pair, its shares times the coverage ``C = 1 - f1 / n``
    (a row of singletons only counts ``f1 = n - 1``) and ``1 - C`` over the next states
    unseen in that row but reached from the same state by any action, weighted by those
    moves' counts. A row with nothing unseen to give to, or nothing seen once, keeps its
    plug-in shares; unvisited pairs stay 0."""
    c = _counts(counts, "counts")
    T, n = _probabilities(c)
    out = T.copy()
    from_state = c.sum(axis=1)                       # (S, S'): any action's next states
    f1 = (c == 1).sum(axis=2)
    f1 = np.where((f1 == n) & (n > 0), n - 1, f1)
    cover = 1.0 - f1 / np.maximum(n, 1)
    for s, a in zip(*np.nonzero((n > 0) & (cover < 1.0)), strict=True):
        w = np.where(c[s, a] == 0, from_state[s], 0).astype(np.float64)
        if w.sum() > 0:
            out[s, a] = T[s, a] * cover[s, a] + (1.0 - cover[s, a]) * w / w.sum()
    return out


def perfect_twin_floor(real: ArrayLike, rng: np.random.Generator, other_n: ArrayLike, *,
                       n_boot: int = 200) -> Floor:
    """The distance of a twin equal to the robot, walked for ``other_n`` (S, A) visits, from
    the real table: two independent samples of the real and of the ``other_n`` sizes drawn
    from :func:`coverage_adjusted` shares (module docstring), their distance's median and
    95 % band over ``n_boot`` resamples of ``rng``. Reads what :func:`bootstrap_floor`'s
    matched floor estimates, without the plug-in's low bias."""
    real_c = _counts(real, "real")
    return _floor(real_c, coverage_adjusted(real_c), rng, n_boot, other_n)


def excess_distance(sim: ArrayLike, real: ArrayLike, rng: np.random.Generator, *,
                    n_boot: int = 32, unvisited: str = "report") -> float:
    """Visit-weighted TV of ``sim`` from ``real`` minus what sampling alone would give if the
    simulator were the truth.

    With few real visits per pair, the plain distance favours simulators whose next states are
    *more certain* than the real robot's (a table of 5 draws looks peaked, and a peaked
    simulator matches it best). The reference here is the median distance between two samples
    drawn from the simulated T itself, of the simulated and of the real visit sizes on the
    pairs both tables visited: a simulator equal to the truth scores about 0 whatever the
    sparsity, a too-certain one is charged for the spread it lacks. ``rng`` draws the
    resamples (seeded: same inputs, same value).
    """
    sim_c, real_c = _counts(sim, "sim"), _counts(real, "real")
    observed = tv_distance(sim_c, real_c, unvisited=unvisited).distance
    if not np.isfinite(observed):
        return float("nan")
    Ts, ns = _probabilities(sim_c)
    _, nr = _probabilities(real_c)
    nr_common = np.where(ns > 0, nr, 0)
    ref = np.empty(int(n_boot))
    for b in range(int(n_boot)):
        ref[b] = tv_distance(_resample(Ts, ns, rng), _resample(Ts, nr_common, rng)).distance
    finite = ref[np.isfinite(ref)]
    # no pair in both tables: nothing of the distance is sampling, all of it is a miss
    return float(observed - (np.median(finite) if finite.size else 0.0))


def cross_entropy(sim: ArrayLike, real: ArrayLike, *, alpha: float = 0.5) -> float:
    """Bits per real transition of the real counts under the simulated T (smoothed).

    ``-sum n_real(s,a,s') log2 q(s'|s,a) / sum n_real`` with
    ``q = (n_sim(s,a,s') + alpha m(s,s')) / (n_sim(s,a) + alpha sum_s' m(s,s'))``, where
    ``m(s, .)`` marks the states the simulation ever reached from ``s`` (any action) and
    ``s`` itself, plus a 1e-6 uniform share so every ``q > 0``. A proper scoring rule: for a
    large simulated sample its expectation is smallest at the real T, whatever the real
    sample size. The TV distance is not: with a few real visits per pair it favours
    low-entropy simulators (the mode of a small sample is over-represented), which pulls a
    search towards moves that stay in their cell. Hence this optional search objective.
    """
    sim_c, real_c = _counts(sim, "sim"), _counts(real, "real")
    if sim_c.shape != real_c.shape:
        raise ConfigError(f"shapes differ: sim {sim_c.shape}, real {real_c.shape}", key="counts")
    S = sim_c.shape[0]
    reach = sim_c.sum(axis=1) > 0
    reach[np.arange(S), np.arange(S)] = True
    m = reach[:, None, :].astype(np.float64)
    q = (sim_c + alpha * m) / (sim_c.sum(axis=2, keepdims=True) + alpha * m.sum(axis=2,
                                                                            keepdims=True))
    q = (1 - 1e-6) * q + 1e-6 / S
    total = real_c.sum()
    if total == 0:
        return float("nan")
    return float(-(real_c * np.log2(q)).sum() / total)


def argmax_agreement(sim: ArrayLike, real: ArrayLike) -> float:
    """Share of the pairs visited in both tables whose most likely next state agrees.

    Decision on ties (common with few visits): the pair agrees when the sets of most
    likely next states of the two tables intersect. Unweighted; NaN with no common pair.
    """
    sim_c, real_c = _counts(sim, "sim"), _counts(real, "real")
    common = (sim_c.sum(axis=2) > 0) & (real_c.sum(axis=2) > 0)
    if not common.any():
        return float("nan")
    s_max = sim_c == sim_c.max(axis=2, keepdims=True)
    r_max = real_c == real_c.max(axis=2, keepdims=True)
    agree = (s_max & r_max).any(axis=2)
    return float(agree[common].mean())


def entropy_per_action(counts: ArrayLike) -> NDArray[np.float64]:
    """``(A,)`` mean next-state entropy (bits) over the visited pairs of each action.

    Plug-in estimate of ``-sum T log2 T`` per pair; NaN for an action never taken.
    """
    c = _counts(counts, "counts")
    T, n = _probabilities(c)
    with np.errstate(divide="ignore", invalid="ignore"):
        H = -np.where(T > 0, T * np.log2(np.where(T > 0, T, 1.0)), 0.0).sum(axis=2)
    visited = n > 0
    out = np.full(c.shape[1], np.nan)
    for a in range(c.shape[1]):
        if visited[:, a].any():
            out[a] = float(H[visited[:, a], a].mean())
    return out


def self_transition_share(counts: ArrayLike) -> float:
    """Share of all transitions with ``s' = s`` (NaN for an empty table)."""
    c = _counts(counts, "counts")
    total = c.sum()
    diag = np.einsum("sas->", c)
    return float(diag / total) if total > 0 else float("nan")


def table_summary(counts: ArrayLike, *, hours: float | None = None,
                  blocked: int | None = None) -> dict[str, object]:
    """Side-by-side numbers of one table (JSON-ready).

    Args:
        counts: ``(S, A, S)`` counts.
        hours: time the table covers (h); gives transitions per hour when known.
        blocked: number of blocked transitions; gives the blocked rate when known.
    """
    c = _counts(counts, "counts")
    total = int(c.sum())
    n = c.sum(axis=2)
    ent = entropy_per_action(c)
    return {
        "states": int(c.shape[0]),
        "states_visited": int((c.sum(axis=(1, 2)) + c.sum(axis=(0, 1)) > 0).sum()),
        "actions": int(c.shape[1]),
        "transitions": total,
        "hours": None if hours is None else float(hours),
        "transitions_per_hour": None if not hours else total / float(hours),
        "pairs_visited": int((n > 0).sum()),
        "mean_entropy_bits": _float(float(np.nanmean(ent))) if np.isfinite(ent).any() else None,
        "entropy_per_action_bits": [_float(float(e)) for e in ent],
        "self_transition_share": _float(self_transition_share(c)),
        "blocked_rate": None if blocked is None or total == 0 else blocked / total,
    }
