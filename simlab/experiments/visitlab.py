"""The Visit-the-lab results of ``simlab reproduce``: thesis Figs. 4.1-4.7, the combined
task, and the IMOL 2023 poster's Figs. 4 and 5.

Runners (the ``visitlab`` group of :mod:`simlab.experiments.registry`)
--------------------------------------------------------------------
* ``visitlab.curves`` — learning curves of several training runs (Figs. 4.1, 4.2, 4.4,
  4.5, 4.6, poster Fig. 4), with per-run metrics (below);
* ``visitlab.nav_heatmaps`` — Fig. 4.3, navigation value maps for the 9 goal rooms;
* ``visitlab.combined`` — the combined architecture (goals per trial, an episode GIF);
* ``visitlab.adaptability`` — Fig. 4.7, continued learning with three humans;
* ``visitlab.passive_qmaps`` — poster Fig. 5, what a passive Q-learner learns from
  watching model-based agents that explore differently.

Training runs (``[[params.runs]]`` and the module tables)
--------------------------------------------------------
A run is one agent trained on one task for ``seeds`` seeds (``budget.seeds``) of
``trials`` trials, given as a table::

    [[params.runs]]
    label = "mb"               # names its metrics (mb_plateau, ...) and its legend
    agent = "mb-egreedy"       # a registry agent (simlab.agents.registry)
    task = "nav"               # nav | social | gotohuman (default: params.task)
    variant = "thesis"         # thesis | paper (default: params.variant or thesis)
    env = {human = "easy"}     # env settings (simlab.visitlab.envs; a human may be a
                               # preset name or a table of Human fields)
    overrides = {}             # agent settings (loop_agent_config; "actor.x" nested)
    observer = false           # a passive Q-learner watches the agent ...
    takeover = 0.5             # ... and acts from this fraction of the trials on
    legend = "MB eps-greedy"   # optional legend text

``budget.trials`` is a number, or a table by run label or task
(``trials = {nav = 2000, social = 40000}``).

**Runs are shared.** A run is built once per output folder into
``DIR/_cache/visitlab/run-<key>/`` (``runs.npz``: returns ``(seeds, trials)`` and
final Q tables; ``model_<i>.npz`` when a model is kept; ``_stage.json`` written last),
where ``key`` hashes everything that defines it (task, agent, variant, env, overrides,
observer, trials, seeds), the root seed, the simlab version and a fingerprint of the
source the run depends on (:func:`code_fingerprint`: changed code is never reused). So
Figs. 4.1 and 4.2 share their model-based navigation runs, poster Fig. 4 reuses
Fig. 4.5's social run, Fig. 4.4's random-episode go-to-human run is the combined
architecture's module, and the combined task and Fig. 4.7 share the three trained
modules — as long as their tables agree (the TOMLs say which must stay equal).

Seeds: every run uses the integer seed :func:`visitlab_seed` and its seed ``i`` is
``seed_generators(visitlab_seed(root), seeds)[i]`` — exactly seed ``i`` of
``simlab visitlab train --seed <visitlab_seed(root)> --seeds <seeds>``; all the agents of
a figure start from the same environment streams (common random numbers). The combined
task's evaluation and continued runs use a second stream (spawn key ``(VISL, 1)``).

Curve metrics (for every run ``L``)
-----------------------------------
``L_plateau`` (mean reward per trial over the last 10 % of trials, all seeds),
``L_std`` (the thesis's band: standard deviation of the reward within windows of
``trials / 100`` trials, pooled over seeds, averaged over the last 10 windows),
``L_seed_std`` (standard deviation across seeds of the per-seed plateau),
``L_trials_to_90pct`` (first trial at which the smoothed seed-mean curve reaches 90 % of
the plateau), ``L_trials_to_<x>`` for every ``params.thresholds`` value ``x`` (first trial
at which the smoothed curve reaches ``x``; no value if never), and
``L_<name>`` for every ``params.windows`` entry ``name = [lo, hi]`` (mean reward over the
trials ``[lo * trials, hi * trials)``).

Every runner appends ``params.notes`` (a list of sentences, e.g. why our simulation
differs from the thesis where a check fails) to the notes of ``results.md``.
"""

from __future__ import annotations

import functools
import json
import math
import shutil
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from simlab.errors import ConfigError
from simlab.experiments.context import RunContext, RunResult
from simlab.experiments.registry import runner
from simlab.io import atomic_write, atomic_write_json
from simlab.orchestration.stages import file_lock, source_fingerprint, stage_key

#: First element of the spawn key of every Visit-the-lab stream ("VISL" in ASCII).
VISITLAB_SPAWN_KEY = 0x5649534C
_MARKER = "_stage.json"
_TASKS = ("nav", "social", "gotohuman")
_RUN_KEYS = {"label", "agent", "task", "variant", "env", "overrides", "observer", "takeover",
             "legend"}


def visitlab_seed(root_seed: int, stream: int = 0) -> int:
    """The integer seed of the Visit-the-lab runs (``stream`` 0) or of the combined
    task's evaluations (1) for the reproduction's root seed."""
    seq = np.random.SeedSequence(int(root_seed), spawn_key=(VISITLAB_SPAWN_KEY, int(stream)))
    return int(seq.generate_state(1, np.uint32)[0])


# --------------------------------------------------------------------------- settings


def _whole(v: Any, key: str, low: int = 1) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or v < low:
        raise ConfigError(f"expected a whole number >= {low}, got {v!r}", key=key)
    return int(v)


def _fraction(v: Any, key: str) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or not 0.0 <= v <= 1.0:
        raise ConfigError(f"expected a number in [0, 1], got {v!r}", key=key)
    return float(v)


def _table(v: Any, key: str) -> dict[str, Any]:
    if v is None:
        return {}
    if not isinstance(v, Mapping):
        raise ConfigError(f"expected a table, got {v!r}", key=key)
    return dict(v)


@dataclass(frozen=True)
class RunSpec:
    """One training run (module docstring). ``env`` and ``overrides`` are JSON-ready."""

    label: str
    agent: str
    task: str
    trials: int
    seeds: int
    variant: str = "thesis"
    env: Mapping[str, Any] = field(default_factory=dict)
    overrides: Mapping[str, Any] = field(default_factory=dict)
    observer: bool = False
    takeover: float = 0.5
    keep_model: bool = False
    legend: str = ""

    def key(self) -> dict[str, Any]:
        """Everything that defines the run's numbers (not its label)."""
        return {"agent": self.agent, "task": self.task, "trials": self.trials,
                "seeds": self.seeds, "variant": self.variant, "env": dict(self.env),
                "overrides": dict(self.overrides), "observer": self.observer,
                "takeover": self.takeover if self.observer else None,
                "keep_model": self.keep_model}

    @property
    def steps(self) -> int:
        """Steps per trial of the run's env."""
        from simlab.visitlab.training import make_env

        return int(make_env(self.task, variant=self.variant, **env_kwargs(self.env)).max_steps)


def env_kwargs(env: Mapping[str, Any]) -> dict[str, Any]:
    """Env settings of a run with a human given as a table turned into a :class:`Human`."""
    from simlab.visitlab.humans import Human

    out = dict(env)
    h = out.get("human")
    if isinstance(h, Mapping):
        fields = dict(h)
        if "speed_probs" in fields:
            fields["speed_probs"] = tuple(fields["speed_probs"])
        try:
            out["human"] = Human(**fields)
        except TypeError as exc:
            raise ConfigError(f"bad human table: {exc}", key="env.human") from None
    return out


def _budget_trials(budget: Mapping[str, Any], label: str, task: str, key: str = "trials") -> int:
    t = budget.get(key)
    if isinstance(t, Mapping):
        if label in t:
            return _whole(t[label], f"budget.{key}.{label}")
        if task in t:
            return _whole(t[task], f"budget.{key}.{task}")
        raise ConfigError(f"no trials for run {label!r} (task {task})", key=f"budget.{key}",
                          fix=f"add {label} = N or {task} = N")
    if t is None:
        raise ConfigError("missing", key=f"budget.{key}")
    return _whole(t, f"budget.{key}")


def parse_run(raw: Any, where: str, params: Mapping[str, Any], budget: Mapping[str, Any],
              *, trials_key: str = "trials", keep_model: bool = False) -> RunSpec:
    """A :class:`RunSpec` from a run table (``where`` names it in errors)."""
    from simlab.agents.registry import AGENTS

    run = _table(raw, where)
    unknown = sorted(set(run) - _RUN_KEYS)
    if unknown:
        raise ConfigError(f"unknown key(s) {', '.join(unknown)}", key=where,
                          fix=f"allowed: {', '.join(sorted(_RUN_KEYS))}")
    agent = run.get("agent")
    if agent not in AGENTS:
        raise ConfigError(f"unknown agent {agent!r}", key=f"{where}.agent",
                          fix=f"use one of {', '.join(AGENTS)}")
    task = run.get("task", params.get("task"))
    if task not in _TASKS:
        raise ConfigError(f"expected one of {_TASKS}, got {task!r}", key=f"{where}.task")
    variant = run.get("variant", params.get("variant", "thesis"))
    if variant not in ("thesis", "paper"):
        raise ConfigError(f"expected thesis or paper, got {variant!r}", key=f"{where}.variant")
    label = str(run.get("label", agent))
    if not label.replace("_", "").replace("-", "").isalnum():
        raise ConfigError(f"use letters, digits, '_' and '-', got {label!r}", key=f"{where}.label")
    env = {**_table(params.get("env"), "params.env"), **_table(run.get("env"), f"{where}.env")}
    observer = run.get("observer", False)
    if not isinstance(observer, bool):
        raise ConfigError(f"expected true or false, got {observer!r}", key=f"{where}.observer")
    return RunSpec(label=label.replace("-", "_"), agent=agent, task=task,
                   trials=_budget_trials(budget, label, task, trials_key),
                   seeds=_whole(budget["seeds"], "budget.seeds"), variant=variant, env=env,
                   overrides=_table(run.get("overrides"), f"{where}.overrides"),
                   observer=observer,
                   takeover=_fraction(run.get("takeover", 0.5), f"{where}.takeover"),
                   keep_model=keep_model, legend=str(run.get("legend", "")))


def param_notes(params: Mapping[str, Any]) -> list[str]:
    """``params.notes``: sentences the TOML adds to the result (e.g. why our simulation
    differs from the thesis), a list of strings."""
    raw = params.get("notes", [])
    if not isinstance(raw, list) or not all(isinstance(n, str) and n.strip() for n in raw):
        raise ConfigError(f"expected a list of sentences, got {raw!r}", key="params.notes")
    return [n.strip() for n in raw]


# --------------------------------------------------------------------------- shared runs




#: The modules a training run's numbers depend on (besides ``simlab.agents``).
_RUN_SOURCES = ("actions", "grid", "perception", "humans", "dynamics", "envs", "training",
                "passive")


@functools.lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """:func:`~simlab.orchestration.stages.source_fingerprint` of the source a training run depends on:
    the Visit-the-lab simulation and training loops (:data:`_RUN_SOURCES`) and every
    module of ``simlab.agents``. Figures, the combined architecture and these runners are
    not part of it (they do not change a run's numbers)."""
    import simlab

    pkg = Path(simlab.__file__).resolve().parent
    files = [pkg / "visitlab" / f"{name}.py" for name in _RUN_SOURCES]
    return source_fingerprint([*files, pkg / "agents"])


@dataclass(frozen=True, eq=False)
class RunData:
    """A built run: ``returns`` ``(seeds, trials)``, final ``q`` ``(seeds, S, A)``,
    ``q_observer`` (or None), the models kept (``model_<i>.npz`` paths) and whether
    this experiment built it."""

    spec: RunSpec
    returns: np.ndarray
    q: np.ndarray
    q_observer: np.ndarray | None
    model_paths: tuple[Path, ...]
    built: bool
    path: Path

    def model(self, i: int) -> dict[str, np.ndarray]:
        """Seed ``i``'s kept model as :func:`~simlab.visitlab.training.model_state` arrays."""
        with np.load(self.model_paths[i], allow_pickle=False) as data:
            return {k: data[k] for k in data.files}


def _stage_dir(ctx: RunContext, kind: str, key: Mapping[str, Any]) -> tuple[Path, dict]:
    digest, full = stage_key(kind, {"root_seed": int(ctx.root_seed), **key}, code_fingerprint())
    return ctx.cache / "visitlab" / f"{kind}-{digest}", full


def train_job(spec: dict[str, Any], seed: int, index: int) -> Any:
    """Seed ``index`` of the run ``spec`` (a :meth:`RunSpec.key` dict): a
    :class:`~simlab.visitlab.training.SeedRun` (module-level, for ``ctx.map``)."""
    from simlab.visitlab.passive import observer_run
    from simlab.visitlab.training import loop_agent_config, run_seed, seed_generators

    gens = seed_generators(int(seed), int(spec["seeds"]))[int(index)]
    env = env_kwargs(spec["env"])
    if spec["observer"]:
        return observer_run(spec["task"], spec["agent"], int(spec["trials"]), gens,
                            takeover_fraction=float(spec["takeover"]), variant=spec["variant"],
                            actor_overrides=dict(spec["overrides"]), env_kwargs=env)
    cfg = loop_agent_config(spec["agent"], spec["task"], spec["variant"], dict(spec["overrides"]))
    return run_seed(spec["task"], cfg, int(spec["trials"]), gens, variant=spec["variant"],
                    env_kwargs=env, keep_model=bool(spec["keep_model"]))


def _load_run(spec: RunSpec, d: Path, built: bool) -> RunData:
    with np.load(d / "runs.npz", allow_pickle=False) as data:
        returns = data["returns"]
        q = data["q"]
        q_obs = data["q_observer"] if "q_observer" in data.files else None
    models = tuple(d / f"model_{i}.npz" for i in range(spec.seeds)) if spec.keep_model else ()
    return RunData(spec, returns, q, q_obs, models, built, d)


def _job_cost(spec: RunSpec) -> float:
    """Rough relative cost of one seed (to start the long jobs first)."""
    per_step = {"social": 4.0, "gotohuman": 1.5, "nav": 1.0}[spec.task]
    if spec.agent not in ("q-learning", "q-softmax"):
        per_step *= 3.0
    return spec.trials * spec.steps * per_step


def get_runs(ctx: RunContext, specs: Sequence[RunSpec], desc: str = "training runs"
             ) -> list[RunData]:
    """The runs ``specs`` from the shared cache, building the missing ones (all their
    seeds in one ``ctx.map``, longest first)."""
    seed = visitlab_seed(ctx.root_seed)
    found: dict[int, RunData] = {}
    todo: list[tuple[int, RunSpec, Path, dict]] = []
    for i, spec in enumerate(specs):
        d, full = _stage_dir(ctx, "run", spec.key())
        if (d / _MARKER).exists():
            found[i] = _load_run(spec, d, False)
        else:
            todo.append((i, spec, d, full))
    if todo:
        uniq: dict[Path, tuple[RunSpec, dict]] = {}
        for _, spec, d, full in todo:
            uniq.setdefault(d, (spec, full))
        jobs = [(_job_cost(spec), d, k) for d, (spec, _) in uniq.items()
                for k in range(spec.seeds)]
        jobs.sort(key=lambda j: -j[0])
        t0 = time.perf_counter()
        results = ctx.map(train_job, [{"spec": uniq[d][0].key(), "seed": seed, "index": k}
                                      for _, d, k in jobs], desc=f"{ctx.name}: {desc}")
        wall = time.perf_counter() - t0
        by_run: dict[Path, dict[int, Any]] = {}
        for (_, d, k), res in zip(jobs, results, strict=True):
            by_run.setdefault(d, {})[k] = res
        for d, (spec, full) in uniq.items():
            _write_run(d, spec, full, [by_run[d][k] for k in range(spec.seeds)], wall)
        for i, spec, d, _ in todo:
            found[i] = _load_run(spec, d, True)
        ctx.log(f"built {len(uniq)} training run(s), {len(jobs)} seeds, in {wall:.0f} s")
    return [found[i] for i in range(len(specs))]


def _write_run(d: Path, spec: RunSpec, full: dict, seeds: list[Any], wall: float) -> None:
    with file_lock(d.parent / f".{d.name}.lock"):
        if (d / _MARKER).exists():
            return
        if d.exists():  # an interrupted build
            shutil.rmtree(d)
        d.mkdir(parents=True)
        arrays = {"returns": np.stack([s.returns for s in seeds]),
                  "q": np.stack([s.q for s in seeds])}
        if seeds[0].q_observer is not None:
            arrays["q_observer"] = np.stack([s.q_observer for s in seeds])
        with atomic_write(d / "runs.npz", "wb") as fh:
            np.savez_compressed(fh, **arrays)
        if spec.keep_model:
            for i, s in enumerate(seeds):
                with atomic_write(d / f"model_{i}.npz", "wb") as fh:
                    np.savez_compressed(fh, **s.model)
        atomic_write_json(d / _MARKER, {"key": full, "wall_seconds_of_the_batch": wall,
                                         "steps": [int(s.steps) for s in seeds]})


def _cache_note(runs: Sequence[RunData]) -> str:
    built = sum(r.built for r in runs)
    reused = len(runs) - built
    parts = []
    if built:
        parts.append(f"{built} built")
    if reused:
        parts.append(f"{reused} reused from the shared cache")
    return f"Training runs: {', '.join(parts)} (DIR/_cache/visitlab)."


# --------------------------------------------------------------------------- curve metrics


def curve_metrics(label: str, returns: np.ndarray, thresholds: Sequence[float] = (),
                  windows: Mapping[str, Sequence[float]] | None = None) -> dict[str, Any]:
    """The curve metrics of one run (module docstring), ``returns`` ``(seeds, trials)``."""
    from simlab.visitlab.training import smooth_curve

    returns = np.asarray(returns, dtype=np.float64)
    n_trials = returns.shape[1]
    tail = max(1, n_trials // 10)
    per_seed = returns[:, -tail:].mean(axis=1)
    plateau = float(per_seed.mean())
    x, mean, std = smooth_curve(returns)
    out: dict[str, Any] = {
        f"{label}_plateau": plateau,
        f"{label}_std": float(std[-min(10, std.size):].mean()),
        f"{label}_seed_std": float(per_seed.std()),
    }
    hit = np.flatnonzero(mean >= 0.9 * plateau) if plateau > 0 else np.zeros(0, dtype=int)
    out[f"{label}_trials_to_90pct"] = int(x[hit[0]]) if hit.size else None
    for thr in thresholds:
        hit = np.flatnonzero(mean >= thr)
        out[f"{label}_trials_to_{_fmt(thr)}"] = int(x[hit[0]]) if hit.size else None
    for name, (lo, hi) in (windows or {}).items():
        a = round(lo * n_trials)
        b = max(round(hi * n_trials), a + 1)
        out[f"{label}_{name}"] = float(returns[:, a:b].mean())
    return out


def _fmt(x: float) -> str:
    return str(int(x)) if float(x) == int(x) else f"{x:g}"


def _curve_details(label: str, returns: np.ndarray) -> dict[str, Any]:
    from simlab.visitlab.training import smooth_curve

    x, mean, std = smooth_curve(returns)
    return {"x": x.tolist(), "mean": np.round(mean, 4).tolist(), "std": np.round(std, 4).tolist()}


def _windows(params: Mapping[str, Any]) -> dict[str, tuple[float, float]]:
    raw = _table(params.get("windows"), "params.windows")
    out = {}
    for name, v in raw.items():
        if not (isinstance(v, list) and len(v) == 2 and all(isinstance(x, int | float) for x in v)
                and 0 <= v[0] < v[1] <= 1):
            raise ConfigError(f"expected [lo, hi] with 0 <= lo < hi <= 1, got {v!r}",
                              key=f"params.windows.{name}")
        out[str(name)] = (float(v[0]), float(v[1]))
    return out


def _thresholds(params: Mapping[str, Any]) -> list[float]:
    raw = params.get("thresholds", [])
    if not isinstance(raw, list) or not all(isinstance(x, int | float) and not isinstance(x, bool)
                                            for x in raw):
        raise ConfigError(f"expected a list of numbers, got {raw!r}", key="params.thresholds")
    return [float(x) for x in raw]


# --------------------------------------------------------------------------- visitlab.curves


@runner("visitlab.curves")
def curves(params: dict[str, Any], budget: dict[str, Any], ctx: RunContext) -> RunResult:
    """Learning curves of the runs ``[[params.runs]]`` (module docstring).

    ``params.panels`` (optional): ``[{title = "...", runs = ["label", ...]}, ...]``
    (default: one panel with every run); ``params.title``; ``params.ylabel``;
    ``params.thresholds``, ``params.windows``: extra curve metrics. Metrics: the curve
    metrics of every run, plus ``trials`` and ``seeds``. Figure: ``curves.png``.
    """
    raw_runs = params.get("runs")
    if not isinstance(raw_runs, list) or not raw_runs:
        raise ConfigError("expected one or more [[params.runs]] tables", key="params.runs")
    specs = [parse_run(r, f"params.runs[{i}]", params, budget) for i, r in enumerate(raw_runs)]
    labels = [s.label for s in specs]
    if len(set(labels)) != len(labels):
        raise ConfigError(f"run labels must be unique, got {labels}", key="params.runs")
    thresholds, windows = _thresholds(params), _windows(params)
    runs = get_runs(ctx, specs)
    by_label = {r.spec.label: r for r in runs}
    metrics: dict[str, Any] = {}
    details: dict[str, Any] = {"curves": {}}
    for r in runs:
        metrics.update(curve_metrics(r.spec.label, r.returns, thresholds, windows))
        details["curves"][r.spec.label] = _curve_details(r.spec.label, r.returns)
    metrics["seeds"] = specs[0].seeds
    panels_raw = params.get("panels") or [{"title": "", "runs": labels}]
    panels = []
    marks: list[list[float]] = []
    for i, p in enumerate(panels_raw):
        p = _table(p, f"params.panels[{i}]")
        names = [str(x).replace("-", "_") for x in p.get("runs", [])]
        missing = [n for n in names if n not in by_label]
        if missing or not names:
            raise ConfigError(f"unknown run label(s) {missing or names}",
                              key=f"params.panels[{i}].runs", fix=f"labels: {', '.join(labels)}")
        curves_ = [(by_label[n].spec.legend or n, by_label[n].returns) for n in names]
        panels.append((str(p.get("title", "")), curves_))
        marks.append(sorted({s.takeover * s.trials for s in (by_label[n].spec for n in names)
                             if s.observer and s.takeover < 1.0}))
    from simlab.visitlab.figures import plot_curve_panels

    fig = plot_curve_panels(panels, ctx.out / "curves.png",
                            ylabel=str(params.get("ylabel", "reward per trial")),
                            title=f"{params.get('title', '')} ({specs[0].seeds} seeds)".strip(),
                            marks=marks)
    notes = [_cache_note(runs), "Runs: " + "; ".join(
        f"{s.label} = {s.agent} on {s.task} ({s.variant}), {s.trials:,} trials"
        + (f", a Q-learner watching it takes over at {s.takeover:.0%}" if s.observer else "")
        + (f", {json.dumps(dict(s.overrides))}" if s.overrides else "")
        + (f", env {json.dumps(dict(s.env))}" if s.env else "") for s in specs) + "."]
    return RunResult(metrics=metrics, figures=[fig], notes=notes + param_notes(params),
                     details=details)


# --------------------------------------------------------------------------- Fig. 4.3


@runner("visitlab.nav_heatmaps")
def nav_heatmaps(params: dict[str, Any], budget: dict[str, Any], ctx: RunContext) -> RunResult:
    """Thesis Fig. 4.3: the navigation Q values for each goal room.

    ``params.run``: the run table (goal-conditioned navigation: random start and goal).
    Metrics: ``goals``; ``min_greedy_success`` / ``mean_greedy_success`` (fraction of
    the cells outside the goal room from which the greedy policy of a seed's Q reaches
    the goal room within one trial, worst goal / mean over goals and seeds);
    ``min_inside_minus_outside`` (per goal, mean ``max_a Q`` inside the goal room minus
    outside, averaged over seeds; the worst goal); ``mean_corr_vstar`` (correlation of
    ``max_a Q`` with the optimal V* over the cells, mean over goals and seeds).
    Figure: ``heatmaps.png`` (``max_a Q`` averaged over seeds).
    """
    from simlab.visitlab.figures import plot_nav_heatmaps
    from simlab.visitlab.passive import nav_optimal_q

    spec = parse_run(params.get("run"), "params.run", params, budget)
    if spec.task != "nav":
        raise ConfigError("expected a navigation run", key="params.run.task")
    (run,) = get_runs(ctx, [spec])
    env = env_kwargs(spec.env)
    from simlab.visitlab.training import make_env

    nav_env = make_env("nav", variant=spec.variant, **env)
    lay = nav_env.layout
    horizon = nav_env.max_steps
    qstar = nav_optimal_q(lay)
    n = lay.n_cells
    nxt = lay.transition_table()
    labels = lay.cell_labels
    success = np.zeros((run.q.shape[0], len(lay.goal_labels)))
    corr = np.zeros_like(success)
    for i, q in enumerate(run.q):
        for j, g in enumerate(lay.goal_labels):
            block = q[g * n:(g + 1) * n]
            success[i, j] = greedy_success(nxt, labels, block, g, horizon)
            corr[i, j] = _corr(block.max(axis=1), qstar[g * n:(g + 1) * n].max(axis=1))
    values = run.q.max(axis=2).mean(axis=0)  # mean over seeds of max_a Q
    gaps = []
    for g in lay.goal_labels:
        v = values[g * n:(g + 1) * n]
        inside = labels == g
        gaps.append(float(v[inside].mean() - v[~inside].mean()))
    fig = plot_nav_heatmaps(lay, values, ctx.out / "heatmaps.png", arrows_q=run.q[0],
                            title=f"{spec.agent}: max_a Q per goal room (mean of {spec.seeds} "
                                  f"seeds, {spec.trials:,} trials; arrows: seed 0's greedy move)")
    per_goal = success.mean(axis=0)
    metrics = {"goals": len(lay.goal_labels), "min_greedy_success": float(per_goal.min()),
               "mean_greedy_success": float(success.mean()),
               "min_inside_minus_outside": float(min(gaps)),
               "mean_corr_vstar": float(np.nanmean(corr)),
               **curve_metrics(spec.label, run.returns)}
    notes = [_cache_note([run]),
             f"{spec.agent} trained on the {lay.name} world with a random start and a random "
             f"goal room each trial ({spec.trials:,} trials x {spec.seeds} seeds, "
             f"{horizon}-step trials); the maps show max_a Q averaged over seeds."]
    details = {"greedy_success_per_goal": per_goal.round(4).tolist(),
               "inside_minus_outside": [round(g, 4) for g in gaps],
               "corr_vstar_per_goal": np.nanmean(corr, axis=0).round(4).tolist()}
    return RunResult(metrics=metrics, figures=[fig], notes=notes + param_notes(params),
                     details=details)


def greedy_success(nxt: np.ndarray, labels: np.ndarray, q: np.ndarray, goal: int,
                   horizon: int) -> float:
    """Fraction of the cells outside room ``goal`` from which following ``argmax_a q``
    (first maximiser) reaches the room within ``horizon`` moves; ``q`` ``(n_cells, 25)``,
    ``nxt`` the layout's move table."""
    best = q.argmax(axis=1)
    cells = np.flatnonzero(labels != goal)
    pos = cells.copy()
    done = np.zeros(cells.size, dtype=bool)
    for _ in range(horizon):
        pos = nxt[pos, best[pos]]
        done |= labels[pos] == goal
    return float(done.mean()) if cells.size else 1.0


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    if a.std() == 0 or b.std() == 0:
        return math.nan
    return float(np.corrcoef(a, b)[0, 1])


# --------------------------------------------------------------------------- modules


_MODULE_KEYS = ("nav", "gotohuman", "social")


def module_specs(params: Mapping[str, Any], budget: Mapping[str, Any]) -> dict[str, RunSpec]:
    """The three module runs of the combined architecture: ``[params.nav]``,
    ``[params.gotohuman]``, ``[params.social]`` (run tables without ``task``), trained
    for ``budget.nav_trials``, ``budget.gth_trials``, ``budget.social_trials``. The
    social run keeps its model (for continued learning)."""
    out = {}
    trials_keys = {"nav": "nav_trials", "gotohuman": "gth_trials", "social": "social_trials"}
    for task in _MODULE_KEYS:
        raw = _table(params.get(task), f"params.{task}")
        if "task" in raw:
            raise ConfigError("the task of a module is its table's name", key=f"params.{task}.task")
        raw = {"label": task, **raw, "task": task}
        out[task] = parse_run(raw, f"params.{task}", params, budget,
                              trials_key=trials_keys[task], keep_model=task == "social")
    return out


def _combined_task(params: Mapping[str, Any], specs: Mapping[str, RunSpec], human: Any = None):
    from simlab.visitlab.combined import CombinedTask
    from simlab.visitlab.perception import perception_for

    c = _table(params.get("combined"), "params.combined")
    unknown = sorted(set(c) - {"layout", "speed_weights", "max_steps"})
    if unknown:
        raise ConfigError(f"unknown key(s) {', '.join(unknown)}", key="params.combined")
    if human is None:
        human = env_kwargs(specs["social"].env).get("human", "easy")
    return CombinedTask(layout=c.get("layout", "gridworld"), human=human,
                        perception=perception_for(specs["social"].variant),
                        speed_weights=tuple(c.get("speed_weights", (0.1, 0.1, 0.8))),
                        max_steps=_whole(c.get("max_steps", 100), "params.combined.max_steps"))


def _modules(runs: Mapping[str, RunData], i: int):
    from simlab.visitlab.combined import Modules

    return Modules(runs["nav"].q[i], runs["social"].q[i], runs["gotohuman"].q[i])


def direction_matrix(weights: Sequence[float]) -> np.ndarray:
    """``(25, 8)`` matrix ``M`` with ``Q_row @ M`` = the weighted sums per direction of
    :func:`simlab.visitlab.combined.direction_values` (STAY has no direction)."""
    from simlab.visitlab.actions import ACTION_DIR, ACTION_SPEED

    m = np.zeros((25, 8))
    for a in range(24):
        m[a, ACTION_DIR[a]] = weights[ACTION_SPEED[a] - 1]
    return m


def _module_metrics(runs: Mapping[str, RunData], task: Any) -> dict[str, Any]:
    """Quality of the navigation module's required directions and the modules' curves."""
    from simlab.visitlab.passive import nav_optimal_q

    lay = task.layout
    m = direction_matrix(task.speed_weights)
    n = lay.n_cells
    rows = np.concatenate([np.arange(n)[lay.cell_labels != g] + g * n for g in lay.goal_labels])
    best_star = nav_optimal_q(lay)[rows] @ m
    top = best_star.max(axis=1) - 1e-9
    ok = [np.mean(best_star[np.arange(rows.size), (q[rows] @ m).argmax(axis=1)] >= top)
          for q in runs["nav"].q]
    return {"nav_direction_optimal": float(np.mean(ok)),
            "nav_plateau": curve_metrics("x", runs["nav"].returns)["x_plateau"],
            "gth_plateau": curve_metrics("x", runs["gotohuman"].returns)["x_plateau"],
            "social_plateau": curve_metrics("x", runs["social"].returns)["x_plateau"]}


def evaluate_job(task: Any, modules: Any, trials: int, seed: int, index: int, n_seeds: int,
                 epsilon: float) -> Any:
    """Greedy (``epsilon`` 0) or epsilon-greedy evaluation of seed ``index``'s modules."""
    from simlab.visitlab.combined import evaluate
    from simlab.visitlab.training import seed_generators

    return evaluate(task, modules, int(trials), seed_generators(seed, n_seeds)[index],
                    epsilon=float(epsilon))


# --------------------------------------------------------------------------- combined


@runner("visitlab.combined")
def combined(params: dict[str, Any], budget: dict[str, Any], ctx: RunContext) -> RunResult:
    """The combined architecture (thesis 3.1.1, 4.4): goal rooms reached per trial.

    Trains (or reuses) the three modules (:func:`module_specs`), then runs the frozen
    architecture greedily for ``budget.trials`` trials per seed, epsilon-greedily, and
    the chance level (the social module replaced by uniformly random actions). Metrics:
    ``goals_per_trial`` (mean over trials and seeds), ``goals_per_trial_seed_std``,
    ``egreedy_goals_per_trial`` (the social module epsilon-greedy with its training
    epsilon), ``random_goals_per_trial``, ``trials_with_a_goal`` (fraction),
    ``nav_direction_optimal`` (fraction of (cell, goal) outside the goal room where the
    navigation module's required direction is an optimal one), the modules' plateaus,
    ``gif_goals``. Figures: ``goals_per_trial.png``, ``episode.gif``.
    """
    from simlab.visitlab.combined import record_episodes, write_episode_gif
    from simlab.visitlab.figures import plot_histograms
    from simlab.visitlab.training import loop_agent_config, seed_generators

    specs = module_specs(params, budget)
    n = specs["nav"].seeds
    trials = _whole(budget.get("trials"), "budget.trials")
    task = _combined_task(params, specs)
    got = get_runs(ctx, [specs[k] for k in _MODULE_KEYS], desc="modules")
    runs = dict(zip(_MODULE_KEYS, got, strict=True))
    seed = visitlab_seed(ctx.root_seed, 1)
    social_cfg = loop_agent_config(specs["social"].agent, "social", specs["social"].variant,
                                   dict(specs["social"].overrides))
    eps = float(getattr(social_cfg, "epsilon", 0.05))
    jobs = [{"task": task, "modules": _modules(runs, i), "trials": trials, "seed": seed,
             "index": i, "n_seeds": n, "epsilon": e} for e in (0.0, eps, 1.0) for i in range(n)]
    res = ctx.map(evaluate_job, jobs, desc=f"{ctx.name}: evaluation")
    goals = np.stack([r.goals for r in res[:n]])
    explore = np.stack([r.goals for r in res[n:2 * n]])
    rand = np.stack([r.goals for r in res[2 * n:]])
    figures = [plot_histograms([("combined architecture (greedy)", goals.ravel()),
                                (f"eps-greedy social module ({eps:g})", explore.ravel()),
                                ("random social actions", rand.ravel())],
                               ctx.out / "goals_per_trial.png", xlabel="goal rooms reached per trial",
                               title=f"{task.max_steps}-step trials, {n} seeds x {trials} trials")]
    # the GIF: the first evaluation trial of seed 0 with two goals or more (else the best)
    k = min(trials, 50)
    episodes = record_episodes(task, _modules(runs, 0), k, seed_generators(seed, n)[0])
    pick = next((e for e in episodes if e.goals >= 2), max(episodes, key=lambda e: e.goals))
    figures.append(write_episode_gif(task, pick, ctx.out / "episode.gif", overwrite=True))
    per_seed = goals.mean(axis=1)
    metrics = {"goals_per_trial": float(goals.mean()), "goals_per_trial_seed_std":
               float(per_seed.std()), "egreedy_goals_per_trial": float(explore.mean()),
               "random_goals_per_trial": float(rand.mean()),
               "trials_with_a_goal": float((goals > 0).mean()),
               **_module_metrics(runs, task), "gif_goals": pick.goals,
               "trials": trials, "seeds": n, "max_steps": task.max_steps}
    notes = [_cache_note(got),
             f"Modules (seed i of each): navigation {specs['nav'].agent} "
             f"({specs['nav'].trials:,} trials, random start and goal), go-to-human "
             f"{specs['gotohuman'].agent} ({specs['gotohuman'].trials:,} trials), social "
             f"{specs['social'].agent} with human '{task.human.name}' "
             f"({specs['social'].trials:,} trials). World {task.layout.name}, "
             f"{task.max_steps}-step trials, speed weights {task.speed_weights}.",
             "The GIF is the first evaluation trial of seed 0 in which at least two goal "
             "rooms were reached (the goal room is blue; the caption gives the social "
             "module's action, the delegated go-to-human move after '->', the interaction "
             "level and the required direction).",
             "A greedy social module can loop: in social training action 29 jumped two "
             "cells ahead of the human's gaze with a random orientation, here it is one "
             "go-to-human move, which does nothing once the robot stands in the facing "
             "field; trials_with_a_goal and the eps-greedy evaluation "
             "(egreedy_goals_per_trial, the module's own exploration rate) show how much "
             "this costs."]
    details = {"goals_per_seed": per_seed.round(4).tolist(),
               "random_goals_per_seed": rand.mean(axis=1).round(4).tolist()}
    return RunResult(metrics=metrics, figures=figures, notes=notes + param_notes(params),
                     details=details)


# --------------------------------------------------------------------------- Fig. 4.7


def adapt_job(task: Any, modules: Any, model: dict[str, np.ndarray] | None, agent_cfg: Any,
              trials: int, seed: int, index: int, n_seeds: int) -> np.ndarray:
    """Goals per trial of seed ``index``'s social module continuing to learn."""
    from simlab.visitlab.adaptability import continue_learning
    from simlab.visitlab.training import seed_generators

    run = continue_learning(task, modules, agent_cfg, int(trials),
                            seed_generators(seed, n_seeds)[index], model=model)
    return run.goals


def _adaptation_humans(params: Mapping[str, Any], trained: Any) -> dict[str, Any]:
    """``[params.humans]`` (name -> preset name or table of Human fields), or the thesis's
    three humans for the training human (:func:`~simlab.visitlab.adaptability.thesis_humans`)."""
    from simlab.visitlab.adaptability import thesis_humans
    from simlab.visitlab.humans import human as get_human

    raw = _table(params.get("humans"), "params.humans")
    if not raw:
        return thesis_humans(trained)
    out = {}
    for name, h in raw.items():
        if not str(name).replace("_", "").isalnum():
            raise ConfigError(f"use letters, digits and '_', got {name!r}",
                              key=f"params.humans.{name}")
        out[str(name)] = (env_kwargs({"human": dict(h)})["human"] if isinstance(h, Mapping)
                          else get_human(h))
    return out


@runner("visitlab.adaptability")
def adaptability(params: dict[str, Any], budget: dict[str, Any], ctx: RunContext) -> RunResult:
    """Thesis Fig. 4.7: the social module trained with one human continues learning in
    the combined task with the same human, a 2x slower one and one needing POINTING.

    The modules are :func:`module_specs` (shared with ``visitlab.combined``); the
    humans :func:`simlab.visitlab.adaptability.thesis_humans` of the social module's
    human, or ``[params.humans]`` (name -> preset or table of Human fields; a human
    named ``same`` is the reference of the ratios); ``params.carry_model`` a list of booleans (what continues: Q and model, or Q
    only; one figure panel each; the first is the one the metrics without suffix
    describe). Metrics per human ``h`` (``same``, ``slower``, ``pointing``) and carry
    option (suffix ``_q_only`` for Q only, ``_model`` for Q and model, on the options
    after the first): ``h_start`` (mean goals per trial over the
    first 10 % of trials), ``h_final`` (last 20 %), ``h_trials_to_90pct`` (first trial at
    which the smoothed curve reaches 90 % of ``h_final``), and the ratios
    ``pointing_over_same`` and ``slower_over_same`` of the final levels. Figure:
    ``adaptability.png``.
    """
    from simlab.visitlab.figures import plot_curve_panels
    from simlab.visitlab.training import loop_agent_config

    specs = module_specs(params, budget)
    n = specs["nav"].seeds
    trials = _whole(budget.get("trials"), "budget.trials")
    carry = params.get("carry_model", [True])
    if (not isinstance(carry, list) or not carry or not all(isinstance(c, bool) for c in carry)
            or len(set(carry)) != len(carry)):
        raise ConfigError(f"expected a list of distinct booleans, got {carry!r}",
                          key="params.carry_model")
    base_task = _combined_task(params, specs)
    humans = _adaptation_humans(params, base_task.human)
    got = get_runs(ctx, [specs[k] for k in _MODULE_KEYS], desc="modules")
    runs = dict(zip(_MODULE_KEYS, got, strict=True))
    s = specs["social"]
    cfg = loop_agent_config(s.agent, "social", s.variant, dict(s.overrides))
    seed = visitlab_seed(ctx.root_seed, 1)
    jobs, keys = [], []
    for c in carry:
        for name, h in humans.items():
            for i in range(n):
                jobs.append({"task": base_task.with_human(h), "modules": _modules(runs, i),
                             "model": runs["social"].model(i) if c else None, "agent_cfg": cfg,
                             "trials": trials, "seed": seed, "index": i, "n_seeds": n})
                keys.append((c, name))
    res = ctx.map(adapt_job, jobs, desc=f"{ctx.name}: continued learning")
    curves_: dict[tuple[bool, str], list[np.ndarray]] = {}
    for k, g in zip(keys, res, strict=True):
        curves_.setdefault(k, []).append(g)
    metrics: dict[str, Any] = {}
    panels = []
    legends = {"same": "same human", "slower": "2x slower human", "pointing": "pointing need"}
    details: dict[str, Any] = {"curves": {}}
    from simlab.visitlab.training import smooth_curve

    for c in carry:
        suffix = "" if c == carry[0] else ("_model" if c else "_q_only")
        panel = []
        for name in humans:
            g = np.stack(curves_[(c, name)])
            start = float(g[:, :max(1, trials // 10)].mean())
            final = float(g[:, -max(1, trials // 5):].mean())
            x, mean, _ = smooth_curve(g, min(50, trials))
            hit = np.flatnonzero(mean >= 0.9 * final) if final > 0 else np.zeros(0, dtype=int)
            metrics[f"{name}_start{suffix}"] = start
            metrics[f"{name}_final{suffix}"] = final
            metrics[f"{name}_trials_to_90pct{suffix}"] = int(x[hit[0]]) if hit.size else None
            panel.append((legends.get(name, humans[name].name), g))
            details["curves"][f"{name}{suffix}"] = _curve_details(name, g)
        same = metrics.get(f"same_final{suffix}")
        for name in humans:
            if same is not None and name != "same":
                metrics[f"{name}_over_same{suffix}"] = (metrics[f"{name}_final{suffix}"] / same
                                                       if same > 0 else None)
        title = ("Q table and model carried over" if c
                 else "Q table only (model rebuilt from the new human)")
        panels.append((title, panel))
    fig = plot_curve_panels(panels, ctx.out / "adaptability.png",
                            ylabel="goal rooms reached per trial",
                            title=f"Continued learning with a new human ({n} seeds, "
                                  f"{base_task.max_steps}-step trials)", n_points=min(50, trials))
    metrics.update({"trials": trials, "seeds": n})
    trained = env_kwargs(s.env).get("human", "easy")
    described = "; ".join(f"{name}: '{h.name}' (s_H {h.speed_probs}, P_H {h.pointing_need:g})"
                          for name, h in humans.items())
    notes = [_cache_note(got),
             f"Social module trained with '{getattr(trained, 'name', trained)}'; continued with "
             f"{described}. The social agent ({s.agent}) continues with its own settings; the "
             "navigation and go-to-human modules are frozen (greedy)."]
    return RunResult(metrics=metrics, figures=[fig], notes=notes + param_notes(params),
                     details=details)


# --------------------------------------------------------------------------- poster Fig. 5


@runner("visitlab.passive_qmaps")
def passive_qmaps(params: dict[str, Any], budget: dict[str, Any], ctx: RunContext) -> RunResult:
    """IMOL poster Fig. 5: Q maps learned by model-free agents on the goal-conditioned
    navigation task, alone or watching model-based agents that explore differently.

    ``[[params.runs]]`` as for ``visitlab.curves`` (navigation runs; an ``observer`` run
    contributes its observer's Q table, another run its own); ``params.goal`` the goal
    room of the maps. Metrics per run ``L``: ``L_corr_vstar`` (Pearson correlation of
    the learned ``max_a Q(s)`` with the optimal ``V*(s)`` over every state of every goal,
    pooled over seeds), ``L_mae_vstar`` (mean absolute error), ``L_visited`` (fraction
    of states whose learned value is not 0, i.e. that the learner ever updated toward a
    reward) and the curve metrics. Figures: ``qmaps.png``, ``q_vs_vstar.png``.
    """
    from simlab.visitlab.figures import plot_q_maps, plot_q_vs_vstar
    from simlab.visitlab.passive import nav_optimal_q
    from simlab.visitlab.training import make_env

    raw_runs = params.get("runs")
    if not isinstance(raw_runs, list) or not raw_runs:
        raise ConfigError("expected one or more [[params.runs]] tables", key="params.runs")
    specs = [parse_run(r, f"params.runs[{i}]", params, budget) for i, r in enumerate(raw_runs)]
    if any(s.task != "nav" for s in specs):
        raise ConfigError("poster Fig. 5 is about the navigation task", key="params.runs")
    runs = get_runs(ctx, specs)
    env = make_env("nav", variant=specs[0].variant, **env_kwargs(specs[0].env))
    lay = env.layout
    goal = params.get("goal", lay.goal_labels[-1])
    if goal not in lay.goal_labels:
        raise ConfigError(f"expected one of {lay.goal_labels}, got {goal!r}", key="params.goal")
    vstar = nav_optimal_q(lay).max(axis=1)
    goal_rows = np.concatenate([np.arange(lay.n_cells) + g * lay.n_cells
                                for g in lay.goal_labels])
    metrics: dict[str, Any] = {}
    tables, series = [], []
    for r in runs:
        q = r.q_observer if r.spec.observer else r.q
        learned = q.max(axis=2)[:, goal_rows]  # (seeds, states)
        v = np.broadcast_to(vstar[goal_rows], learned.shape)
        L = r.spec.label
        metrics[f"{L}_corr_vstar"] = _corr(learned.ravel(), v.ravel())
        metrics[f"{L}_mae_vstar"] = float(np.abs(learned - v).mean())
        metrics[f"{L}_visited"] = float((learned != 0).mean())
        metrics.update(curve_metrics(L, r.returns))
        legend = r.spec.legend or L
        tables.append((legend, q.max(axis=2).mean(axis=0)))
        series.append((legend, v.ravel(), learned.ravel()))
    figs = [plot_q_maps(lay, tables, int(goal), ctx.out / "qmaps.png",
                        title=f"max_a Q for {lay.room_names[int(goal)]} (mean of "
                              f"{specs[0].seeds} runs)"),
            plot_q_vs_vstar(series, ctx.out / "q_vs_vstar.png",
                            title=f"learned values vs V*(s), all goal rooms, {specs[0].seeds} runs")]
    notes = [_cache_note(runs), "Observers watch for the whole run (take-over at 100 %), so their "
             "Q tables hold only what the actor's exploration showed them."]
    return RunResult(metrics=metrics, figures=figs, notes=notes + param_notes(params))
