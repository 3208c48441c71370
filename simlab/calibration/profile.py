"""What the real table can tell: each searched field moved alone from the winner.

The search's candidates say little of this: the sampler gathers its best candidates near
one another whatever the data tell, and the share of the first rung's score a field explains
(Optuna's PED-ANOVA) is read from walks of a quarter of the real transitions, where sampling
hides most fields. On the ISIR lab the two disagree: ``max_drive_time`` explained 4 % of the
first rung's score, yet moving it down by a quarter of its range raised the confirming-size
score by 0.48 (timeouts end the moves before the state changes).

So the profile measures it where the winner was picked: every searched field is moved alone
by ``step`` of its searched range below and above the winner's value (clipped to the range;
a named field takes each other choice), and each point walks the confirming size on the
winner's first confirming seed (common random numbers with the winner's own walk there). A
move's change of score is read against the score's spread from walk to walk (the winner's
confirming and twin walks on their seeds, ``sigma``): a field is *told* by the table when a
move changes the score by more than :func:`told_band` ``sigma``, the 95 % half-width of the
difference of two independent walks with the spread estimated from the winner's walks
(Student's t for their degrees of freedom, times ``sqrt(2)``: 6.08 from three walks); walks
on one seed differ less, so this errs towards "not told". Each point costs one confirming
walk: ``2 d`` more walks for ``d`` fields (an option of calibrate, ``--profile-step``).

The profile also says which values the data allow (:attr:`FieldProfile.allowed`): a move
that raised the score beyond the band excludes the values past it (the score worsens
further out as it worsened there, which holds for a score with one basin along the field);
any other move excludes nothing on its side, as far as the searched range (nothing was
measured further out). The confirmation has walked other candidates on the same seed, every
field at its own value: one within the band whose value of a field lies past an excluding
move refutes that assumption there, and nothing measured bounds that side any more
(:func:`bounding`). On the synthetic lab's first winner (below) a confirmed candidate at
3.3 Hz, +0.013 against a band of 0.018, so frees the hidden 2 Hz the slice excluded, at no
walk of its own. So a field told on both sides is bounded by its two moves, a field
not told keeps its whole range: that interval is what the report states as the spread the
data allow, and what the synthetic lab's benchmark checks its hidden robot against. A side
left at the searched range's end is *open* (:attr:`FieldProfile.open`): the data set no bound
there, so the statement is "at least" (or "at most") the other side, and a value past that
end is not excluded by anything measured; the report writes such a side as open. It is
the robot's value only as far as the twin can move as the robot does: a field can make up
for an effect the simulator lacks, and then the data allow the value that does. And it is a
slice, not a profile likelihood: the other fields stay at the winner's values, so where two
fields trade off (one raised, the other lowered, the same score) a value the slice excludes
may be allowed with the other field moved too. With ``pairs`` (``--profile-pairs``) the
told numeric fields are then moved two at a time, both diagonals both ways, by the same step
on the same seed (:func:`pair_moves`: up to ``2 t (t - 1)`` more walks for ``t`` told fields),
and a value is excluded only when every point that put the field there raised the score
beyond the band (:func:`excluding`); two fields each told alone whose joint move stays within
the band are *tied* (:meth:`Profile.ties`): the table tells a combination of the two, not
each. The exclusion tests "this value is as good as the winner's": when the best point at a
value is truly no worse, the value is excluded only if that point's own noise passes the band
(at most 2.5 % of walks, less on one seed), however many other points sit there; more points
only free a truly worse value more often (one of them dips below the band), so the pairs widen
the allowed values and never lose the robot's value more often than the slice. Measured on
the synthetic lab (a hidden robot, three calibration seeds, nine searched fields; the normal
band of 2.77, before :func:`told_band`): six fields
held the hidden value on every seed. One winner sat at 10 Hz of localization with little
persistence of its error (0.16) against the hidden 2 Hz and 0.8, and its slice excluded 2 Hz
and the hidden wall back-off; another winner's slice excluded the hidden persistence (allowed
up to 0.76). Every field held the hidden value on one seed of three. Moving the other
fields further from that first winner at each value still excluded frees no more: an Optuna
CMA-ES search of the other eight (eight walks a value) freed neither hidden value, and a
quadratic surface fitted to the slice's and the pairs' walks not the back-off the pairs leave
excluded (they free the 2 Hz there). The hidden robot's values lie in another basin, several
fields away at once, so a value the profile excludes is worse near its winner, not everywhere.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.calibration.search import Candidate, evaluate_points, walk_size
from simlab.calibration.space import ParameterSpace, ParamSpec
from simlab.calibration.walks import WalkRunner


def told_band(dof: float | None = None) -> float:
    """How many walk-to-walk standard deviations a difference of two walks must pass to be
    beyond sampling: ``sqrt(2)`` times the 97.5 % quantile of Student's t with ``dof``, the
    degrees of freedom of the standard deviation's estimate (Student 1908; the 95 %
    half-width of a difference of two walks, the spread measured, not known). ``None``: the
    spread known (the normal quantile, 1.96 * sqrt(2) = 2.77); NaN with no degree of freedom.

    The degrees of freedom matter: calibrate's profile estimates the spread from the winner's
    three twin walks (2 degrees of freedom), where a move that changes nothing passes the
    normal band 2.77 with probability 0.16-0.19 (0.16 as the profile reads it, against one of
    those walks; 0.19 against an independent one), and this band, 6.08, with 0.036-0.05.
    Measured on the synthetic lab of ``benchmarks/calibrate_twin.py`` (eleven calibrate
    seeds, the same walks re-read): the profile's spreads ranged 0.0016-0.0143 around the
    0.0054 the pool's 33 walks measured, and with 2.77 a single run's allowed values held
    every hidden value on 2 seeds of 11, with 6.08 on 5 of 11 (each field's allowed share of
    its range 0.64 and 0.72 on average). That gain is the wider band's, not a truer
    statement: with the spread pooled from the twin walks and the pool's walks of the same
    winners (four degrees of freedom, 3.93) the profiles hold every hidden value on 2 of 11,
    with the pool's 33 walks' spread (2.93 times 0.0054) on none. What a profile excludes is
    mostly worse near its winner beyond sampling: the hidden robot sits in another basin
    (module docstring)."""
    from scipy.stats import t as student_t

    if dof is None or math.isinf(dof):
        return float(1.959963984540054 * math.sqrt(2.0))
    if not dof >= 1:
        return math.nan
    return float(student_t.ppf(0.975, dof) * math.sqrt(2.0))


@dataclass(frozen=True)
class FieldMove:
    """One moved point: the field's ``value`` there, and the point's ``distance`` and
    ``score`` minus the winner's on the same seed; ``partner``, ``partner_value``: the
    second field a pair move moved with it, and its value there (None on the slice);
    ``confirmed``: not a move but another confirmed candidate walked on the same seed, every
    field at its own value (:func:`allowed_values` reads it)."""

    value: Any
    distance_change: float
    score_change: float
    partner: str | None = None
    partner_value: Any = None
    confirmed: bool = False


@dataclass(frozen=True)
class FieldProfile:
    """A field's moves from the winner's ``value``; ``told``: a move changed the score
    beyond sampling (None when the spread is unknown); ``allowed``: the values the moves
    do not exclude (module docstring): ``(low, high)`` of a numeric field, the choices
    left of a named one; None when not measured; ``open``: whether each side of a numeric
    field's ``allowed`` is the searched range's end with no move excluding past it (the data
    set no bound there)."""

    name: str
    value: Any
    moves: tuple[FieldMove, ...]
    told: bool | None
    allowed: tuple[Any, ...] | None = None
    open: tuple[bool, bool] = (False, False)

    def admits(self, value: Any) -> bool | None:
        """Whether ``value`` is among the values the profile allows (None: not measured): in
        ``allowed``, or past one of its open sides (nothing measured excludes it)."""
        if self.allowed is None:
            return None
        if isinstance(self.value, str):
            return value in self.allowed
        low, high = self.allowed
        x = float(value)
        return bool((self.open[0] or low - 1e-12 <= x) and (self.open[1] or x <= high + 1e-12))

    @property
    def alone(self) -> tuple[FieldMove, ...]:
        """The slice's moves: the field moved with the others at the winner's values."""
        return tuple(m for m in self.moves if m.partner is None and not m.confirmed)

    def excluded_alone(self, limit: float) -> set[Any]:
        """The values a move of the field alone excludes (it raised the score beyond
        ``limit``)."""
        return {m.value for m in self.alone if m.score_change > limit}

    def sliced(self, spec: ParamSpec, limit: float) -> FieldProfile:
        """This field as the slice alone states it (its pair moves left out): what the
        profile says without pairs, from the same walks."""
        alone = list(self.alone)
        return FieldProfile(self.name, self.value, tuple(alone), self.told,
                            allowed_values(spec, self.value, alone, limit),
                            open_sides(spec, self.value, alone, limit))

    def past_range(self, value: Any) -> bool:
        """Whether a numeric ``value`` lies past an open side of ``allowed``: admitted, though
        outside the searched range (the search could not have found it)."""
        if self.allowed is None or isinstance(self.value, str):
            return False
        low, high = self.allowed
        x = float(value)
        return bool((self.open[0] and x < low - 1e-12) or (self.open[1] and x > high + 1e-12))


def excluding(mine: list[FieldMove], limit: float) -> list[FieldMove]:
    """The moves of ``mine`` that exclude their value: it raised the score by more than
    ``limit`` at every point that put the field there (the slice's move, and each pair
    move that moved a second field with it: with a pair, the value is excluded only when
    no partner's move made up for it). A confirmed point is not a move and is left out here
    (:func:`bounding` reads it)."""
    best: dict[Any, FieldMove] = {}
    for m in mine:
        if m.confirmed:
            continue
        if m.value not in best or m.score_change < best[m.value].score_change:
            best[m.value] = m
    return [m for m in best.values() if m.score_change > limit]


def bounding(spec: ParamSpec, value: Any, mine: list[FieldMove],
             limit: float) -> list[FieldMove]:
    """The moves of ``mine`` that bound the field's values: those that exclude their value
    (:func:`excluding`), less any a confirmed candidate refutes:
    one within ``limit`` of the winner on the same seed whose value of the field lies past
    the move's, on the same side of the winner's ``value`` (the values past an excluded
    move are excluded on the assumption that the score keeps worsening beyond it; a point
    as good as the winner out there shows it does not, so nothing measured excludes that
    side). A named field's choice is freed by a confirmed candidate with that choice."""
    return [m for m in excluding(mine, limit) if refuting(spec, value, m, mine, limit) is None]


def refuting(spec: ParamSpec, value: Any, move: FieldMove, mine: list[FieldMove],
             limit: float) -> FieldMove | None:
    """The first confirmed point of ``mine`` within ``limit`` that lies past ``move``, on its
    side of the winner's ``value`` (a named field: one with the move's choice), or None
    (:func:`bounding`)."""
    for m in mine:
        if not m.confirmed or m.score_change > limit:
            continue
        if (m.value == move.value if spec.categorical else
                (m.value < move.value < value) or (value < move.value < m.value)):
            return m
    return None


def allowed_values(spec: ParamSpec, value: Any, mine: list[FieldMove],
                   limit: float) -> tuple[Any, ...] | None:
    """What a field's moves ``mine`` from the winner's ``value`` do not exclude, a value
    excluded when every move there raised the score by more than ``limit`` (module
    docstring, :func:`excluding`) and no confirmed candidate as good as the winner lies
    past it (:func:`bounding`); None when ``limit`` is not finite (the spread unknown)."""
    if not math.isfinite(limit):
        return None
    worse = bounding(spec, value, mine, limit)
    if spec.categorical:
        assert spec.choices is not None
        out = {m.value for m in worse}
        return tuple(c for c in spec.choices if c not in out)
    low, high = float(spec.low), float(spec.high)
    for m in worse:
        if m.value < value:
            low = max(low, float(m.value))
        elif m.value > value:
            high = min(high, float(m.value))
    return (low, high)


def open_sides(spec: ParamSpec, value: Any, mine: list[FieldMove],
               limit: float) -> tuple[bool, bool]:
    """Whether the low and the high side of :func:`allowed_values` are open: no move on
    that side raised the score by more than ``limit``, so the side is the searched range's
    end (a named field, or an unknown spread: neither)."""
    if spec.categorical or not math.isfinite(limit):
        return (False, False)
    worse = bounding(spec, value, mine, limit)
    return (not any(m.value < value for m in worse), not any(m.value > value for m in worse))


@dataclass(frozen=True)
class Profile:
    """The profile of a calibration (module docstring).

    Attributes:
        step: the move, as a share of each field's searched range.
        seed, transitions: the seed and size of every walk of the profile.
        distance, score: the winner's on that seed.
        sigma: the score's standard deviation from walk to walk (NaN with fewer than two
            of the winner's walks).
        fields: per searched field, in the space's order.
        pairs: whether the told fields were also moved in pairs (:func:`pair_moves`).
        dof: the degrees of freedom of ``sigma`` (the winner's walks less one), which set
            the band (:func:`told_band`); None in a report written before they were kept:
            that report's band was the normal one.
    """

    step: float
    seed: int
    transitions: int
    distance: float
    score: float
    sigma: float
    fields: tuple[FieldProfile, ...]
    pairs: bool = False
    dof: int | None = None

    def verdicts(self) -> dict[str, bool | None]:
        """``{field: told}``."""
        return {f.name: f.told for f in self.fields}

    @property
    def band(self) -> float:
        """How many ``sigma`` a score change must pass to tell a field (:func:`told_band`)."""
        return told_band(self.dof)

    @property
    def limit(self) -> float:
        """The band a score change must pass to tell a field (NaN when the spread is
        unknown)."""
        return self.band * self.sigma

    def restated(self, space: ParameterSpace, dof: int | None) -> Profile:
        """The same moves read with the band of ``dof`` degrees of freedom (None: the normal
        band): each field's told, allowed values and open sides again (a report written
        before the degrees of freedom were kept read its spread with the normal band)."""
        prof = replace(self, dof=None if dof is None else int(dof))
        limit = prof.limit
        fields = []
        for spec, f in zip(space.specs, self.fields, strict=True):
            mine = list(f.moves)
            told = None if not math.isfinite(limit) else any(
                abs(m.score_change) > limit for m in f.alone)
            fields.append(replace(f, told=told,
                                  allowed=allowed_values(spec, f.value, mine, limit),
                                  open=open_sides(spec, f.value, mine, limit)))
        return replace(prof, fields=tuple(fields))

    @property
    def pair_walks(self) -> int:
        """The walks of the pairs (each pair point is a move of both its fields)."""
        return sum(m.partner is not None for f in self.fields for m in f.moves) // 2

    def ties(self) -> list[tuple[str, str]]:
        """The pairs of fields the data tie (with :attr:`pairs`): a move of each alone
        raised the score beyond the band, yet moving both together (one point of the pairs)
        did not, so the table tells a combination of the two, not each one."""
        limit = self.limit
        if not math.isfinite(limit):
            return []
        out_alone = {f.name: f.excluded_alone(limit) for f in self.fields}
        found: list[tuple[str, str]] = []
        for f in self.fields:
            for m in f.moves:
                pair = tuple(sorted((f.name, m.partner or "")))
                if (m.partner is not None and m.score_change <= limit
                        and m.value in out_alone[f.name]
                        and m.partner_value in out_alone[m.partner] and pair not in found):
                    found.append(pair)  # type: ignore[arg-type]
        return found

    @classmethod
    def from_json(cls, doc: dict[str, Any]) -> Profile:
        """The profile :meth:`to_json` wrote (``report.json``'s ``profile``)."""
        def num(x: float | None) -> float:
            return math.nan if x is None else float(x)

        def field(f: dict[str, Any]) -> FieldProfile:
            moves = tuple(FieldMove(m["value"], float(m["distance_change"]),
                                    float(m["score_change"]),
                                    *((m["with"]["field"], m["with"]["value"])
                                      if m.get("with") else ()),
                                    confirmed=bool(m.get("confirmed", False)))
                          for m in f["moves"])
            allowed = None if f["allowed"] is None else tuple(f["allowed"])
            return FieldProfile(f["field"], f["value"], moves, f["told"], allowed,
                                tuple(f.get("open", (False, False))))  # type: ignore[arg-type]

        return cls(step=float(doc["step"]), seed=int(doc["seed"]),
                   transitions=int(doc["transitions"]), distance=num(doc["distance"]),
                   score=num(doc["score"]), sigma=num(doc["sigma"]),
                   fields=tuple(field(f) for f in doc["fields"]),
                   pairs=bool(doc.get("pairs", False)),
                   dof=None if doc.get("dof") is None else int(doc["dof"]))

    def to_json(self) -> dict[str, Any]:
        def num(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        return {"step": self.step, "seed": self.seed, "transitions": self.transitions,
                "distance": num(self.distance), "score": num(self.score),
                "sigma": num(self.sigma), "dof": self.dof, "band": num(self.band),
                "pairs": self.pairs,
                "ties": [list(t) for t in self.ties()],
                "fields": [{"field": f.name, "value": f.value, "told": f.told,
                            "allowed": None if f.allowed is None else list(f.allowed),
                            "open": list(f.open),
                            "moves": [{"value": m.value, "distance_change": m.distance_change,
                                       "score_change": m.score_change,
                                       "with": None if m.partner is None else
                                       {"field": m.partner, "value": m.partner_value},
                                       "confirmed": m.confirmed}
                                      for m in f.moves]}
                           for f in self.fields]}


def moves(space: ParameterSpace, unit: NDArray[np.float64], step: float
          ) -> list[tuple[int, NDArray[np.float64]]]:
    """``[(field index, moved unit point)]``: each numeric field ``step`` below and above
    ``unit`` (clipped to [0, 1], a move that stays put left out), each named field at its
    other choices."""
    out = []
    for k, spec in enumerate(space.specs):
        if spec.categorical:
            assert spec.choices is not None
            here = spec.value(unit[k])
            targets = [spec.unit(c) for c in spec.choices if c != here]
        else:
            targets = [float(np.clip(unit[k] + s * step, 0.0, 1.0)) for s in (-1.0, 1.0)]
            targets = [t for t in targets if abs(t - unit[k]) > 1e-12]
        for t in targets:
            u = np.array(unit, dtype=np.float64)
            u[k] = t
            out.append((k, u))
    return out


def pair_moves(space: ParameterSpace, unit: NDArray[np.float64], step: float,
               fields: list[int]) -> list[tuple[int, int, NDArray[np.float64]]]:
    """``[(first field, second field, moved unit point)]``: each pair of the numeric
    ``fields`` moved together by ``step`` on both diagonals, both ways (up to four points a
    pair; clipped to [0, 1] as :func:`moves` clips, a point where either field stays put
    left out: the slice has it)."""
    numeric = [k for k in fields if not space.specs[k].categorical]
    out = []
    for a, i in enumerate(numeric):
        for j in numeric[a + 1:]:
            for si in (-1.0, 1.0):
                for sj in (-1.0, 1.0):
                    ti = float(np.clip(unit[i] + si * step, 0.0, 1.0))
                    tj = float(np.clip(unit[j] + sj * step, 0.0, 1.0))
                    if abs(ti - unit[i]) <= 1e-12 or abs(tj - unit[j]) <= 1e-12:
                        continue
                    u = np.array(unit, dtype=np.float64)
                    u[i], u[j] = ti, tj
                    out.append((i, j, u))
    return out


def _walk_points(runner: WalkRunner, points: list[NDArray[np.float64]], stage: str,
                 seed: int, ctx: dict[str, Any], budget: tuple[float | None, int | None]
                 ) -> list[Candidate]:
    """Each unit point walked at ``budget`` on ``seed``, in the config's batches, with a
    progress bar naming ``stage``."""
    from tqdm.auto import tqdm

    cfg = ctx["config"]
    done: list[Candidate] = []
    bar = tqdm(total=len(points), unit="walk", disable=not cfg.progress,
               desc=f"calibrate: {stage} ({walk_size(budget)} a walk)")
    with bar:
        for i in range(0, len(points), cfg.batch):
            chunk = points[i:i + cfg.batch]
            done += evaluate_points(runner, chunk, stage, i, ctx, seeds=[seed] * len(chunk),
                                    budget=budget)
            bar.update(len(chunk))
    return done


def profile_stage(runner: WalkRunner, winner: Candidate, walks: list[Candidate],
                  ctx: dict[str, Any], budget: tuple[float | None, int | None],
                  step: float, pairs: bool = False,
                  confirmed: list[Candidate] | tuple[Candidate, ...] = ()) -> Profile:
    """The profile (module docstring) of ``winner`` from its confirming-size ``walks``
    (its confirming walks then its twin walks, each a :class:`Candidate` with its seed;
    the first is the base of every move); with ``pairs``, the told numeric fields are
    then moved in pairs too (:func:`pair_moves`), and a value is excluded only when no
    point that put the field there stayed within the band (:func:`excluding`).
    ``confirmed``: the confirmation's walks; those of other candidates on the profile's seed
    (common random numbers with every move) join every field's moves as ``confirmed``
    points, so a side whose bound one of them refutes is open (:func:`bounding`)."""
    space: ParameterSpace = ctx["space"]
    base = walks[0]
    points = moves(space, winner.unit, step)
    done = _walk_points(runner, [u for _k, u in points], "profile", base.seed, ctx, budget)
    scores = [w.score for w in walks]
    sigma = float(np.std(scores, ddof=1)) if len(scores) >= 2 else math.nan
    dof = len(scores) - 1
    limit = told_band(dof) * sigma
    mine: list[list[FieldMove]] = [[] for _ in space.specs]
    for (k, _u), c in zip(points, done, strict=True):
        mine[k].append(FieldMove(c.values[space.specs[k].name], c.distance - base.distance,
                                 c.score - base.score))
    told = [None if not math.isfinite(sigma) else
            any(abs(m.score_change) > limit for m in mine[k]) for k in range(space.dim)]
    if pairs:
        both = pair_moves(space, winner.unit, step, [k for k, t in enumerate(told) if t])
        found = _walk_points(runner, [u for _i, _j, u in both], "profile pairs", base.seed,
                             ctx, budget)
        for (i, j, _u), c in zip(both, found, strict=True):
            a, b = space.specs[i].name, space.specs[j].name
            dd, ds = c.distance - base.distance, c.score - base.score
            mine[i].append(FieldMove(c.values[a], dd, ds, b, c.values[b]))
            mine[j].append(FieldMove(c.values[b], dd, ds, a, c.values[a]))
    for c in confirmed:
        if c.seed == base.seed and c.index != winner.index:
            for k, spec in enumerate(space.specs):
                mine[k].append(FieldMove(c.values[spec.name], c.distance - base.distance,
                                         c.score - base.score, confirmed=True))
    # every field's verdict, allowed values and open sides from its moves, as a report is read
    fields = tuple(FieldProfile(spec.name, winner.values[spec.name], tuple(mine[k]), None)
                   for k, spec in enumerate(space.specs))
    return Profile(step=float(step), seed=int(base.seed), transitions=int(base.sim.rows),
                   distance=base.distance, score=base.score, sigma=sigma,
                   fields=fields, pairs=bool(pairs)).restated(space, dof)
