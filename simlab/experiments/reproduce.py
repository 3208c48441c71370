"""``simlab reproduce``: run the thesis experiments and write ``results.md``.

The driver (see the contract in :mod:`simlab.experiments`):

1. reads the experiment TOMLs (validated, runners resolved) and selects ``only``;
2. checks every output folder ``DIR/<name>/`` before anything runs (existing ones need
   ``overwrite``);
3. runs the experiments one after the other, each with a :class:`RunContext` whose
   ``map`` spreads its independent runs over the backend (one executor for the whole
   reproduction, so the process pool or Ray runtime starts once);
4. catches any error of an experiment (shown as ERROR, traceback in
   ``DIR/<name>/error.txt``) and goes on with the next;
5. after every experiment, rewrites ``DIR/results.json`` and ``DIR/results.md`` (entries
   of experiments run earlier into the same ``DIR`` and not selected now are kept, with
   their own budget and date), so an interrupted reproduction still leaves a table.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import shutil
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from simlab.base import validation
from simlab.base.errors import ConfigError, DataError
from simlab.base.io import atomic_write_json, atomic_write_text
from simlab.base.options import CommandConfig, command, option
from simlab.experiments.spec import BUDGETS, FAIL, ExperimentSpec, discover_experiments, select

RESULTS_MD = "results.md"
RESULTS_JSON = "results.json"
CACHE_DIR = "_cache"


@dataclass(frozen=True)
class ReproduceResult:
    """What :func:`reproduce` did.

    Attributes:
        out: the output folder.
        budget, backend: the settings of this run.
        entries: one JSON-ready dict per experiment run now (as in ``results.json``).
        results_md, results_json: the two tables (they also list earlier runs).
        wall_seconds: wall time of the whole reproduction (s).
    """

    out: Path
    budget: str
    backend: str
    entries: tuple[dict[str, Any], ...]
    results_md: Path
    results_json: Path
    wall_seconds: float

    @property
    def errors(self) -> list[str]:
        """Names of the experiments that failed to run."""
        return [e["name"] for e in self.entries if e["status"] != "ok"]

    @property
    def failed_checks(self) -> list[tuple[str, str]]:
        """``(experiment, check)`` of every FAIL."""
        return [(e["name"], c["check"]) for e in self.entries for c in e.get("checks", [])
                if c["status"] == FAIL]

    def entry(self, name: str) -> dict[str, Any]:
        """The entry of experiment ``name``."""
        for e in self.entries:
            if e["name"] == name:
                return e
        raise KeyError(name)


def _now() -> str:
    return _dt.datetime.now().astimezone().isoformat(timespec="seconds")


def _check_outputs(out: Path, specs: Sequence[ExperimentSpec], overwrite: bool) -> None:
    if out.exists() and not out.is_dir():
        raise ConfigError("output exists and is not a directory", path=out,
                          fix="choose another --out")
    for s in specs:
        d = out / s.name
        if d.exists() and (not d.is_dir() or any(d.iterdir())) and not overwrite:
            raise ConfigError(f"results of experiment {s.name!r} already exist", path=d,
                              fix="pass --overwrite to replace them, or choose another --out")
    for name in (RESULTS_MD, RESULTS_JSON):
        p = out / name
        if p.exists() and not p.is_file():
            raise ConfigError("expected a file", path=p)


def _read_previous(path: Path) -> dict[str, dict[str, Any]]:
    if not path.exists():
        return {}
    try:
        data = json.loads(path.read_text())
        return {str(e["name"]): e for e in data["experiments"]}
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise DataError(f"cannot read the earlier results table: {exc}", ) from None


def _fresh_dir(d: Path) -> None:
    if d.is_dir():
        shutil.rmtree(d)
    elif d.exists():
        d.unlink()
    d.mkdir(parents=True)


def _relative_figures(figures: Sequence[Path], out: Path, exp_dir: Path) -> list[str]:
    rel = []
    for f in figures:
        p = f if f.is_absolute() else exp_dir / f
        if not p.exists():
            raise DataError(f"the runner listed a figure that does not exist: {p}")
        try:
            rel.append(p.resolve().relative_to(out.resolve()).as_posix())
        except ValueError:
            rel.append(str(p))
    return rel


def _run_one(spec: ExperimentSpec, budget: str, out: Path, executor: Any, seed: int,
             progress: bool, log: Callable[[str], None] | None) -> dict[str, Any]:
    from simlab.experiments.context import RunContext, RunResult, experiment_seed
    from simlab.experiments.registry import get_runner

    exp_dir = out / spec.name
    _fresh_dir(exp_dir)
    table = spec.budget(budget)
    entry: dict[str, Any] = {
        "name": spec.name, "title": spec.title, "reference": spec.reference,
        "claim": spec.claim, "runner": spec.runner, "file": str(spec.path),
        "budget": budget, "budget_table": table, "params": dict(spec.params),
        "backend": executor.describe(), "seed": seed, "written": _now(),
    }
    ctx = RunContext(name=spec.name, out=exp_dir.resolve(),
                     seed=experiment_seed(seed, spec.name), root_seed=seed, budget_name=budget,
                     cache=(out / CACHE_DIR).resolve(),
                     progress=progress, backend_name=executor.name, executor=executor,
                     logger=log)
    t0 = time.perf_counter()
    try:
        fn = get_runner(spec.runner)
        result = fn(dict(spec.params), table, ctx)
        if not isinstance(result, RunResult):
            raise TypeError(f"runner {spec.runner} returned {type(result).__name__}, "
                            "not a RunResult")
        figures = _relative_figures(result.figures, out, exp_dir)
        checks = []
        for c in spec.checks:
            o = c.evaluate(result.metrics, budget)
            checks.append({"metric": c.metric, "check": c.describe(), "thesis": c.thesis,
                           "op": c.op, "status": o.status, "ours": o.ours,
                           "detail": o.detail})
        entry.update(status="ok", metrics=dict(result.metrics), checks=checks, figures=figures,
                     notes=list(result.notes))
        details = dict(result.details)
    except Exception as exc:  # one experiment's failure must not stop the others
        message = str(exc) or type(exc).__name__
        if isinstance(exc, ConfigError) and exc.path is None:
            message = f"{spec.path}: {message}"
        entry.update(status="error", error=f"{type(exc).__name__}: {message}", metrics={},
                     checks=[], figures=[], notes=[])
        atomic_write_text(exp_dir / "error.txt", traceback.format_exc())
        details = {}
    entry["wall_seconds"] = time.perf_counter() - t0
    atomic_write_json(exp_dir / "result.json", {**entry, "details": details})
    return entry


@dataclass(frozen=True, kw_only=True)
class ReproduceConfig(CommandConfig):
    """Options of ``simlab reproduce`` / :func:`reproduce`.

    ``out`` may be None here because ``simlab reproduce --list`` needs no output folder;
    :func:`reproduce` refuses it. ``strict`` only sets the command's exit code (the
    function returns the same result either way).
    """

    COMMAND = "reproduce"
    ARGUMENTS = ("out",)

    out: Path | None = option(None, "output folder (figures, results.md); required unless "
                              "--list")
    only: Any | None = option(None, "run only these experiments (a list from Python or TOML)",
                              metavar="NAME[,NAME]", parse=str)
    budget: str = option("quick", "quick: tiny runs (seconds); full: the thesis's trial "
                         "counts, 10 seeds", choices=BUDGETS)
    backend: str = option("local", "where independent runs go: local process pool or Ray "
                          "tasks", choices=("local", "ray"))
    address: str | None = option(None, "Ray cluster address (default: start Ray locally)")
    workers: int | None = option(None, "local processes (default: all cores)")
    experiments: Any | None = option(
        None, "a folder of experiment TOMLs or one file (a list of files from Python or "
        "TOML; default: experiments/)", metavar="PATH", parse=str)
    seed: int = option(0, "root seed")
    overwrite: bool = option(False, "replace the results of experiments already in --out")
    strict: bool = option(False, "exit 1 when a check FAILs too")
    progress: bool = option(True, "progress bars (--no-progress hides them)")

    def validate(self) -> None:
        validation.whole(self.seed, "seed", minimum=0)
        if self.workers is not None:
            validation.whole(self.workers, "workers", minimum=1)
        for key in ("only", "experiments"):  # lists from TOML/Python: a hashable tuple
            value = getattr(self, key)
            if isinstance(value, list):
                object.__setattr__(self, key, tuple(value))
            elif not (value is None or isinstance(value, str | os.PathLike | tuple)):
                raise ConfigError(f"expected a text, a path or a list, got {value!r}", key=key)


@command(ReproduceConfig, extras=("log",))
def reproduce(cfg: ReproduceConfig, log: Callable[[str], None] | None = print
              ) -> ReproduceResult:
    """Run the thesis experiments and write ``out/results.md`` (see the module docstring).

    Takes a :class:`ReproduceConfig` or its fields (``reproduce(out, budget="full")``):

    * ``out``: output folder (created).
    * ``only``: experiment names (``"fig4_8_entropy,fig4_9_training"`` or a list); None: all.
    * ``budget``: ``"quick"`` (tiny, seconds) or ``"full"`` (the thesis's trial counts).
    * ``backend``: ``"local"`` (process pool) or ``"ray"``; ``address``: Ray cluster
      address (``ray`` only; default: reuse or start a local Ray).
    * ``workers``: processes of the local pool (default: the machine's cores).
    * ``experiments``: a folder of ``*.toml`` or a list of files (default: the
      repository's ``experiments/``).
    * ``seed``: root seed; experiment ``name`` uses
      ``SeedSequence(seed, spawn_key=(crc32(name),))``.
    * ``overwrite``: replace the results of experiments that already have an output folder.
    * ``progress``: progress bars.
    * ``log`` (not an option): receives one line per experiment (None: silent).

    Returns:
        :class:`ReproduceResult`. Raises :class:`ConfigError` for bad options or experiment
        files, before anything runs; errors inside an experiment are recorded instead.
    """
    if cfg.out is None:
        raise ConfigError("missing", key="--out", fix="e.g. --out runs/reproduce")
    budget, seed, experiments = cfg.budget, cfg.seed, cfg.experiments
    specs = select(discover_experiments(experiments), cfg.only)
    if not specs:
        raise ConfigError("no experiment files found", path=experiments, key="experiments")
    from simlab.experiments.registry import get_runner

    for spec in specs:  # only the selected ones: a broken group must not block the others
        try:
            get_runner(spec.runner)
        except ConfigError as exc:
            raise ConfigError(exc.problem, path=spec.path, key="runner", fix=exc.fix) from None
    out = cfg.out
    _check_outputs(out, specs, cfg.overwrite)
    previous = _read_previous(out / RESULTS_JSON)

    from simlab import __version__
    from simlab.base.parallel import make_executor

    executor = make_executor(cfg.backend, workers=cfg.workers, address=cfg.address)
    say = log or (lambda _line: None)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    done: list[dict[str, Any]] = []
    header: dict[str, Any] = {"simlab_version": __version__, "seed": seed,
                              "backend": executor.describe(), "budget": budget}
    try:
        say(f"simlab reproduce: {len(specs)} experiment(s), budget {budget}, "
            f"{executor.describe()} -> {out}")
        for i, spec in enumerate(specs, start=1):
            say(f"[{i}/{len(specs)}] {spec.name}: {spec.reference} — {spec.title} ...")
            entry = _run_one(spec, budget, out, executor, seed, cfg.progress, log)
            done.append(entry)
            say(f"[{i}/{len(specs)}] {spec.name}: {_headline(entry)}")
            header["wall_seconds"] = time.perf_counter() - t_start
            _write_tables(out, header, previous, done)
    finally:
        executor.close()
    wall = time.perf_counter() - t_start
    header["wall_seconds"] = wall
    _write_tables(out, header, previous, done)
    return ReproduceResult(out=out, budget=budget, backend=executor.describe(),
                           entries=tuple(done), results_md=out / RESULTS_MD,
                           results_json=out / RESULTS_JSON, wall_seconds=wall)


def _write_tables(out: Path, header: dict[str, Any], previous: dict[str, dict[str, Any]],
                  done: list[dict[str, Any]]) -> None:
    from simlab.experiments.report import render_results
    from simlab.experiments.spec import natural_key

    merged = dict(previous)
    for e in done:
        merged[e["name"]] = e
    entries = sorted(merged.values(), key=lambda e: natural_key(e["name"]))
    header = {**header, "written": _now()}
    atomic_write_json(out / RESULTS_JSON, {**header, "experiments": entries})
    atomic_write_text(out / RESULTS_MD, render_results(header, entries))


def _headline(entry: dict[str, Any]) -> str:
    wall = f"{entry['wall_seconds']:.1f} s"
    if entry["status"] != "ok":
        return f"ERROR {entry['error']} ({wall})"
    counts: dict[str, int] = {}
    for c in entry["checks"]:
        counts[c["status"]] = counts.get(c["status"], 0) + 1
    parts = [f"{v} {k}" for k, v in sorted(counts.items())] or ["no checks"]
    return f"{', '.join(parts)} ({wall})"
