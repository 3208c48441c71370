"""Several calibrations of one lab pooled: which basins the data allow, and what they allow.

A calibration's profile (:mod:`~simlab.calibration.profile`) reads the basin its winner sits
in: a value it excludes is worse *near that winner*, not everywhere. On the synthetic lab
of ``benchmarks/calibrate_twin.py`` three calibrate seeds landed in different basins, each
within sampling of the others on fresh walks, and each one's profile excluded one hidden
value the others allowed (the localization's rate and wall back-off on one, the error's
persistence on another). Restarting the search from other seeds is the well-tried answer
to a search with several basins (a multi-start); this module reads the restarts together.

Every run's winner (its ``primitives.toml``, fitted decision latency included) walks the
same fresh seeds at the confirming size (common random numbers across the winners), and
each walk is scored as the runs scored theirs, one objective for all. The best mean score
is the pool's winner. A run *joins* the pool when its mean score is within sampling of the
best's: by at most :func:`~simlab.calibration.profile.told_band` ``sigma / sqrt(n)``, the
95 % half-width of a difference of two means of ``n`` independent walks, ``sigma`` the
walk-to-walk standard deviation of the score pooled over the runs' own walks here (Student's
t for its ``runs * (n - 1)`` degrees of freedom; walks on common seeds differ less, so this
errs towards joining, as the profile errs towards "not told").

What the data allow, field by field, is then the union of the joined runs' allowed values:
a value is allowed when it is within the profile's band of a winner that is itself within
sampling of the best. That chains two tests, so it states somewhat more than one profile
would; it is the statement that does not depend on which basin one search happened to
reach. The joined winners form a twin ensemble across basins (``[[ensemble]]`` of the
pool's ``primitives.toml``, each member with its own fitted latency), which ``collect`` and
``online --arena`` draw from with ``--ensemble``.

The pool's walks also say what each basin's policies are worth on the robot: each winner's
walks pooled into one twin, its shortest-path policy per goal scored on the real model beside
a perfect twin with the same data (:mod:`~simlab.calibration.policies`), and, with two
joined runs or more, the same number of walks drawn across the joined winners in turn (walk
``j`` from joined run ``j mod m``, on the winner's seed ``j``): whether the ensemble across
basins transfers better than the pool's winner alone. No walk is added for it. Measured
(synthetic seeds 0-2 and 0-5; ISIR seeds 1-2 on three sets of pool seeds): the ensemble took
1.066x, 1.075x, 1.080x and 1.102x the real optimum's steps against its winner's 1.064x, 1.073x,
1.098x and 1.101x, a perfect twin with the same data 1.040x-1.069x: better once in four, so the
recommended twin stays the single winner and the ensemble is there for domain randomisation.

Measured on that synthetic lab (seeds 0 to 2, three pool seeds, the normal bands of 2.77):
seeds 0 and 2 joined (+0.003 against a band of 0.008), seed 1 did not (+0.017), and the union
of seeds 0 and 2 held the hidden value of every field, which neither run's profile did alone;
on seeds 3 to 5 only seed 3 joined, and its statement excluded the hidden 2 Hz (with
Student's bands both triples hold every hidden value). Read, with Student's bands,
for every subset of eleven seeds from one pool's walks, every hidden value was inside on 45 %
of single seeds, 73 % of triples, 88 % of fives, 99 % of eights and every nine or more; the one
independent five (seeds 6-10) failed. With each profile's spread known better (pooled with
the pool's walks of its winner: 18 %, 45 %, 72 %, 98 %) fewer small pools hold it; with three
more seeds (fourteen read as one pool) eights hold it on 98 % (82 % read sharply) and elevens
on 98-100 % whichever. The union is wider with more seeds (0.72 of each field's
range for one seed, 0.80 for five, 0.83 for eleven); the fields it allows over
:data:`OPEN_SHARE` of their range or more are named as left open.

Each winner's pool walks are also tested against the real table pair by pair
(:mod:`~simlab.calibration.contradictions`), and the pairs **every** winner contradicts beyond
sampling are named: winners at different points of the searched space that all differ from
the robot at a pair point at the map or the arena there, not at a field (ISIR seeds 0-4: five
such pairs, all at the lab's two ends).

Outputs in ``--out``: ``primitives.toml`` (the pool's winner, and the ensemble), ``pool.json``
and ``pool.md``.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base.actions import ActionSet, ActionSetOptions
from simlab.base.errors import ConfigError
from simlab.base.io import atomic_write_json, atomic_write_text, ensure_new, output_transaction
from simlab.base.options import command, option
from simlab.calibration.command import CalibrateConfig
from simlab.calibration.config import CalibrationConfig
from simlab.calibration.contradictions import Contradictions, common_pairs, contradicted_pairs
from simlab.calibration.metrics import perfect_twin_floor
from simlab.calibration.profile import FieldProfile, Profile, told_band
from simlab.calibration.space import ParameterSpace, ParamSpec

#: ``kind`` of ``pool.json``: what ``--overwrite`` recognises as the pool's own.
KIND = "simlab-calibrate-pool"
FILES = ("primitives.toml", "pool.json", "pool.md")
#: First seed of the pool's walks: far from any seed a calibration walks (its seed and the
#: few after it), so the walks are fresh for every run; a clash is refused.
FIRST_SEED = 100_000
#: Options every pooled run must share: they decide what a score is and how a walk is made.
SHARED = ("objective", "unvisited", "signature_weight", "simulator", "pose_source",
          "start_states", "reset_states")


@dataclass(frozen=True)
class Run:
    """One calibration read back: its folder, ``report.json``, winner and profile."""

    path: Path
    report: dict[str, Any]
    params: Any
    profile: Profile | None
    #: the walks behind the profile's spread, when the report did not keep its degrees of
    #: freedom and the profile was re-read with Student's band for them (:func:`read_run`)
    restated: int | None = None

    @property
    def seed(self) -> int:
        return int(self.report["config"]["seed"])

    def seeds_walked(self) -> range:
        """The walk seeds the calibration used (search, rungs, confirmation, twins)."""
        c = self.report["config"]
        return range(self.seed, self.seed + int(c["rungs"]) + int(c["confirm_seeds"])
                     + int(c["transfer_seeds"]) + 1)


@dataclass(frozen=True)
class PooledField:
    """A searched field across the joined runs: each run's winner ``values``, its allowed
    ``spans`` (``(low, high, open low, open high)``, a named field's choices as a tuple of
    them), and their union ``allowed`` (merged intervals with open ends; the choices).
    ``share``: the union's share of the searched range (:func:`range_share`)."""

    name: str
    categorical: bool
    values: tuple[Any, ...]
    spans: tuple[Any, ...]
    allowed: tuple[Any, ...] | None
    share: float | None = None

    def admits(self, value: Any) -> bool | None:
        """Whether ``value`` lies in the union (None: no joined run measured it)."""
        if self.allowed is None:
            return None
        if self.categorical:
            return value in self.allowed
        x = float(value)
        return any((lo_open or lo - 1e-12 <= x) and (hi_open or x <= hi + 1e-12)
                   for lo, hi, lo_open, hi_open in self.allowed)

    def to_json(self) -> dict[str, Any]:
        return {"field": self.name, "values": list(self.values),
                "spans": [None if s is None else list(s) for s in self.spans],
                "allowed": None if self.allowed is None else [
                    s if self.categorical else list(s) for s in self.allowed],
                "share": self.share}


#: What pool.md and the command say when only the pool's winner is within sampling: the union
#: is that run's profile, one basin. Measured on the synthetic lab of
#: ``benchmarks/calibrate_twin.py`` (fourteen calibrate seeds read as one pool), every hidden
#: value was inside on 33-68 % of three-seed pools and 82-98 % of eight-seed ones.
ONE_BASIN = (" Only the pool's winner is within sampling of the best: the union is its profile "
             "alone, one basin. Calibrations from more seeds can reach others as good.")

#: A field whose union allows at least this share of its searched range is one the pooled
#: basins leave open: the data do not tell it.
OPEN_SHARE = 0.9


def range_share(spec: ParamSpec, allowed: tuple[Any, ...] | None) -> float | None:
    """The share of ``spec``'s searched range that ``allowed`` covers, in the search's own
    scale (log fields in log units: the unit cube the search samples); a named field's
    choices as a share of its choices. An open end reaches the range's edge."""
    if allowed is None:
        return None
    if spec.choices is not None:
        return len(allowed) / len(spec.choices)
    return float(sum((1.0 if hi_open else spec.unit(hi)) - (0.0 if lo_open else spec.unit(lo))
                     for lo, hi, lo_open, hi_open in allowed))


@dataclass(frozen=True)
class PoolTransfer:
    """Each winner's pool walks pooled into one twin, its shortest-path policy per goal
    scored on the real model (steps summed over the goals, over the real optimum's:
    ``ratios``, one per run, inf where a policy never arrives), beside ``perfect``: a perfect
    twin with the same data (:func:`~simlab.calibration.transfer.score.perfect_twin_line`).
    With two joined runs or more, ``ensemble``: the same number of walks drawn across the
    joined winners (walk ``j`` from joined run ``j mod m``, on seed ``j``: common random
    numbers with the winner's) and its ``ensemble_ratio``."""

    goals: tuple[int, ...]
    left_out: tuple[int, ...]
    transitions: int
    ratios: tuple[float, ...]
    perfect: Any
    ensemble: tuple[int, ...] = ()
    ensemble_ratio: float | None = None

    def to_json(self) -> dict[str, Any]:
        return {"goals": list(self.goals), "left_out": list(self.left_out),
                "transitions": self.transitions, "ratios": [_finite(r) for r in self.ratios],
                "perfect_twin": self.perfect.to_json(),
                "ensemble_runs": list(self.ensemble),
                "ensemble_ratio": None if self.ensemble_ratio is None
                else _finite(self.ensemble_ratio)}


def join_dof(runs: int, seeds: int) -> int:
    """The degrees of freedom of the pool's spread: ``seeds`` walks of each of ``runs``."""
    return runs * (seeds - 1)


def join_limit(sigma: float, runs: int, seeds: int) -> float:
    """How far above the best mean score of ``seeds`` walks a run joins (module docstring)."""
    return told_band(join_dof(runs, seeds)) * sigma / math.sqrt(seeds)


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


@dataclass(frozen=True)
class PoolResult:
    """The pool (module docstring). ``scores``/``distances``: ``(runs, seeds)``; ``best``:
    the index of the pool's winner; ``joined``: the runs within sampling of it."""

    runs: tuple[Run, ...]
    seeds: tuple[int, ...]
    transitions: int
    scores: np.ndarray
    distances: np.ndarray
    sigma: float
    best: int
    joined: tuple[int, ...]
    fields: tuple[PooledField, ...]
    space: ParameterSpace
    matched_floor: float
    objective: str
    notes: list[str] = field(default_factory=list)
    #: the winners' policies on the real model (:func:`pool_transfer`); None without a goal
    #: the real robot reached
    transfer: PoolTransfer | None = None
    #: per run, the real pairs its pool walks contradict beyond sampling
    #: (:mod:`~simlab.calibration.contradictions`)
    contradictions: tuple[Contradictions, ...] = ()
    #: the distance a twin equal to the robot would show at one pool walk
    #: (:func:`~simlab.calibration.metrics.perfect_twin_floor`)
    perfect_floor: float = math.nan

    @property
    def common_contradictions(self) -> list[tuple[int, int]]:
        """The pairs every run's winner contradicts: wrong whatever the fields."""
        return common_pairs(list(self.contradictions))

    @property
    def left_open(self) -> list[str]:
        """The fields whose union allows :data:`OPEN_SHARE` of their range or more."""
        return [f.name for f in self.fields if f.share is not None and f.share >= OPEN_SHARE]

    @property
    def dof(self) -> int:
        """The degrees of freedom of :attr:`sigma`: each run's walks less one, summed."""
        return join_dof(len(self.runs), len(self.seeds))

    @property
    def band(self) -> float:
        """:func:`~simlab.calibration.profile.told_band` for :attr:`dof`."""
        return told_band(self.dof)

    @property
    def limit(self) -> float:
        """How far above the best mean score a run joins."""
        return join_limit(self.sigma, len(self.runs), len(self.seeds))

    @property
    def gaps(self) -> np.ndarray:
        mean = self.scores.mean(axis=1)
        return mean - mean[self.best]


def read_run(path: str | os.PathLike[str]) -> Run:
    """A calibration's folder: its ``report.json`` (``kind`` checked) and the winner of
    its ``primitives.toml``; ConfigError naming the file otherwise."""
    from simlab.calibration.command import load_base

    folder = Path(path)
    rep_path = folder / "report.json"
    if not folder.is_dir():
        raise ConfigError("not a calibration folder", path=folder, key="runs",
                          fix="give the --out folders of earlier simlab calibrate runs")
    try:
        rep = json.loads(rep_path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError("no report.json here", path=folder, key="runs",
                          fix="give the --out folder of a finished simlab calibrate") from None
    except (ValueError, UnicodeDecodeError) as exc:
        raise ConfigError(f"not JSON: {exc}", path=rep_path, key="runs") from None
    if not isinstance(rep, dict) or rep.get("kind") != "simlab-calibrate":
        raise ConfigError("not a report of simlab calibrate", path=rep_path, key="runs",
                          fix="give the --out folders of simlab calibrate runs")
    for key in ("config", "space", "real", "budgets", "confirmed"):
        if key not in rep:
            raise ConfigError(f"the report has no {key!r}", path=rep_path, key=key,
                              fix="re-run simlab calibrate with this version")
    if not rep["confirmed"]:
        raise ConfigError("this calibration was not confirmed (--no-confirm)", path=rep_path,
                          key="confirmed", fix="pool confirmed calibrations only")
    params = load_base(folder / "primitives.toml", str(rep["config"]["simulator"]))
    prof, walks = report_profile(rep)
    return Run(folder, rep, params, prof, walks)


def report_profile(rep: dict[str, Any]) -> tuple[Profile | None, int | None]:
    """A calibrate ``report.json``'s profile (None without one), and the walks behind its
    spread when the report did not keep their degrees of freedom (written before they were):
    such a profile is re-read with Student's band for them (:meth:`Profile.restated`), the
    band the current calibrate uses."""
    if not rep.get("profile"):
        return None, None
    prof = Profile.from_json(rep["profile"])
    walks = _profile_walks(rep) if prof.dof is None else None
    if walks is None or walks < 2:
        return prof, None
    return prof.restated(ParameterSpace.from_json(rep["space"]), walks - 1), walks


def _profile_walks(rep: dict[str, Any]) -> int | None:
    """How many walks of the winner a report's profile read its spread from: its twin walks
    (the transfer report's twins), else the winner's confirming walks."""
    transfer = rep.get("transfer")
    if isinstance(transfer, dict) and isinstance(transfer.get("twins"), list) \
            and transfer["twins"]:
        return len(transfer["twins"])
    best = rep.get("best_candidate")
    count = sum(1 for c in rep["confirmed"] if isinstance(c, dict) and c.get("index") == best)
    return count or None


def check_runs(runs: list[Run]) -> ParameterSpace:
    """Runs that can be pooled: the same searched space, real table size and the options
    of :data:`SHARED`; ConfigError naming the run and the field otherwise."""
    if len(runs) < 2:
        raise ConfigError(f"{len(runs)} calibration given; a pool needs two or more",
                          key="runs", fix="give several --out folders of simlab calibrate "
                          "(different --seed, same lab)")
    first = runs[0].report
    seen: dict[Path, int] = {}
    for k, run in enumerate(runs):
        resolved = run.path.resolve()
        if resolved in seen:
            raise ConfigError(f"given twice (also run {seen[resolved]})", path=run.path,
                              key="runs", fix="give each calibration once")
        seen[resolved] = k
        rep = run.report
        where = run.path / "report.json"
        if rep["space"] != first["space"]:
            raise ConfigError("another searched space than the first run's", path=where,
                              key="space", fix="pool calibrations of the same space")
        for key in ("transitions", "states", "action_set"):
            if rep["real"].get(key) != first["real"].get(key):
                raise ConfigError(f"real {key} {rep['real'].get(key)!r}, the first run's "
                                  f"{first['real'].get(key)!r}", path=where, key=f"real.{key}",
                                  fix="pool calibrations against the same real table")
        for key in SHARED:
            if rep["config"].get(key) != first["config"].get(key):
                raise ConfigError(f"{key} {rep['config'].get(key)!r}, the first run's "
                                  f"{first['config'].get(key)!r}", path=where,
                                  key=f"config.{key}",
                                  fix="pool calibrations made with the same options")
    return ParameterSpace.from_json(first["space"])


def pool_seeds(runs: list[Run], n: int, first: int) -> tuple[int, ...]:
    """``n`` walk seeds from ``first``; refused when a run walked one of them."""
    seeds = tuple(range(first, first + n))
    for run in runs:
        clash = sorted(set(seeds) & set(run.seeds_walked()))
        if clash:
            raise ConfigError(f"seed {clash[0]} was walked by this calibration (seed "
                              f"{run.seed})", path=run.path, key="first_seed",
                              fix="choose a --first-seed away from the runs' seeds")
    return seeds


def pooled_fields(space: ParameterSpace, runs: list[Run], joined: list[int]
                  ) -> tuple[PooledField, ...]:
    """Per searched field, the union of the joined runs' allowed values (module docstring).
    A run without a profile contributes nothing; no joined profile: ``allowed`` None."""
    out = []
    for k, spec in enumerate(space.specs):
        values, spans = [], []
        for i in joined:
            run = runs[i]
            values.append(run.report["params"][spec.name])
            f: FieldProfile | None = None if run.profile is None else run.profile.fields[k]
            if f is None or f.allowed is None:
                spans.append(None)
            elif spec.categorical:
                spans.append(tuple(f.allowed))
            else:
                spans.append((float(f.allowed[0]), float(f.allowed[1]), *f.open))
        known = [s for s in spans if s is not None]
        if not known:
            allowed = None
        elif spec.categorical:
            assert spec.choices is not None
            allowed = tuple(c for c in spec.choices if any(c in s for s in known))
        else:
            allowed = _merge(known)
        out.append(PooledField(spec.name, bool(spec.categorical), tuple(values), tuple(spans),
                               allowed, range_share(spec, allowed)))
    return tuple(out)


def _merge(spans: list[tuple[float, float, bool, bool]]) -> tuple[Any, ...]:
    """Overlapping intervals merged, an open end kept where the interval holding it is
    open there."""
    merged: list[list[Any]] = []
    for lo, hi, lo_open, hi_open in sorted(spans):
        if merged and lo <= merged[-1][1] + 1e-12:
            last = merged[-1]
            if hi > last[1] + 1e-12:
                last[1], last[3] = hi, hi_open
            elif abs(hi - last[1]) <= 1e-12:
                last[3] = last[3] or hi_open
            last[2] = last[2] or (lo_open and abs(lo - last[0]) <= 1e-12)
        else:
            merged.append([lo, hi, lo_open, hi_open])
    return tuple(tuple(m) for m in merged)


def pool(runs: list[Run], real: Any, arena: Any, states: Any, *, seeds: int = 3,
         first_seed: int = FIRST_SEED, workers: int = 2, address: str | None = None,
         progress: bool = True) -> PoolResult:
    """Walk every run's winner on common fresh seeds and pool the runs (module docstring).

    Args:
        runs: the calibrations (:func:`read_run`), checked by :func:`check_runs`.
        real: the real table they were calibrated against (reset rows as they chose).
        arena, states: the lab's arena and states.
        seeds: walk seeds per winner (>= 2: the walk-to-walk spread is measured here).
    """
    from simlab.calibration.stages import prepare_calibration

    space = check_runs(runs)
    if int(seeds) < 2:
        raise ConfigError(f"expected 2 or more, got {seeds}", key="seeds",
                          fix="the spread of a walk is measured from these seeds")
    walk_seeds = pool_seeds(runs, int(seeds), int(first_seed))
    known = {f.name for f in fields(CalibrationConfig)}
    cfg = CalibrationConfig(**{k: v for k, v in runs[0].report["config"].items()
                               if k in known and k != "address"})
    cfg = replace(cfg, seed=int(first_seed), workers=int(workers), progress=progress)
    setup = prepare_calibration(real, arena, states, space, runs[0].params, cfg)
    recorded = int(runs[0].report["real"]["transitions"])
    if int(setup.real.counts.sum()) != recorded:  # both without the reset rows
        raise ConfigError(f"{int(setup.real.counts.sum())} transitions (reset rows left out), "
                          f"the runs were calibrated against {recorded}",
                          path=real.source or None, key="real",
                          fix="give the real table the runs were calibrated against")
    sizes = sorted({int(r.report["budgets"]["confirm_transitions"]) for r in runs})
    scores, dists, walks = _walk_winners(runs, setup, cfg, walk_seeds, sizes[-1], address)
    sigma = float(np.sqrt(np.mean(np.var(scores, axis=1, ddof=1))))
    mean = scores.mean(axis=1)
    best = int(np.argmin(mean))
    limit = join_limit(sigma, len(runs), len(walk_seeds))
    joined = [i for i in range(len(runs)) if mean[i] - mean[best] <= limit]
    joined.sort(key=lambda i: (mean[i], i))
    notes = []
    if len(sizes) > 1:
        notes.append(f"the runs confirmed at {', '.join(f'{s:,}' for s in sizes)} transitions; "
                     f"the pool walks {sizes[-1]:,}")
    old = [f"{r.path} ({r.restated} walks)" for r in runs if r.restated is not None]
    if old:
        notes.append("profiles written before their spread's degrees of freedom were kept, "
                     "re-read with Student's band for the walks behind it: " + ", ".join(old))
    missing = [str(runs[i].path) for i in joined if runs[i].profile is None]
    if missing:
        notes.append("no profile in " + ", ".join(missing) + " (calibrate --profile-step "
                     "0.25 measures one): its allowed values are not in the union")
    differ = [str(r.path) for r in runs[1:]
              if any(r.report["config"].get(k) != runs[0].report["config"].get(k)
                     for k in ("goal_states", "untried"))]
    if differ:
        notes.append(f"the transfer scores the goals and untried rule of {runs[0].path}; "
                     + ", ".join(differ) + " chose others")
    rng = np.random.default_rng(np.random.SeedSequence(int(first_seed), spawn_key=(11,)))
    matched = float(runs[best].report["matched_floor"]["median"])
    # at the pool's own walks, on its own stream (nothing drawn after it moves)
    perfect = perfect_twin_floor(setup.real.counts, np.random.default_rng(
        np.random.SeedSequence(int(first_seed), spawn_key=(19,))),
        np.sum(walks[best], axis=0).sum(axis=2) // len(walk_seeds), n_boot=cfg.n_boot).median
    return PoolResult(tuple(runs), walk_seeds, sizes[-1], scores, dists, sigma, best,
                      tuple(joined), pooled_fields(space, runs, joined), space, matched,
                      cfg.objective, notes,
                      pool_transfer(setup, walks, best, joined, cfg.untried, rng),
                      tuple(contradicted_pairs(
                          setup.real.counts, np.sum(w, axis=0),
                          # the same relabellings for every run: equal walks, equal listing
                          np.random.default_rng(np.random.SeedSequence(
                              int(first_seed), spawn_key=(17,))),
                          skip_states=list(setup.real.reset_states or ()),
                          regions=setup.regions) for w in walks),
                      perfect)


def _walk_winners(runs: list[Run], setup: Any, cfg: CalibrationConfig,
                  walk_seeds: tuple[int, ...], rows: int, address: str | None
                  ) -> tuple[np.ndarray, np.ndarray, list[list[np.ndarray]]]:
    """Every run's winner walked ``rows`` transitions on each seed, scored as the runs
    scored theirs: the ``(runs, seeds)`` scores and distances, and each walk's counts."""
    from tqdm.auto import tqdm

    from simlab.calibration.search import make_candidate, walk_context
    from simlab.calibration.walks import WalkJob, WalkRunner

    space = setup.space
    ctx = walk_context(setup.real, setup.arena, setup.disc, space, runs[0].params, cfg,
                       walk_seeds[0], (None, rows), setup.reference())
    jobs = [WalkJob(index=i, arena=setup.arena, states=setup.disc, params=run.params,
                    hours=None, transitions=rows, seed=s, simulator=cfg.simulator,
                    pose_source=cfg.pose_source, action_set=setup.real.action_set,
                    start_states=cfg.start_states, n_states=int(setup.disc.n_states))
            for i, run in enumerate(runs) for s in walk_seeds]
    workers = max(1, int(cfg.workers))
    runner = WalkRunner(workers, address)
    scores = np.zeros((len(runs), len(walk_seeds)))
    dists = np.zeros_like(scores)
    walks: list[list[Any]] = [[None] * len(walk_seeds) for _ in runs]
    bar = tqdm(total=len(jobs), desc=f"calibrate-pool: {len(runs)} winners on "
               f"{len(walk_seeds)} fresh seeds ({rows:,} transitions a walk)", unit="walk",
               disable=not cfg.progress)
    try:
        for k in range(0, len(jobs), workers):
            chunk = jobs[k:k + workers]
            for job, sim in zip(chunk, runner.map(chunk), strict=True):
                c = make_candidate(job.index, "pool", np.zeros(len(space.names)), sim,
                                   job.seed, ctx)
                j = walk_seeds.index(job.seed)
                scores[job.index, j], dists[job.index, j] = c.score, c.distance
                walks[job.index][j] = sim.counts
            bar.update(len(chunk))
    finally:
        bar.close()
        runner.close()
    return scores, dists, walks


def pool_transfer(setup: Any, walks: list[list[np.ndarray]], best: int, joined: list[int],
                  untried: str, rng: np.random.Generator) -> PoolTransfer | None:
    """The winners' policies on the real model (:class:`PoolTransfer`), on the goals of the
    runs' transfer reports that the real robot reached; None when it reached none."""
    from simlab.calibration.policies import LINE_BOOT, reached_goals, real_transfer_counts
    from simlab.calibration.transfer import TransferModel, transfer_report
    from simlab.calibration.transfer.score import perfect_twin_line

    flat = [w for run in walks for w in run]
    real_counts = real_transfer_counts(setup.real, flat)
    kept, left_out = reached_goals(real_counts, list(setup.goals))
    if not kept:
        return None
    aset, centres = setup.real.action_set, setup.disc.centres

    def model(counts: np.ndarray, name: str) -> Any:
        return TransferModel.from_counts(counts, name=name, action_set=aset, centres=centres)

    pooled = [np.sum(run, axis=0) for run in walks]
    twins = [model(counts, f"run {i}") for i, counts in enumerate(pooled)]
    members: tuple[int, ...] = ()
    if len(joined) >= 2:
        members = tuple(joined[j % len(joined)] for j in range(len(walks[best])))
        twins.append(model(np.sum([walks[i][j] for j, i in enumerate(members)], axis=0),
                           "ensemble"))
    real_model = model(real_counts, setup.real.source or "real")
    rep = transfer_report(real_model, twins, {f"s{g}": [g] for g in kept}, untried=untried)
    ratios = [float(r) for r in rep.overall_ratios()]
    line = perfect_twin_line(real_model, rep, pooled[best].sum(axis=2), n_boot=LINE_BOOT,
                             rng=rng)
    return PoolTransfer(tuple(kept), tuple(left_out), int(pooled[best].sum()),
                        tuple(ratios[:len(walks)]), line, members,
                        ratios[-1] if members else None)


# -- outputs ----------------------------------------------------------------------------


def _value(v: Any) -> str:
    return v if isinstance(v, str) else f"{float(v):.4g}"


def _span(s: Any, categorical: bool) -> str:
    if s is None:
        return "n/a"
    if categorical:
        return ", ".join(s)
    lo, hi, lo_open, hi_open = s
    return f"{'(open) ' * lo_open}{_value(lo)} - {_value(hi)}{' (open)' * hi_open}"


def pool_json(res: PoolResult) -> dict[str, Any]:
    mean_s, mean_d = res.scores.mean(axis=1), res.distances.mean(axis=1)
    return {"kind": KIND, "seeds": list(res.seeds), "transitions": res.transitions,
            "objective": res.objective, "sigma": res.sigma, "limit": res.limit,
            "dof": res.dof, "band": res.band, "matched_floor": res.matched_floor,
            "perfect_twin_floor": res.perfect_floor if math.isfinite(res.perfect_floor)
            else None,
            "best": res.best, "joined": list(res.joined),
            "runs": [{"path": str(r.path), "seed": r.seed,
                      "own_distance": r.report["distance"]["distance"],
                      "scores": res.scores[i].tolist(), "distances": res.distances[i].tolist(),
                      "score": float(mean_s[i]), "distance": float(mean_d[i]),
                      "gap": float(res.gaps[i]), "joined": i in res.joined,
                      "profile": r.profile is not None,
                      "params": {n: r.report["params"][n] for n in res.space.names}}
                     for i, r in enumerate(res.runs)],
            "fields": [f.to_json() for f in res.fields],
            "transfer": None if res.transfer is None else res.transfer.to_json(),
            "contradictions": {"runs": [c.to_json() for c in res.contradictions],
                               "common": [list(p) for p in res.common_contradictions]},
            "notes": res.notes}


def pool_markdown(res: PoolResult) -> str:
    mean_s, mean_d = res.scores.mean(axis=1), res.distances.mean(axis=1)
    mf = res.matched_floor
    lines = [f"# Pool of {len(res.runs)} calibrations against "
             f"{res.runs[0].report['real'].get('source') or 'a real table'}", "",
             f"Every run's winner walked the same {len(res.seeds)} fresh seeds "
             f"({', '.join(map(str, res.seeds))}) at {res.transitions:,} transitions, scored "
             f"by the `{res.objective}` objective. Walk-to-walk spread of the score "
             f"{res.sigma:.4f}; a run joins within {res.limit:.4f} of the best mean score "
             f"({res.band:.2f} sigma / sqrt({len(res.seeds)}), Student's t for the spread's "
             f"{res.dof} degrees of freedom). Matched floor {mf:.4f}; a twin equal to the "
             f"robot would lie {res.perfect_floor:.4f} from the real table at one of these "
             "walks (the perfect-twin floor: the matched floor without the plug-in's low "
             "bias).", "",
             "| # | run | calibrate seed | own distance | pool distance (x matched floor; x a "
             "twin equal to the robot) | score | above the best | joined |",
             "|---|---|---|---|---|---|---|---|"]
    for i, r in enumerate(res.runs):
        own = float(r.report["distance"]["distance"])
        mark = " (the pool's winner)" if i == res.best else ""
        lines.append(f"| {i} | {r.path} | {r.seed} | {own:.4f} | {mean_d[i]:.4f} "
                     f"({mean_d[i] / mf:.2f}x; {mean_d[i] / res.perfect_floor:.2f}x) | "
                     f"{mean_s[i]:.4f} | {res.gaps[i]:+.4f} | "
                     f"{'yes' if i in res.joined else 'no'}{mark} |")
    lines += ["", "## What the data allow, field by field", "",
              "Each joined run's winner and the values its profile allows (#: the run's row "
              "above, the best first); the union is the "
              "values within the band of a winner that is itself within sampling of the best "
              "(several basins, each allowing what it measured); *share*: the union's share of "
              "the searched range (log fields in log units)." + (ONE_BASIN if len(res.joined) == 1
                                                                else ""), "",
              "| field | winners | allowed per run | union | share |", "|---|---|---|---|---|"]
    for f in res.fields:
        union = "n/a" if f.allowed is None else (", ".join(f.allowed) if f.categorical else
                                                 "; ".join(_span(s, False) for s in f.allowed))
        runs = [f"#{i}" for i in res.joined]
        lines.append(f"| {f.name} | "
                     + ", ".join(f"{k} {_value(v)}" for k, v in zip(runs, f.values, strict=True))
                     + " | " + "; ".join(f"{k} {_span(s, f.categorical)}"
                                         for k, s in zip(runs, f.spans, strict=True))
                     + f" | {union} | {'n/a' if f.share is None else f'{f.share:.2f}'} |")
    if res.left_open:
        lines += ["", f"Left open across these basins (the union allows {OPEN_SHARE:.0%} of the "
                  "searched range or more): " + ", ".join(res.left_open) + ". The data do not tell "
                  "these fields; a twin's value for them is one of many the robot's table "
                  "allows."]
    lines += _transfer_markdown(res)
    lines += _contradictions_markdown(res)
    if res.notes:
        lines += [""] + [f"- {n}" for n in res.notes]
    return "\n".join(lines) + "\n"


def _ratio(x: float) -> str:
    return f"{x:.3f}" if math.isfinite(x) else "never arrives"


def _transfer_markdown(res: PoolResult) -> list[str]:
    t = res.transfer
    if t is None:
        return ["", "## Policies on the real model", "",
                "None: the real robot reached none of the transfer's goals."]
    line = t.perfect.to_json()
    lo, hi = line["ratio_low_2.5"], line["ratio_high_97.5"]
    spread = "" if lo is None or hi is None else f" (95 % of resamples {lo:.3f}-{hi:.3f})"
    out = ["", "## Policies on the real model", "",
           f"Each winner's {len(res.seeds)} pool walks ({t.transitions:,} transitions) estimated "
           f"into one twin; its shortest-path policy for each of {len(t.goals)} goals scored on "
           "the real model: expected steps summed over the goals, over the real optimum's. A "
           f"perfect twin with the same data scores {_ratio(t.perfect.median)}{spread}.", "",
           "| # | run | steps over the real optimum |", "|---|---|---|"]
    out += [f"| {i} | {r.path} | {_ratio(x)} |" for i, (r, x) in
            enumerate(zip(res.runs, t.ratios, strict=True))]
    if t.ensemble_ratio is not None:
        drawn = ", ".join(f"#{i}" for i in t.ensemble)
        w, e = t.ratios[res.best], t.ensemble_ratio
        verdict = ("as the pool's winner's" if not (math.isfinite(w) or math.isfinite(e))
                   else f"{'lower than' if e < w else 'equal to' if e == w else 'higher than'}"
                   f" the pool's winner's {_ratio(w)}")
        out += ["", f"The ensemble across basins (the same number of walks, walk j from "
                f"{drawn} in turn, on the same seeds): {_ratio(e)}, {verdict}."]
    if t.left_out:
        out += ["", f"Goals left out (the real robot never reached them): {list(t.left_out)}."]
    return out


def _contradictions_markdown(res: PoolResult) -> list[str]:
    """The pairs every winner contradicts, from the pool's own walks."""
    if not res.contradictions:
        return []
    from simlab.calibration.contradictions import direction

    cs = res.contradictions
    out = ["", "## Where every winner contradicts the robot", "",
           f"Each winner's pool walks against the real table, pair by pair (a permutation "
           f"test per (s, a), Benjamini-Hochberg at {100 * cs[0].alpha:.0f} % across pairs; "
           "calibrate's report.md says how): listed pairs per run "
           + ", ".join(f"#{i} {len(c.pairs)} of {c.tested}" for i, c in enumerate(cs))
           + f"; {len({(r['state'], r['action']) for c in cs for r in c.pairs})} pairs listed "
           "by some run."]
    common = res.common_contradictions
    if not common:
        return [*out, "", "No pair is listed by every run: what one winner gets wrong, "
                "another gets right."]
    out += ["", f"**{len(common)} pairs are listed by every run**: the winners sit at "
            "different points of the searched space and still differ from the robot there, "
            "so what is wrong there is no searched field; check the map and the arena at "
            "these pairs first.", "",
            "| state | action | real transitions | stays, real | stays, each winner | "
            "most likely next, real | each winner |", "|---|---|---|---|---|---|---|"]
    for s, a in common:
        rows = [next(r for r in c.pairs if (r["state"], r["action"]) == (s, a)) for c in cs]
        r0 = rows[0]
        out.append(f"| {s} | {a} | {r0['real']} | {r0['stay_real']:.2f} | "
                   + ", ".join(f"{r['stay_twin']:.2f}" for r in rows)
                   + f" ({direction(r0)}) | {r0['next_real']} ({r0['share_real']:.2f}) | "
                   + ", ".join(str(r["next_twin"]) for r in rows) + " |")
    return out


def pool_primitives_toml(res: PoolResult) -> str:
    """The pool's winner as ``[primitives]``; with two joined runs or more, each joined
    winner as an ``[[ensemble]]`` member, the pool's winner first."""
    from simlab.calibration.report import ensemble_tables, record_lines, toml_value

    best = res.runs[res.best]
    d = float(res.distances[res.best].mean())
    lines = [f"# Pooled by `simlab calibrate-pool` from {len(res.runs)} calibrations; the "
             f"winner is {best.path}", "[primitives]", *record_lines(best.params)]
    lines += ["", "[calibration]", f"distance = {toml_value(d)}",
              f"matched_floor_median = {toml_value(res.matched_floor)}",
              f"perfect_twin_floor_median = {toml_value(res.perfect_floor)}",
              f"searched = [{', '.join(toml_value(n) for n in res.space.names)}]",
              f"simulator = {toml_value(best.report['config']['simulator'])}"]
    if len(res.joined) >= 2:
        lines += ["", "# The twin ensemble across basins (`collect` / `online --arena` with "
                  "--ensemble): the joined", "# runs' winners, the pool's winner first, each "
                  "with its own fitted decision latency"]
        lines += ensemble_tables([(f"member {k}: {res.runs[i].path}, pool distance "
                                   f"{float(res.distances[i].mean()):.6f}", res.runs[i].params)
                                  for k, i in enumerate(res.joined)])
    return "\n".join(lines) + "\n"


def _is_ours(path: Path) -> bool:
    try:
        if path.name == "pool.json":
            return json.loads(path.read_text(encoding="utf-8")).get("kind") == KIND
        with path.open(encoding="utf-8") as fh:
            first = fh.readline()
        return first.startswith("# Pool of " if path.name == "pool.md" else
                                "# Pooled by `simlab calibrate-pool`")
    except (OSError, ValueError, UnicodeDecodeError, AttributeError):
        return False


def check_pool_outputs(out: str | os.PathLike[str], *, overwrite: bool) -> dict[str, Path]:
    """Refuse before any walk: an ``out`` that is a file, an existing output without
    ``overwrite``, and with it any output the pool did not write."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError("the output directory is a file", path=out, key="out",
                          fix="choose another --out")
    paths = {name: out / name for name in FILES}
    for path in paths.values():
        ensure_new(path, overwrite=overwrite, what="pool output")
        if overwrite and path.exists() and not _is_ours(path):
            raise ConfigError("not written by simlab calibrate-pool; --overwrite replaces "
                              "only its own outputs", path=path, key="overwrite",
                              fix="choose another --out, or move the file away")
    return paths


def write_pool(res: PoolResult, out: str | os.PathLike[str], *, overwrite: bool = False
               ) -> dict[str, Path]:
    paths = check_pool_outputs(out, overwrite=overwrite)
    with output_transaction(out, paths.values(), overwrite=overwrite,
                            what="pool output") as txn:
        atomic_write_text(txn.path(paths["primitives.toml"]), pool_primitives_toml(res))
        atomic_write_json(txn.path(paths["pool.json"]), pool_json(res))
        atomic_write_text(txn.path(paths["pool.md"]), pool_markdown(res))
    return paths


# -- the command ------------------------------------------------------------------------


@dataclass(frozen=True)
class PoolFiles:
    result: PoolResult
    files: dict[str, Path]


@dataclass(frozen=True, kw_only=True)
class PoolConfig(ActionSetOptions):
    """Options of ``simlab calibrate-pool`` / :func:`pool_command`: the calibrations, the
    lab they calibrated (the files given to calibrate) and the pool's walks."""

    COMMAND = "calibrate-pool"
    ARGUMENTS = ("runs", "real", "states", "arena", "out")

    runs: tuple[Path, ...] = option(help="--out folders of simlab calibrate runs of one lab "
                                    "(different --seed)")
    real: Any = option(help="the real counts the runs were calibrated against")
    states: Any = option(help="the states file the runs used")
    arena: Any = option("table", "the arena the runs used (name or TOML)")
    out: Path = option(help="output directory: primitives.toml, pool.json, pool.md")
    seeds: int = option(3, "fresh walk seeds per winner (>= 2)")
    first_seed: int = option(FIRST_SEED, "first of those seeds")
    workers: int = option(2, "walks simulated in parallel processes")
    address: str | None = option(None, "Ray cluster address (default: local processes)")
    overwrite: bool = option(False, "replace the outputs of an earlier calibrate-pool")
    progress: bool = option(True, "progress bar (--no-progress hides it)")

    def validate(self) -> None:
        from simlab.physics.arena import check_arena_option

        check_arena_option(self.arena)
        if int(self.seeds) < 2:
            raise ConfigError(f"expected 2 or more, got {self.seeds}", key="seeds",
                              fix="the spread of a walk is measured from these seeds")
        if int(self.workers) < 1:
            raise ConfigError(f"expected 1 or more, got {self.workers}", key="workers")

    #: what the options say the real actions mean (None: none given), as calibrate reads them
    real_action_set = CalibrateConfig.real_action_set


@command(PoolConfig)
def pool_command(cfg: PoolConfig) -> PoolFiles:
    """``simlab calibrate-pool``: read the runs, check them and the outputs (before any
    walk), pool them (:func:`pool`) and write the outputs."""
    from simlab.calibration.command import read_real_table
    from simlab.physics.inputs import load_arena_config, load_discretizer

    check_pool_outputs(cfg.out, overwrite=cfg.overwrite)
    runs = [read_run(p) for p in cfg.runs]
    check_runs(runs)
    disc = load_discretizer(cfg.states)
    # the runs record the action set they read the table in; options that say another are
    # refused rather than read the table otherwise
    aset = ActionSet.from_json(runs[0].report["real"]["action_set"],
                               where=f"{runs[0].path / 'report.json'}: real.action_set")
    given = cfg.real_action_set()
    if given is not None and given != aset:
        raise ConfigError(f"the runs read the real table as {aset.describe()}, the options "
                          f"say {given.describe()}", key="action_set",
                          fix="drop --n-actions/--convention/--speed: the runs' record is used")
    real = read_real_table(cfg.real, int(disc.n_states), aset,
                       runs[0].report["real"].get("hours"))
    res = pool(runs, real, load_arena_config(cfg.arena), disc, seeds=cfg.seeds,
               first_seed=cfg.first_seed, workers=cfg.workers, address=cfg.address,
               progress=cfg.progress)
    return PoolFiles(res, write_pool(res, cfg.out, overwrite=cfg.overwrite))
