"""Seeded Visit-the-lab training runs on the fused loops of :mod:`simlab.visitlab.fused`
(thesis ch. 4): :func:`train` (one agent, one task, ``seeds`` runs, here or on worker
processes), :func:`run_seed` (one run, the building block for callers with their own
workers) and ``simlab visitlab train`` (:func:`train_command`: every agent and human of a
:class:`~simlab.visitlab.options.VisitlabTrainConfig`, saved together).

The loops, the agents' variant settings (``thesis``, ``paper``) and the learner records
are :mod:`simlab.visitlab.fused`, the options :mod:`simlab.visitlab.options` (the names of
both are importable from here too); the files are :mod:`simlab.visitlab.results`.

Randomness: each seeded run draws two generators from
``SeedSequence(seed).spawn(n_seeds)[i].spawn(2)`` — the environment's and the
agent's — so identical seeds give identical curves and Q tables.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from simlab.agents import core
from simlab.agents.config import PassiveObserverConfig, QLearningConfig, config_to_dict
from simlab.base import validation
from simlab.base.errors import ConfigError
from simlab.base.options import command
from simlab.visitlab import TASKS
from simlab.visitlab.curves import TrainResult
from simlab.visitlab.fused import (
    gth_train_chunk,
    loop_agent_config,
    make_learner,
    model_from_state,
    model_state,
    nav_train_chunk,
    social_train_chunk,
    with_observer,
)
from simlab.visitlab.options import (
    ShowConfig,
    VisitlabEnvOptions,
    VisitlabTrainConfig,
    parse_overrides,
    parse_value,
)

__all__ = ["CHUNK_SECONDS", "EnvSpec", "ObserverSpec", "SeedRun", "ShowConfig", "TrainRuns",
           "VisitlabEnvOptions", "VisitlabTrainConfig", "gth_train_chunk", "loop_agent_config",
           "make_env", "make_learner", "model_from_state", "model_state", "nav_train_chunk",
           "parse_overrides", "parse_value", "run_seed", "seed_generators", "social_train_chunk",
           "train", "train_command", "with_observer"]


def make_env(task: str, **env_kwargs: Any):
    """The (unwrapped) Gymnasium env of a task: ``nav``, ``social`` or ``gotohuman``."""
    from simlab.visitlab.envs import GoToHumanEnv, NavEnv, SocialEnv

    classes = {"nav": NavEnv, "social": SocialEnv, "gotohuman": GoToHumanEnv}
    if task not in classes:
        raise ConfigError(f"expected one of {TASKS}, got {task!r}", key="task")
    return classes[task](**env_kwargs)


@dataclass(frozen=True)
class EnvSpec:
    """Which Visit-the-lab env a run trains on, as a picklable record (worker processes
    build their own env from it).

    Attributes:
        task: ``nav``, ``social`` or ``gotohuman``.
        variant: ``thesis`` or ``paper`` (see the module docstring).
        kwargs: the env's other keyword arguments (``human``, ``layout``, ``episode``,
            ``max_steps``, ...).
    """

    task: str
    variant: str = "thesis"
    kwargs: dict[str, Any] = field(default_factory=dict)

    def make(self):
        """The (unwrapped) env: :func:`make_env`."""
        return make_env(self.task, variant=self.variant, **self.kwargs)


@dataclass(frozen=True)
class ObserverSpec:
    """A passive Q-learner watching a run (:func:`with_observer`): its config and the
    share of the trials after which it takes control (1.0: it only watches)."""

    config: QLearningConfig
    takeover_fraction: float = 0.5


class _Runner:
    """Binds one env configuration to its fused chunk kernel."""

    def __init__(self, env: Any, task: str) -> None:
        self.env = env
        self.task = task
        self.n_states = env.observation_space.n
        self.n_actions = env.action_space.n
        self.fixed = env.kernel_args()
        self.kernel = {"nav": nav_train_chunk, "social": social_train_chunk,
                       "gotohuman": gth_train_chunk}[task]

    def run(self, lr: core.Learner, gens: tuple[np.random.Generator, np.random.Generator],
            t: int, trial0: int, returns: np.ndarray) -> int:
        """Run ``len(returns)`` trials from global trial ``trial0``; returns ``t``."""
        return int(self.kernel(self.fixed, lr, gens[0], gens[1], t, trial0, returns))


def seed_generators(seed: int, n_seeds: int) -> list[tuple[np.random.Generator, np.random.Generator]]:
    """``(env_rng, agent_rng)`` of each seeded run, from ``SeedSequence(seed)``."""
    out = []
    for child in np.random.SeedSequence(seed).spawn(n_seeds):
        env_ss, agent_ss = child.spawn(2)
        out.append((np.random.default_rng(env_ss), np.random.default_rng(agent_ss)))
    return out


def train(
    env: EnvSpec | str = "social",
    agent: str = "mb-egreedy",
    trials: int | None = None,
    seeds: int = 10,
    seed: int = 0,
    progress: bool = True,
    agent_overrides: dict[str, Any] | None = None,
    initial_q: np.ndarray | None = None,
    workers: int = 1,
    **env_kwargs: Any,
) -> TrainResult:
    """Train one agent on one Visit-the-lab task for ``seeds`` seeded runs.

    Args:
        env: the :class:`EnvSpec` trained on, or its task (``"nav"``, ``"social"`` or
            ``"gotohuman"``) with the rest of the record as ``env_kwargs``: ``variant``
            (``"thesis"`` or ``"paper"``: env and agent settings, default thesis) and the
            env's keyword arguments (e.g. ``human="medium"``, ``layout="lab"``,
            ``episode="fixed"``, ``max_steps=40``).
        agent: a registry name (:data:`simlab.agents.registry.AGENTS`).
        trials: trials per run (default: thesis counts — nav 2000, social 40,000,
            go-to-human 2000).
        seeds: number of independent runs; ``seed`` the root of the SeedSequence.
        agent_overrides: config fields to change (e.g. ``{"plan_every": 1000}``,
            ``{"q_init": 0.0}``, ``{"actor.epsilon": 0.1}``).
        initial_q: starting Q table, ``(S, A)`` for every seed or ``(seeds, S, A)``
            (e.g. continue learning with another human); the model starts empty.
        workers: processes running seeds in parallel (results do not depend on it).

    ``simlab visitlab train`` (every agent and human of a
    :class:`~simlab.visitlab.options.VisitlabTrainConfig`, files written into its ``out``)
    is :func:`train_command`.
    """
    from simlab.base.guards import array_bytes, check_memory

    spec = _env_spec(env, env_kwargs)
    task, variant = spec.task, spec.variant
    if trials is None:
        trials = {"nav": 2000, "social": 40_000, "gotohuman": 2000}[task]
    for key, value in (("trials", trials), ("seeds", seeds), ("workers", workers)):
        validation.whole(value, key, minimum=1)
    made = spec.make()
    cfg = loop_agent_config(agent, task, variant, agent_overrides)
    n_states, n_actions = made.observation_space.n, made.action_space.n
    q0s = _initial_qs(initial_q, seeds, n_states, n_actions)
    check_memory(array_bytes((seeds, trials)) + array_bytes((seeds, n_states, n_actions)),
                 what=f"learning curves of {seeds} seeds x {trials} trials and their Q-tables",
                 key="trials", fix="fewer --trials or --seeds")
    jobs = [(spec, cfg, trials, g, q0)
            for g, q0 in zip(seed_generators(seed, seeds), q0s, strict=True)]
    start = time.perf_counter()
    returns, qs = _run_seeds(jobs, (n_states, n_actions), workers,
                             progress and f"{task} {agent}")
    wall = time.perf_counter() - start
    human = getattr(made, "human", None)
    label = agent if human is None or task != "social" else f"{agent} / {human.name}"
    config = _run_config(spec, made, agent, cfg, trials, seeds, seed, initial_q is not None)
    return TrainResult(label, returns, qs, config, wall)


def _run_config(spec: EnvSpec, env: Any, agent: str, cfg: Any, trials: int, seeds: int,
                seed: int, initial_q: bool) -> dict[str, Any]:
    """The ``config`` record of a :class:`TrainResult`: the env (``spec`` and the env made
    from it), the agent and its config, the runs, whether Q started from a given table."""
    human = getattr(env, "human", None)
    return {
        "task": spec.task,
        "variant": spec.variant,
        "agent": agent,
        "agent_config": config_to_dict(cfg),
        "trials": int(trials),
        "seeds": int(seeds),
        "seed": int(seed),
        "max_steps": int(env.max_steps),
        "layout": env.layout.name,
        "human": None if human is None else asdict(human),
        "initial_q": initial_q,
        "env_kwargs": {k: (v if isinstance(v, int | float | str | bool | type(None)) else repr(v))
                       for k, v in spec.kwargs.items()},
    }


def _env_spec(env: EnvSpec | str, env_kwargs: dict[str, Any]) -> EnvSpec:
    """The :class:`EnvSpec` of :func:`train`'s ``env`` and ``env_kwargs`` (the task name
    spelling: ``variant`` and the env's arguments as keywords; none beside a record)."""
    if isinstance(env, EnvSpec):
        if env_kwargs:
            raise ConfigError(f"give the env's arguments {sorted(env_kwargs)} in the EnvSpec",
                              key="env_kwargs")
        validation.choice(env.task, TASKS, "task")
        return env
    kwargs = dict(env_kwargs)
    variant = kwargs.pop("variant", "thesis")
    validation.choice(env, TASKS, "task")
    return EnvSpec(env, variant, kwargs)


@dataclass(frozen=True)
class TrainRuns:
    """What :func:`train_command` did: one :class:`TrainResult` per (agent, human), in
    the order trained (agents outer), and the files written (``curves.npz``,
    ``curves.png``, ``summary.json`` in ``out``)."""

    results: tuple[TrainResult, ...]
    files: tuple[Path, ...]


@command(VisitlabTrainConfig, extras=("on_result",))
def train_command(cfg: VisitlabTrainConfig,
                  on_result: Callable[[TrainResult], None] | None = None) -> TrainRuns:
    """``simlab visitlab train``: :func:`train` for every agent and human of ``cfg`` (a
    :class:`VisitlabTrainConfig` or its fields), saved into ``cfg.out``. ``on_result``
    (not an option) is called with each result as it is done (the CLI prints it).

    One output transaction: refused before any training (a file in the way, a locked
    ``out``), written whole or not at all (a full disk, Ctrl-C).
    """
    from simlab.base.io import output_transaction
    from simlab.visitlab.results import FILES, save_results

    finals = tuple(cfg.out / name for name in FILES)
    with output_transaction(cfg.out, list(finals), overwrite=cfg.overwrite,
                            what="visitlab output") as txn:
        results = []
        for agent in cfg.agents():
            for human in cfg.humans():
                env = EnvSpec(cfg.task, cfg.variant, cfg.env_kwargs(human))
                res = train(env, agent, trials=cfg.trials, seeds=cfg.seeds, seed=cfg.seed,
                            progress=cfg.progress,
                            agent_overrides=dict(cfg.agent_overrides or {}),
                            workers=cfg.workers)
                results.append(res)
                if on_result is not None:
                    on_result(res)
        save_results(results, txn.staging, overwrite=True, title=cfg.title)
    return TrainRuns(tuple(results), finals)


def _initial_qs(initial_q: np.ndarray | None, seeds: int, n_states: int, n_actions: int
                ) -> list[np.ndarray | None]:
    """One starting Q-table per seed (None: the agent's own initial values)."""
    if initial_q is None:
        return [None] * seeds
    q = np.asarray(initial_q, dtype=np.float64)
    if q.shape == (n_states, n_actions):
        return [q] * seeds
    if q.shape == (seeds, n_states, n_actions):
        return list(q)
    raise ConfigError(f"expected shape {(n_states, n_actions)} or "
                      f"{(seeds, n_states, n_actions)}, got {q.shape}", key="initial_q")


def _run_seeds(jobs: list[tuple[Any, ...]], shape: tuple[int, int], workers: int,
               desc: str | bool) -> tuple[np.ndarray, np.ndarray]:
    """Each job's ``_seed_curve`` (in this process, or on ``workers`` processes of the one
    worker pool: results do not depend on it) -> returns (seeds, trials), Q (seeds, S, A)."""
    from tqdm.auto import tqdm

    seeds, trials = len(jobs), jobs[0][2]
    returns = np.zeros((seeds, trials), dtype=np.float64)
    qs = np.zeros((seeds, *shape), dtype=np.float64)
    with tqdm(total=seeds * trials, disable=not desc, unit="trial", desc=desc or None) as bar:
        if workers == 1 or seeds == 1:
            for i, job in enumerate(jobs):
                returns[i], qs[i] = _seed_curve(*job, bar.update)
            return returns, qs
        from concurrent.futures import as_completed

        from simlab.base.parallel import worker_pool

        # workers exit with this process; Ctrl-C cancels what has not started instead of
        # waiting for every seed to finish
        pool = worker_pool(min(workers, seeds))
        try:
            futures = {pool.submit(_seed_curve, *job): i for i, job in enumerate(jobs)}
            for fut in as_completed(futures):
                returns[futures[fut]], qs[futures[fut]] = fut.result()
                bar.update(trials)
        except BaseException:
            pool.stop_now()  # Ctrl-C: the seeds still running are not waited for
            raise
        pool.shutdown(wait=True)
    return returns, qs


# --------------------------------------------------------------------------- one seed


@dataclass(frozen=True, eq=False)
class SeedRun:
    """One seeded training run (:func:`run_seed`).

    Attributes:
        returns: reward per trial, float64 ``(trials,)``.
        q: the acting agent's final Q table ``(S, A)``.
        q_observer: the passive observer's final Q table ``(S, A)``, or None.
        model: the actor's count model as :func:`model_state` arrays (``keep_model``),
            or None.
        steps: steps counted by the actor's planning clock at the end.
    """

    returns: np.ndarray
    q: np.ndarray
    q_observer: np.ndarray | None = None
    model: dict[str, np.ndarray] | None = None
    steps: int = 0


def _seed_curve(env: EnvSpec, cfg: Any, trials: int,
                gens: tuple[np.random.Generator, np.random.Generator],
                q0: np.ndarray | None, on_chunk: Any = None) -> tuple[np.ndarray, np.ndarray]:
    """One seed of :func:`train`: ``(returns (trials,), final Q (S, A))`` (the observer's
    Q for a passive observer)."""
    run = run_seed(env, cfg, trials, gens, initial_q=q0, on_chunk=on_chunk)
    return run.returns, (run.q_observer if run.q_observer is not None else run.q)


#: Wall seconds one compiled chunk of trials aims at: Ctrl-C (a Python signal handler) is
#: seen only between chunks, and a progress bar moves once per chunk.
CHUNK_SECONDS = 0.25


def _next_chunk(done: int, seconds: float, most: int) -> int:
    """Trials of the next chunk: as many as take about :data:`CHUNK_SECONDS` at the pace of
    the last one (``done`` trials in ``seconds``), at most twice as many, at most ``most``.
    The chunking changes no result: the kernels carry the random generators and the step
    counter from chunk to chunk."""
    if seconds <= 0:
        return min(most, 2 * done)
    return max(1, min(most, 2 * done, int(done * CHUNK_SECONDS / seconds)))


def run_seed(env_spec: EnvSpec, cfg: Any, trials: int,
             gens: tuple[np.random.Generator, np.random.Generator], *,
             observer: ObserverSpec | None = None, initial_q: np.ndarray | None = None,
             keep_model: bool = False, on_chunk: Any = None) -> SeedRun:
    """One seeded run of agent config ``cfg`` (from :func:`loop_agent_config`) on the env
    of ``env_spec``.

    The building block of :func:`train` for callers that spread seeds over their own
    workers (``simlab reproduce``): with ``gens = seed_generators(seed, n)[i]`` it gives
    exactly seed ``i`` of ``train(..., seeds=n, seed=seed)``. ``observer`` adds a
    passive Q-learner (:func:`with_observer`) taking over after its
    ``takeover_fraction`` of the trials. ``initial_q`` starts the actor's Q (the
    observer's for the registry's ``passive-observer``); ``keep_model`` returns the
    actor's count model as arrays. ``on_chunk(n)`` is called after each chunk of ``n``
    trials (progress bars).
    """
    env = env_spec.make()
    runner = _Runner(env, env_spec.task)
    registry_observer = isinstance(cfg, PassiveObserverConfig)
    if registry_observer and observer is not None:
        raise ConfigError("the passive-observer agent already has an observer", key="observer")
    fraction = (cfg.takeover_fraction if registry_observer
                else 0.5 if observer is None else observer.takeover_fraction)
    if not 0.0 <= float(fraction) <= 1.0:
        raise ConfigError(f"expected a fraction in [0, 1], got {fraction!r}",
                          key="takeover_fraction")
    takeover = round(fraction * trials) if (registry_observer or observer is not None) else -1
    lr = make_learner(cfg, runner.n_states, runner.n_actions, takeover)
    if observer is not None:
        lr = with_observer(lr, observer.config, takeover)
    if initial_q is not None:
        target = lr.observer.Q if registry_observer else lr.Q
        target[...] = initial_q
    returns = np.zeros(trials, dtype=np.float64)
    t, lo = 0, 0
    most = max(1, 200_000 // env.max_steps)  # trials of the longest chunk
    chunk = max(1, min(most, 2_000 // env.max_steps))
    while lo < trials:
        hi = min(trials, lo + chunk)
        start = time.perf_counter()
        t = runner.run(lr, gens, t, lo, returns[lo:hi])
        if on_chunk is not None:
            on_chunk(hi - lo)
        chunk = _next_chunk(hi - lo, time.perf_counter() - start, most)
        lo = hi
    has_observer = registry_observer or observer is not None
    kept = None
    if keep_model:
        actor = cfg.actor if registry_observer else cfg
        if isinstance(actor, QLearningConfig):
            raise ConfigError("a Q-learner has no model to keep", key="keep_model")
        kept = model_state(lr.model)
    return SeedRun(returns, lr.Q, lr.observer.Q if has_observer else None, kept, int(t))
