"""The transfer report's figures: each twin's policy scored on the real model per goal,
the spread over twins, and the perfect-twin floor."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from simlab.base.actions import ActionSet
from simlab.base.errors import ConfigError
from simlab.calibration.transfer.models import (
    QTableTwin,
    TransferModel,
    policy_from_q,
    twin_columns,
)
from simlab.calibration.transfer.steps import (
    evaluate_policy,
    goal_mask,
    optimal_action_mask,
    solve_shortest_path,
    twin_policy,
)

#: ``kind`` of ``transfer.json``: ``--overwrite`` replaces only a file carrying it.
KIND = "simlab-transfer"

#: What a twin's choice of a pair the real robot never tried means (``untried`` option).
UNTRIED_RULES = {
    "stay": "the twin's policy as it is; an untried real (s, a) keeps the robot in place, "
            "so it never arrives from there",
    "mask": "the twin's policy chosen among the (s, a) the real robot tried and was seen "
            "to leave its state in",
}


@dataclass(frozen=True, eq=False)
class TwinScore:
    """One twin's policy for one goal, scored on the real model.

    ``policy`` (S,) real action numbers; ``steps`` (S,) expected decisions to the goal on
    the real model (inf: never); ``excess`` (S,) ``steps - optimum`` (nan where the optimum
    is infinite, 0 at goal states); ``disagree`` (S,) bool the action is not a real-optimal
    one (False at goal states and where the optimum is infinite); ``regret`` (S,) one-step
    regret, the extra expected steps of taking the twin's action once and then acting
    optimally, ``Q*(s, pi(s)) - V*(s)`` (inf for an untried action, nan where the optimum is
    infinite, 0 at goal states); ``untried`` (S,) bool the
    action was never tried by the real robot there; ``mean_steps`` the weighted mean over
    the start states; ``never_share`` share (weighted) of start states that never arrive.
    """

    name: str
    policy: NDArray[np.int64]
    steps: NDArray[np.float64]
    excess: NDArray[np.float64]
    disagree: NDArray[np.bool_]
    regret: NDArray[np.float64]
    untried: NDArray[np.bool_]
    mean_steps: float
    never_share: float
    ratio: float


@dataclass(frozen=True, eq=False)
class GoalTransfer:
    """The transfer to one goal: the real optimum and every twin's score.

    ``goal`` (S,) bool; ``starts`` (n,) start states scored, ``weights`` (n,) summing to 1;
    ``unreachable_starts`` start states dropped (the real optimum is infinite there);
    ``optimum`` (S,) real optimal steps; ``optimum_mean`` its weighted mean over starts.
    """

    name: str
    goal: NDArray[np.bool_]
    starts: NDArray[np.int64]
    weights: NDArray[np.float64]
    unreachable_starts: tuple[int, ...]
    optimum: NDArray[np.float64]
    optimum_mean: float
    twins: tuple[TwinScore, ...]
    floor: TransferFloor | None = None

    @property
    def means(self) -> NDArray[np.float64]:
        """(n_twins,) mean steps of each twin."""
        return np.array([t.mean_steps for t in self.twins])

    def summary(self) -> dict[str, float]:
        """Across twins: ``mean``, ``worst``, ``best``, ``spread`` (standard deviation) of
        the mean steps (inf when any twin never arrives from some start), and ``excess``
        of the mean over the optimum (fraction)."""
        m = self.means
        anyinf = not np.all(np.isfinite(m))
        mean = math.inf if anyinf else float(m.mean())
        return {"mean": mean, "worst": float(m.max()), "best": float(m.min()),
                "spread": math.inf if anyinf else float(m.std()),
                "excess": (mean / self.optimum_mean - 1.0) if self.optimum_mean > 0
                else math.nan}


@dataclass(frozen=True, eq=False)
class TransferResult:
    """:func:`transfer_report`'s result: one :class:`GoalTransfer` per goal."""

    goals: tuple[GoalTransfer, ...]
    real_name: str
    twin_names: tuple[str, ...]
    action_set: ActionSet | None
    weighting: str
    centres: NDArray[np.float64] | None = None
    untried: str = "stay"
    #: per twin, the perfect twin at that twin's data (:func:`perfect_twin_line`; None
    #: where it is not computed: a Q-table twin, no real counts, no resamples)
    lines: tuple[Any, ...] = ()
    #: real states whose rows were an episode reset, given the twins' rows
    reset_states: tuple[int, ...] = ()

    def overview(self) -> dict[str, Any]:
        """Over every goal: each twin's ratio of summed steps to the summed real optimum
        (:meth:`overall_ratios`), and the perfect twin at the same data beside it."""
        ratios = self.overall_ratios()
        lines = self.lines or (None,) * len(ratios)
        return {"goals": len(self.goals), "twins": [
            {"twin": n, "ratio": _num(float(r)),
             "perfect_twin_same_data": None if ln is None else _num(ln.median),
             "gap": None if ln is None or not (math.isfinite(r) and math.isfinite(ln.median))
             else float(r / ln.median - 1.0)}
            for n, r, ln in zip(self.twin_names, ratios, lines, strict=True)]}

    def overview_line(self) -> str:
        """The overview in one line (several goals): per twin its ratio and the line."""
        parts = []
        for t in self.overview()["twins"]:
            r = "never" if t["ratio"] is None else f"{t['ratio']:.3f}"
            line = ("" if t["perfect_twin_same_data"] is None else
                    f" against a perfect twin's {t['perfect_twin_same_data']:.3f} at the same "
                    f"data" + ("" if t["gap"] is None else f" ({100 * t['gap']:+.1f} %)"))
            parts.append(f"{t['twin']}: {r}{line}")
        return (f"over {len(self.goals)} goals, steps / real optimum (summed): "
                + "; ".join(parts))

    def to_json(self) -> dict[str, Any]:
        """Plain types; infinite steps are ``null`` ("never")."""
        return {
            "kind": KIND,
            "real": self.real_name,
            "over_goals": self.overview(),
            "perfect_twin_lines": [None if ln is None else ln.to_json() for ln in self.lines],
            "reset_states": list(self.reset_states),
            "twins": list(self.twin_names),
            "action_set": None if self.action_set is None else self.action_set.to_json(),
            "weights": self.weighting,
            "untried": self.untried,
            "untried_rule": UNTRIED_RULES[self.untried],
            "goals": [_goal_json(g) for g in self.goals],
        }

    def overall_ratios(self) -> NDArray[np.float64]:
        """(n_twins,) each twin's expected steps summed over the goals, over the real
        optimum summed over the same goals (a random start and a random goal: long trips
        weigh more than a start next to its goal); goals the real optimum cannot reach are
        left out, ``inf`` when the twin never arrives for some goal, NaN without goals."""
        opt = np.array([g.optimum_mean for g in self.goals], dtype=np.float64)
        ok = np.isfinite(opt) & (opt > 0)
        out = np.full(len(self.twin_names), math.nan)
        if not ok.any():
            return out
        for k in range(len(self.twin_names)):
            steps = np.array([g.twins[k].mean_steps for g in self.goals], dtype=np.float64)
            out[k] = steps[ok].sum() / opt[ok].sum()
        return out

    def summary_line(self) -> str:
        """``twin policy: mean X steps, worst Y, real optimum Z (+N %)``, one such clause
        per goal (prefixed by its name when there are several); a mean over twins of which
        some never arrive says how many."""
        parts = []
        for g in self.goals:
            s = g.summary()
            label = "twin policy" if len(self.goals) == 1 else f"goal {g.name}: twin policy"
            never = int(np.sum(~np.isfinite(g.means)))
            if math.isfinite(s["mean"]):
                mean = (f"mean {fmt_steps(s['mean'])} steps ({fmt_pct(s['excess'])} over the "
                        f"real optimum {fmt_steps(g.optimum_mean)}), worst "
                        f"{fmt_steps(s['worst'])}")
            else:
                best = (f"the best {fmt_steps(s['best'])} steps" if math.isfinite(s["best"])
                        else "none arrives")
                mean = (f"{never} of {len(g.twins)} twin(s) never arrive from some start "
                        f"(no mean), {best}; real optimum {fmt_steps(g.optimum_mean)} steps")
            part = f"{label}: {mean}"
            if g.floor is not None:
                part += "; " + g.floor.phrase()
            parts.append(part)
        return "; ".join(parts)


def _num(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def fmt_steps(x: float) -> str:
    return f"{x:.2f}" if math.isfinite(x) else "never"


def fmt_pct(x: float) -> str:
    if math.isnan(x):
        return "n/a"
    return f"{100 * x:+.1f} %" if math.isfinite(x) else "never"


def _floats(a: ArrayLike) -> list[float | None]:
    return [_num(float(v)) for v in np.asarray(a, dtype=np.float64)]


def _goal_json(g: GoalTransfer) -> dict[str, Any]:
    s = g.summary()
    return {
        "name": g.name,
        "goal_states": np.flatnonzero(g.goal).tolist(),
        "start_states": g.starts.tolist(),
        "weights": g.weights.tolist(),
        "unreachable_starts": list(g.unreachable_starts),
        "optimum_mean": _num(g.optimum_mean),
        "optimum": _floats(g.optimum),
        "across_twins": {k: _num(v) for k, v in s.items()},
        "perfect_twin_floor": None if g.floor is None else g.floor.to_json(),
        "twins": [{
            "name": t.name, "mean_steps": _num(t.mean_steps), "ratio": _num(t.ratio),
            "never_share": t.never_share,
            "disagreements": int(t.disagree.sum()),
            "untried_choices": int(t.untried.sum()),
            "policy": t.policy.tolist(), "steps": _floats(t.steps),
            "excess": _floats(t.excess), "regret": _floats(t.regret),
            "disagree_states": np.flatnonzero(t.disagree).tolist(),
        } for t in g.twins],
    }


def _start_states(real: TransferModel, goal: NDArray[np.bool_],
                  starts: ArrayLike | None) -> NDArray[np.int64]:
    S = real.n_states
    if starts is None:
        left = real.allowed.any(axis=1) if real.visits is None else real.visits > 0
        return np.flatnonzero(left & ~goal).astype(np.int64)
    ids = np.asarray(starts).ravel()
    if ids.size and not np.issubdtype(ids.dtype, np.integer):
        raise ConfigError(f"expected state ids, got {ids.tolist()!r}", key="start_states")
    bad = [int(s) for s in ids if not 0 <= int(s) < S]
    if bad:
        raise ConfigError(f"states {bad} not in [0, {S})", key="start_states")
    ids = np.unique(ids.astype(np.int64))
    if goal[ids].any():
        raise ConfigError(f"start state {int(ids[goal[ids]][0])} is a goal state: a policy "
                          "starting there has arrived before its first step, so there is "
                          "nothing to score", key="start_states",
                          fix="give start states apart from the goal")
    return ids


def _weights(real: TransferModel, starts: NDArray[np.int64], weighting: str
             ) -> NDArray[np.float64]:
    if weighting == "uniform" or starts.size == 0:
        return np.full(starts.size, 1.0 / max(starts.size, 1))
    if weighting != "visits":
        raise ConfigError(f"expected uniform or visits, got {weighting!r}", key="weights")
    if real.visits is None:
        raise ConfigError("the real model has no visit counts", key="weights",
                          fix="use --weights uniform, or give the real counts")
    w = real.visits[starts].astype(np.float64)
    if w.sum() <= 0:
        raise ConfigError("the start states were never visited by the real robot",
                          key="weights", fix="use --weights uniform")
    return w / w.sum()


def _weighted_mean(values: NDArray[np.float64], w: NDArray[np.float64]) -> float:
    if values.size == 0:
        return math.nan
    pos = w > 0
    if not np.all(np.isfinite(values[pos])):
        return math.inf
    return float(np.sum(values[pos] * w[pos]))


def _twin_policy_for(twin: TransferModel | QTableTwin, goal: NDArray[np.bool_], name: str,
                     columns: NDArray[np.int64], restrict: NDArray[np.bool_] | None
                     ) -> NDArray[np.int64]:
    if isinstance(twin, QTableTwin):
        table = twin.table_for(goal)
        if table is None:
            raise ConfigError(f"no Q-table for goal {name} (states "
                              f"{np.flatnonzero(goal).tolist()})", path=twin.name,
                              key="goal", fix="train it with simlab train --goal-states, or "
                              "choose --goal-states of a trained goal")
        return policy_from_q(table, columns, restrict)
    mask = twin.allowed[:, columns]
    if restrict is not None:
        narrowed = mask & restrict
        mask = np.where(narrowed.any(axis=1, keepdims=True), narrowed, mask)
    return twin_policy(twin.T[:, columns], goal, mask)


def transfer_report(
    real: TransferModel,
    twins: Sequence[TransferModel | QTableTwin],
    goals: Mapping[str, ArrayLike],
    starts: ArrayLike | None = None,
    *,
    weights: str = "uniform",
    untried: str = "stay",
    n_boot: int = 0,
    rng: np.random.Generator | None = None,
) -> TransferResult:
    """Score each twin's policy on the real model, for each goal.

    Args:
        real: the real robot's model (:meth:`TransferModel.from_counts` or ``from_mdp``);
            its ``allowed`` pairs are the only ones a real plan may use, an untried pair
            chosen by a twin keeps the robot in place (module docstring).
        twins: one per twin seed: a :class:`TransferModel` (its shortest-path policy,
            :func:`twin_policy`, over its allowed pairs) or a :class:`QTableTwin` (the
            greedy policy of its Q-table for the goal, :func:`policy_from_q`). Same states
            as ``real``; actions mapped onto the real ones by :func:`twin_columns`.
        goals: goal name -> (S,) bool mask or goal state ids.
        starts: start state ids (goal states removed); None: every non-goal state the real
            robot left (visits > 0, else any tried pair).
        weights: ``uniform`` over the start states, or ``visits`` (the real decisions taken
            in each start state).
        untried: ``stay`` (default): the twin's policy as it is; where it picks a pair the
            real robot never tried, the robot stays put (never arrives from there, module
            docstring). ``mask``: the twin's policy is chosen among the pairs the real
            robot tried (a twin that knows the real coverage); the strict score is then
            no longer what the twin alone would do.
        n_boot: resamples of :func:`transfer_floor` (0: no floor); needs ``real.counts``.
        rng: the Generator of those resamples (required when ``n_boot > 0``).

    Returns:
        A :class:`TransferResult`; steps in decisions (actions), ``inf`` = never arrives.

    Raises:
        ConfigError: no twin or goal, states or actions that disagree, a goal without a
            Q-table, bad start states or weights.
    """
    _check_options(twins, goals, weights, untried, n_boot, rng)
    restrict = moving_pairs(real) if untried == "mask" else None
    cols = [columns_of(t, real) for t in twins]
    out = []
    for gname, gspec in goals.items():
        g = goal_mask(gspec, real.n_states)
        if not reached(real, g):
            raise ConfigError(f"the real robot never reached goal {gname} (no real "
                              f"transition ends in state(s) {np.flatnonzero(g).tolist()}): "
                              "no policy can be scored towards it", key="goal_states",
                              fix="choose a goal the real data reach")
        V, Q, _ = solve_shortest_path(real.T, g, real.allowed)
        st = _start_states(real, g, starts)
        unreachable = tuple(int(s) for s in st if not np.isfinite(V[s]))
        st = st[np.isfinite(V[st])]
        w = _weights(real, st, weights)
        opt_mean = _weighted_mean(V[st], w)
        scores = tuple(
            _score_twin(real, t.name, _twin_policy_for(t, g, gname, c, restrict), g, V, Q, st,
                        w, opt_mean)
            for t, c in zip(twins, cols, strict=True))
        floor = None
        if n_boot and real.counts is not None and st.size:
            floor = transfer_floor(real, g, st, w, n_boot=n_boot, rng=rng)  # type: ignore[arg-type]
        out.append(GoalTransfer(name=str(gname), goal=g, starts=st, weights=w,
                                unreachable_starts=unreachable, optimum=V,
                                optimum_mean=opt_mean, twins=scores, floor=floor))
    return TransferResult(goals=tuple(out), real_name=real.name,
                          twin_names=tuple(t.name for t in twins),
                          action_set=real.action_set, weighting=weights,
                          centres=real.centres, untried=untried)


def moving_pairs(real: TransferModel) -> NDArray[np.bool_]:
    """(S, A) bool the pairs the real robot tried and was seen to leave its state in at
    least once: what a twin that knows the real coverage chooses among (rule ``mask``). A
    pair tried only in place, every outcome a stay, holds the robot there for good on the
    real model, whatever the twin believes it does."""
    rows = np.arange(real.n_states)
    return real.allowed & (real.T[rows, :, rows] < 1.0)


def reached(real: TransferModel, goal: NDArray[np.bool_]) -> bool:
    """Whether some tried real pair outside ``goal`` (S,) bool leads into it."""
    into = real.T[~goal][:, :, goal].sum(axis=2) * real.allowed[~goal]
    return bool((into > 0).any())


def _check_options(twins: Sequence[Any], goals: Mapping[str, ArrayLike], weights: str,
                   untried: str, n_boot: int, rng: np.random.Generator | None) -> None:
    if not twins:
        raise ConfigError("no twin to score", key="sim")
    if not goals:
        raise ConfigError("no goal", key="goal_states", fix="give --goal-states, e.g. 18,34")
    if weights not in ("uniform", "visits"):
        raise ConfigError(f"expected uniform or visits, got {weights!r}", key="weights")
    if untried not in UNTRIED_RULES:
        raise ConfigError(f"expected stay or mask, got {untried!r}", key="untried")
    if n_boot and rng is None:
        raise ConfigError("the sampling floor needs a numpy Generator", key="rng",
                          fix="pass rng=np.random.default_rng(seed), or n_boot=0")


def columns_of(twin: TransferModel | QTableTwin, real: TransferModel) -> NDArray[np.int64]:
    """(A_real,) the twin's column of each real action, once the states agree."""
    if twin.n_states != real.n_states:
        raise ConfigError(f"{twin.n_states} states against the real model's {real.n_states}",
                          path=twin.name, key="states",
                          fix="use twins built on the real model's states file")
    if twin.n_actions != real.n_actions:
        raise ConfigError(f"{twin.n_actions} actions against the real model's "
                          f"{real.n_actions}: a twin of a robot walks that robot's own actions "
                          "(its data spread over primitives the robot does not have)",
                          path=twin.name, key="action_set",
                          fix="collect the twin in the real action set (collect --n-actions "
                          f"{real.n_actions} --convention ... --speed ...) and estimate it")
    return twin_columns(twin.action_set, real.action_set, n_twin=twin.n_actions,
                        n_real=real.n_actions, where=twin.name)


def _score_twin(real: TransferModel, name: str, pi: NDArray[np.int64], g: NDArray[np.bool_],
                V: NDArray[np.float64], Q: NDArray[np.float64], st: NDArray[np.int64],
                w: NDArray[np.float64], opt_mean: float) -> TwinScore:
    """One twin's policy ``pi`` (S,) for goal ``g`` on the real model, against its optimum
    ``V``/``Q`` over the starts ``st`` weighted ``w``."""
    S = real.n_states
    rows = np.arange(S)
    steps = evaluate_policy(real.T, pi, g, real.allowed)
    fin = np.isfinite(V)
    V0 = np.where(fin, V, 0.0)
    excess = np.where(fin, steps - V0, np.nan)
    excess[g] = 0.0
    regret = np.where(fin, Q[rows, pi] - V0, np.nan)
    regret[g] = 0.0
    mean = _weighted_mean(steps[st], w)
    never = float(np.sum(w[~np.isfinite(steps[st])])) if st.size else 0.0
    return TwinScore(name=name, policy=pi, steps=steps, excess=excess,
                     disagree=fin & ~g & ~optimal_action_mask(V, Q, g)[rows, pi],
                     regret=regret, untried=~g & ~real.allowed[rows, pi], mean_steps=mean,
                     never_share=never, ratio=mean / opt_mean if opt_mean > 0 else math.nan)


@dataclass(frozen=True)
class TransferFloor:
    """What a perfect twin scores against a real model estimated from this much data.

    ``ratios`` (n_boot,) mean steps of the perfect twin's policy over the resampled real
    optimum (inf: it never arrives from some start in that resample); ``median``, ``low``,
    ``high`` their 50, 2.5 and 97.5 % quantiles.
    """

    ratios: NDArray[np.float64]
    median: float
    low: float
    high: float

    @property
    def never_share(self) -> float:
        """Share of the resamples on which the perfect twin's plan never arrives."""
        return float(np.mean(np.isinf(self.ratios))) if self.ratios.size else math.nan

    def phrase(self) -> str:
        """The floor in words: its median and band, or why there is none."""
        if math.isfinite(self.median):
            return (f"a perfect twin would score {fmt_pct(self.median - 1.0)} (95 %: "
                    f"{fmt_pct(self.low - 1.0)} to {fmt_pct(self.high - 1.0)})")
        return (f"no perfect-twin score: even the real robot's own plan never arrives on "
                f"{100 * self.never_share:.0f} % of the real data's resamples (too few real "
                "transitions per pair to score policies by their steps)")

    def to_json(self) -> dict[str, Any]:
        return {"n_boot": int(self.ratios.size), "ratio_median": _num(self.median),
                "ratio_low_2.5": _num(self.low), "ratio_high_97.5": _num(self.high),
                "never_share": self.never_share}


def transfer_floor(real: TransferModel, goal: ArrayLike, starts: ArrayLike,
                   weights: ArrayLike, *, n_boot: int, rng: np.random.Generator
                   ) -> TransferFloor:
    """The ratio a perfect twin scores, by parametric bootstrap of the real counts.

    The optimum of an estimated model is biased low: its plan exploits the transitions that
    were lucky in the sample (the optimizer's curse, Smith & Winkler 2006, Management
    Science 52(3)), so even a twin equal to the true robot scores above the "real optimum".
    How much depends on the number of real transitions per pair. Each resample draws
    ``counts*(s, a, .) ~ Multinomial(n(s, a), T(s, a, .))`` (Efron & Tibshirani 1993, ch. 6),
    then scores the real optimum's policy (standing for the true robot's plan) on the
    resampled model against that model's own optimum: mean steps over ``starts`` with
    ``weights`` (starts the resample cannot reach are left out of that resample). A
    resample never holds a transition the real data missed, so with few real transitions per
    pair the gap it finds is rather a lower bound of the true one.

    Args:
        real: the real model with its ``counts`` (S, A, S).
        goal: (S,) bool or goal state ids.
        starts: (n,) start states; weights: (n,) their weights.
        n_boot: resamples (>= 1); rng: their Generator.
    """
    from simlab.data.count_model import transition_matrix

    if real.counts is None:
        raise ConfigError("the real model has no counts", path=real.name, key="counts",
                          fix="give the real count file or an mdp.npz with counts")
    S = real.n_states
    g = goal_mask(goal, S)
    st = np.asarray(starts, dtype=np.int64)
    w = np.asarray(weights, dtype=np.float64)
    pi = solve_shortest_path(real.T, g, real.allowed)[2]
    n_sa = real.counts.sum(axis=2)
    ratios = np.empty(int(n_boot))
    for b in range(int(n_boot)):
        T, visited = transition_matrix(rng.multinomial(n_sa, real.T / real.T.sum(axis=2,
                                                                                keepdims=True)))
        V = solve_shortest_path(T, g, visited)[0]
        h = evaluate_policy(T, pi, g, visited)
        keep = np.isfinite(V[st]) & (w > 0)
        if not keep.any():
            ratios[b] = math.nan
            continue
        wk = w[keep] / w[keep].sum()
        opt = float(np.sum(V[st][keep] * wk))
        hk = h[st][keep]
        ratios[b] = math.inf if not np.all(np.isfinite(hk)) else float(np.sum(hk * wk)) / opt
    r = ratios[~np.isnan(ratios)]
    if r.size == 0:
        return TransferFloor(ratios=ratios, median=math.nan, low=math.nan, high=math.nan)
    q = np.quantile(r, [0.5, 0.025, 0.975], method="inverted_cdf")
    return TransferFloor(ratios=ratios, median=float(q[0]), low=float(q[1]), high=float(q[2]))


@dataclass(frozen=True)
class PerfectLine:
    """What a perfect twin of a given amount of data scores (:func:`perfect_twin_line`).

    ``overall`` (n_boot,) its summed steps over the summed real optimum, over the goals, per
    resample (inf: it never arrives from some start); ``per_goal`` (n_goals, n_boot) the
    same per goal; ``transitions`` the twin's data; ``median``/``goal_medians`` their
    medians over the resamples.
    """

    transitions: int
    overall: NDArray[np.float64]
    per_goal: NDArray[np.float64]
    goal_names: tuple[str, ...]

    @property
    def median(self) -> float:
        return _median(self.overall)

    @property
    def goal_medians(self) -> NDArray[np.float64]:
        return np.array([_median(r) for r in self.per_goal])

    def to_json(self) -> dict[str, Any]:
        return {"transitions": self.transitions, "n_boot": int(self.overall.size),
                "ratio_median": _num(self.median),
                "ratio_low_2.5": _num(_quantile(self.overall, 0.025)),
                "ratio_high_97.5": _num(_quantile(self.overall, 0.975)),
                "never_share": float(np.mean(np.isinf(self.overall))) if self.overall.size
                else None,
                "per_goal": {n: _num(m) for n, m in zip(self.goal_names, self.goal_medians,
                                                        strict=True)}}


def _median(x: NDArray[np.float64]) -> float:
    return _quantile(x, 0.5)


def _quantile(x: NDArray[np.float64], q: float) -> float:
    x = x[~np.isnan(x)]
    return float(np.quantile(x, q, method="inverted_cdf")) if x.size else math.nan


def perfect_twin_line(real: TransferModel, result: TransferResult, visits: ArrayLike, *,
                      n_boot: int, rng: np.random.Generator,
                      adjusted: bool = True) -> PerfectLine:
    """The score of a perfect twin with the data ``visits`` (S, A) (transitions per pair),
    on the goals and starts of ``result``, by parametric bootstrap of the real counts.

    A twin equal to the true robot, walked for ``visits``, is still an estimate: its plan
    exploits the noise of its own sample, and it is scored on a real model that is itself an
    estimate (whose optimum is biased low, :func:`transfer_floor`). Each resample draws both
    from shares ``T`` standing for the truth: the twin's counts
    ``Multinomial(visits(s, a), T(s, a, .))`` on the pairs the real robot tried (its other
    pairs stay untried), and a real model at the real counts' sizes. ``T`` is the real
    counts' coverage-adjusted shares (:func:`~simlab.calibration.metrics.coverage_adjusted`;
    ``adjusted=False``: the plug-in shares of the real model), since a row of a few visits
    lacks the rare outcomes the robot has, and a line drawn from its own shares reads low: on
    a lab whose robot is a known physics walk, that robot's own walks of 8,012 transitions
    score 1.078-1.099x the optimum over three real tables, a plug-in line 1.056-1.072x, the
    coverage-adjusted one 1.079-1.102x. The twin's shortest-path
    policy is scored on that real model against its optimum, as :func:`transfer_report`
    scores a twin. A calibrated twin is read against this line at its own data: the gap is
    what the calibration leaves, the rest is data.
    """
    from simlab.data.count_model import transition_matrix

    if real.counts is None:
        raise ConfigError("the real model has no counts", path=real.name, key="counts",
                          fix="give the real count file or an mdp.npz with counts")
    v = np.where(real.allowed, np.asarray(visits, dtype=np.int64), 0)
    n_real = real.counts.sum(axis=2)
    P = real.T / real.T.sum(axis=2, keepdims=True)
    if adjusted:
        from simlab.calibration.metrics import coverage_adjusted

        P = np.where((n_real > 0)[..., None], coverage_adjusted(real.counts), P)
    goals = result.goals
    per_goal = np.full((len(goals), int(n_boot)), math.nan)
    overall = np.full(int(n_boot), math.nan)
    for b in range(int(n_boot)):
        T_twin, seen = transition_matrix(rng.multinomial(v, P))
        T_real, tried = transition_matrix(rng.multinomial(n_real, P))
        steps_sum = opt_sum = 0.0
        for k, g in enumerate(goals):
            V = solve_shortest_path(T_real, g.goal, tried)[0]
            pi = solve_shortest_path(T_twin, g.goal, seen)[2]
            h = evaluate_policy(T_real, pi, g.goal, tried)
            keep = np.isfinite(V[g.starts]) & (g.weights > 0)
            if not keep.any():
                continue
            w = g.weights[keep] / g.weights[keep].sum()
            opt = float(np.sum(V[g.starts][keep] * w))
            hk = h[g.starts][keep]
            mean = math.inf if not np.all(np.isfinite(hk)) else float(np.sum(hk * w))
            per_goal[k, b] = mean / opt if opt > 0 else math.nan
            steps_sum += mean
            opt_sum += opt
        overall[b] = steps_sum / opt_sum if opt_sum > 0 else math.nan
    return PerfectLine(transitions=int(v.sum()), overall=overall, per_goal=per_goal,
                       goal_names=tuple(g.name for g in goals))
