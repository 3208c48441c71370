"""Visit-the-lab training runs of ``simlab reproduce``: the run tables (parsing), the
seeds, and the shared run cache (see the package docstring)."""

from __future__ import annotations

import functools
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base import validation
from simlab.base.errors import ConfigError
from simlab.base.io import atomic_write
from simlab.experiments.context import RunContext
from simlab.orchestration.cache import Slot, StageCache
from simlab.visitlab import TASKS

#: First element of the spawn key of every Visit-the-lab stream ("VISL" in ASCII).
VISITLAB_SPAWN_KEY = 0x5649534C
_RUN_KEYS = {"label", "agent", "task", "variant", "env", "overrides", "observer", "takeover",
             "legend"}


def visitlab_seed(root_seed: int, stream: int = 0) -> int:
    """The integer seed of the Visit-the-lab runs (``stream`` 0) or of the combined
    task's evaluations (1) for the reproduction's root seed."""
    seq = np.random.SeedSequence(int(root_seed), spawn_key=(VISITLAB_SPAWN_KEY, int(stream)))
    return int(seq.generate_state(1, np.uint32)[0])


# --------------------------------------------------------------------------- settings


def as_table(v: Any, key: str) -> dict[str, Any]:
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
            return validation.whole(t[label], f"budget.{key}.{label}", minimum=1)
        if task in t:
            return validation.whole(t[task], f"budget.{key}.{task}", minimum=1)
        raise ConfigError(f"no trials for run {label!r} (task {task})", key=f"budget.{key}",
                          fix=f"add {label} = N or {task} = N")
    if t is None:
        raise ConfigError("missing", key=f"budget.{key}")
    return validation.whole(t, f"budget.{key}", minimum=1)


def parse_run(raw: Any, where: str, params: Mapping[str, Any], budget: Mapping[str, Any],
              *, trials_key: str = "trials", keep_model: bool = False) -> RunSpec:
    """A :class:`RunSpec` from a run table (``where`` names it in errors)."""
    from simlab.agents.registry import AGENTS

    run = as_table(raw, where)
    unknown = sorted(set(run) - _RUN_KEYS)
    if unknown:
        raise ConfigError(f"unknown key(s) {', '.join(unknown)}", key=where,
                          fix=f"allowed: {', '.join(sorted(_RUN_KEYS))}")
    agent = run.get("agent")
    if agent not in AGENTS:
        raise ConfigError(f"unknown agent {agent!r}", key=f"{where}.agent",
                          fix=f"use one of {', '.join(AGENTS)}")
    task = run.get("task", params.get("task"))
    validation.choice(task, TASKS, f"{where}.task")
    variant = validation.choice(run.get("variant", params.get("variant", "thesis")),
                                ("thesis", "paper"), f"{where}.variant")
    label = str(run.get("label", agent))
    if not label.replace("_", "").replace("-", "").isalnum():
        raise ConfigError(f"use letters, digits, '_' and '-', got {label!r}", key=f"{where}.label")
    env = {**as_table(params.get("env"), "params.env"), **as_table(run.get("env"), f"{where}.env")}
    observer = validation.boolean(run.get("observer", False), f"{where}.observer")
    return RunSpec(label=label.replace("-", "_"), agent=agent, task=task,
                   trials=_budget_trials(budget, label, task, trials_key),
                   seeds=validation.whole(budget["seeds"], "budget.seeds", minimum=1),
                   variant=variant, env=env,
                   overrides=as_table(run.get("overrides"), f"{where}.overrides"),
                   observer=observer,
                   takeover=validation.probability(run.get("takeover", 0.5), f"{where}.takeover"),
                   keep_model=keep_model, legend=str(run.get("legend", "")))


def param_notes(params: Mapping[str, Any]) -> list[str]:
    """``params.notes``: sentences the TOML adds to the result (e.g. why our simulation
    differs from the thesis), a list of strings."""
    raw = params.get("notes", [])
    if not isinstance(raw, list) or not all(isinstance(n, str) and n.strip() for n in raw):
        raise ConfigError(f"expected a list of sentences, got {raw!r}", key="params.notes")
    return [n.strip() for n in raw]


# --------------------------------------------------------------------------- shared runs




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
        """Seed ``i``'s kept model as :func:`~simlab.visitlab.fused.model_state` arrays."""
        with np.load(self.model_paths[i], allow_pickle=False) as data:
            return {k: data[k] for k in data.files}


def run_cache(ctx: RunContext) -> StageCache:
    """The shared cache of training runs, ``DIR/_cache/visitlab`` (scope
    ``"visitlab-run"``: keyed on the simulation, training loop and agent sources)."""
    return StageCache(ctx.cache / "visitlab", "visitlab-run")


def train_job(spec: dict[str, Any], seed: int, index: int) -> Any:
    """Seed ``index`` of the run ``spec`` (a :meth:`RunSpec.key` dict): a
    :class:`~simlab.visitlab.training.SeedRun` (module-level, for ``ctx.map``)."""
    from simlab.visitlab.fused import loop_agent_config
    from simlab.visitlab.passive import observer_run
    from simlab.visitlab.training import EnvSpec, run_seed, seed_generators

    gens = seed_generators(int(seed), int(spec["seeds"]))[int(index)]
    env = env_kwargs(spec["env"])
    if spec["observer"]:
        return observer_run(spec["task"], spec["agent"], int(spec["trials"]), gens,
                            takeover_fraction=float(spec["takeover"]), variant=spec["variant"],
                            actor_overrides=dict(spec["overrides"]), env_kwargs=env)
    cfg = loop_agent_config(spec["agent"], spec["task"], spec["variant"], dict(spec["overrides"]))
    return run_seed(EnvSpec(spec["task"], spec["variant"], dict(env)), cfg, int(spec["trials"]),
                    gens, keep_model=bool(spec["keep_model"]))


def _load_run(spec: RunSpec, d: Path, built: bool) -> RunData:
    with np.load(d / "runs.npz", allow_pickle=False) as data:
        returns = data["returns"]
        q = data["q"]
        q_obs = data["q_observer"] if "q_observer" in data.files else None
    models = tuple(d / f"model_{i}.npz" for i in range(spec.seeds)) if spec.keep_model else ()
    return RunData(spec, returns, q, q_obs, models, built, d)


#: Measured cost of one training step, microseconds, by (task, model-based agent): the
#: ``train_job`` of one seed of 400 trials (thesis variant, default env), after a warm-up
#: run, on the 2-core development machine (2026-11; q-learning for model-free, mb-egreedy
#: and rmax averaged for model-based). Only the ORDER of the jobs depends on it (longest
#: first, so that the last job to start is a short one); no result does, since every
#: result is stored by its job's index.
STEP_MICROSECONDS = {("nav", False): 0.7, ("nav", True): 1.7, ("gotohuman", False): 1.4,
                     ("gotohuman", True): 1.6, ("social", False): 1.5, ("social", True): 3.5}
#: The model-free agents (no model to update or plan on at each step).
MODEL_FREE = ("q-learning", "q-softmax")


def job_cost(spec: RunSpec) -> float:
    """Expected seconds of one seed of ``spec``: ``trials * steps per trial`` times the
    measured :data:`STEP_MICROSECONDS` of its task and agent kind (to start long jobs
    first). Decision: measured weights replace the earlier guessed ones (social 4, go-to-
    human 1.5, nav 1, model-based x3), which overstated the model-based agents."""
    per_step = STEP_MICROSECONDS[spec.task, spec.agent not in MODEL_FREE]
    return spec.trials * spec.steps * per_step * 1e-6


def get_runs(ctx: RunContext, specs: Sequence[RunSpec], desc: str = "training runs"
             ) -> list[RunData]:
    """The runs ``specs`` from the shared cache, building the missing ones (all their
    seeds in one ``ctx.map``, longest first)."""
    seed = visitlab_seed(ctx.root_seed)
    cache = run_cache(ctx)
    slots = [cache.slot("run", {"root_seed": int(ctx.root_seed), **spec.key()}) for spec in specs]
    found = {i: _load_run(spec, slot.path, False)
             for i, (spec, slot) in enumerate(zip(specs, slots, strict=True)) if slot.complete}
    todo: dict[Path, tuple[RunSpec, Slot]] = {}
    for i, (spec, slot) in enumerate(zip(specs, slots, strict=True)):
        if i not in found:
            todo.setdefault(slot.path, (spec, slot))
    if todo:
        jobs = sorted(((job_cost(spec), d, k) for d, (spec, _) in todo.items()
                       for k in range(spec.seeds)), key=lambda j: -j[0])
        t0 = time.perf_counter()
        results = ctx.map(train_job, [{"spec": todo[d][0].key(), "seed": seed, "index": k}
                                      for _, d, k in jobs], desc=f"{ctx.name}: {desc}")
        wall = time.perf_counter() - t0
        by_run: dict[Path, dict[int, Any]] = {}
        for (_, d, k), res in zip(jobs, results, strict=True):
            by_run.setdefault(d, {})[k] = res
        for d, (spec, slot) in todo.items():
            seeds = [by_run[d][k] for k in range(spec.seeds)]
            cache.store(slot, functools.partial(_write_run, spec=spec, seeds=seeds), wall)
        for i, slot in enumerate(slots):
            if i not in found:
                found[i] = _load_run(specs[i], slot.path, True)
        ctx.log(f"built {len(todo)} training run(s), {len(jobs)} seeds, in {wall:.0f} s")
    return [found[i] for i in range(len(specs))]


def _write_run(d: Path, spec: RunSpec, seeds: list[Any]) -> dict[str, Any]:
    """Write a run's arrays into its (empty) folder ``d``; returns the marker's summary
    (the steps of each seed; the wall time recorded is the whole batch's)."""
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
    return {"steps": [int(s.steps) for s in seeds]}


def cache_note(runs: Sequence[RunData]) -> str:
    built = sum(r.built for r in runs)
    reused = len(runs) - built
    parts = []
    if built:
        parts.append(f"{built} built")
    if reused:
        parts.append(f"{reused} reused from the shared cache")
    return f"Training runs: {', '.join(parts)} (DIR/_cache/visitlab)."


# --------------------------------------------------------------------------- curve metrics
