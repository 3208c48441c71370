"""Fused training loops: env step + agent update in one numba loop (thesis ch. 4).

The loops call the dynamics kernels of :mod:`simlab.visitlab.dynamics` and the
agent steps of :mod:`simlab.agents.core` (action selection, Q-learning, the sparse
count model and sliding-window model with Bellman backups and value iteration),
with the env's fixed inputs as one named record (``env.kernel_args()``); no Python
runs per step. Python calls a loop once per chunk of trials
(to drive a progress bar); the loop carries its step counter across chunks.

Agents are the registry's (:mod:`simlab.agents.registry`: ``q-learning``,
``q-softmax``, ``mb-egreedy``, ``vi-softmax``, ``rmax``, ``sliding-window``,
``passive-observer``) with their frozen configs; a loop step calls the agent core
(:func:`simlab.agents.core.learner_act` / :func:`~simlab.agents.core.learner_learn`
on a :class:`~simlab.agents.core.Learner` record) like the agent classes of
:mod:`simlab.agents.agents` do in ``act`` then ``update`` (same steps, same random
draws, same order — tested), so the fused loop and
``agent.fit(env)`` on the Gymnasium env give identical curves. On top of the
registry presets, :func:`loop_agent_config` applies the settings of a variant:

* both — Q starts at 0 for Q-learning and the model-based agents (the original
  implementation's choice; the registry's default is optimistic, pass
  ``{"q_init": None}`` to get it back); R-max keeps its optimistic start;
* ``thesis`` — model-based planning every 10,000 steps with at most 50 sweeps
  (thesis Fig. 4.1 caption);
* ``paper`` — Q-learning alpha 0.5, one value-iteration sweep every 1000 steps,
  R-max m = 5 on the social task (m = 1 otherwise), and the paper's planning
  rules of :mod:`simlab.agents.core` (as the code published with Chartouny et al. 2024
  applies them): the sweep is synchronous over all pairs
  (rule 2), untried pairs are valued through a uniform model (rule 1, model-based
  agents) and R-max freezes a pair's model at its m-th visit (rule 7). Without
  them (the registry's presets, the thesis variant) the sweep is in place over the
  visited pairs and untried pairs stay at 0: that agent learns 2-6 times slower
  than that published code on the social task (H1, 10k trials: ~0.9 against ~6 per
  20-step trial), so only the paper
  variant follows the paper's planning rules. Neither variant is compared
  side by side with the published code here: "like the paper" means the rules
  above, not verified identical curves.

then the caller's overrides (registry keys, ``"actor.plan_every"`` for nested ones).

Learning transitions cross the fixed-length trial boundary as time-outs: the last
transition of a trial bootstraps from its real next state (truncation is not
termination); the next trial starts from a reset state.

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
from numba import njit

from simlab.agents import core
from simlab.agents.config import (
    ModelBasedConfig,
    PassiveObserverConfig,
    QLearningConfig,
    RMaxConfig,
    SlidingWindowConfig,
    config_to_dict,
)
from simlab.agents.core import agent_params
from simlab.agents.kernels import count_model_new, rmax_q_init, window_model_new
from simlab.agents.registry import AGENTS, agent_config
from simlab.base import validation
from simlab.base.errors import ConfigError
from simlab.base.options import CommandConfig, command, option
from simlab.visitlab import TASKS
from simlab.visitlab import dynamics as dyn
from simlab.visitlab.curves import TrainResult
from simlab.visitlab.humans import human as preset_human
from simlab.visitlab.perception import P_SHARE


def loop_agent_config(name: str, task: str = "nav", variant: str = "thesis",
                      overrides: dict[str, Any] | None = None) -> Any:
    """Registry config of agent ``name`` with the variant settings, then ``overrides``.

    See the module docstring for the variant settings.
    """
    if name not in AGENTS:
        raise ConfigError(f"unknown agent {name!r}", key="agent",
                          fix=f"use one of {', '.join(AGENTS)}")
    preset = AGENTS[name].config
    changes: dict[str, Any] = {}
    prefix = "actor." if isinstance(preset, PassiveObserverConfig) else ""
    if isinstance(preset, QLearningConfig | ModelBasedConfig | PassiveObserverConfig):
        changes[f"{prefix}q_init"] = 0.0  # the original code starts from Q = 0
    if isinstance(preset, ModelBasedConfig | PassiveObserverConfig):
        if variant == "thesis":
            changes.update({f"{prefix}plan_every": 10_000, f"{prefix}max_sweeps": 50})
        else:  # "one VI sweep every 1000 steps"
            changes.update({f"{prefix}plan_every": 1000, f"{prefix}max_sweeps": 1})
    if variant == "paper":
        if isinstance(preset, QLearningConfig):
            changes["alpha"] = 0.5
        elif isinstance(preset, PassiveObserverConfig):
            changes["observer.alpha"] = 0.5
    if isinstance(preset, RMaxConfig) and variant == "paper" and task == "social":
        changes["m"] = 5
    if variant == "paper" and isinstance(preset, ModelBasedConfig | PassiveObserverConfig):
        # paper rules 1 and 2 (simlab.agents.core): untried pairs valued through a
        # uniform model, one synchronous sweep over all pairs
        changes.update({f"{prefix}synchronous": True, f"{prefix}untried_uniform": True})
    if variant == "paper" and isinstance(preset, RMaxConfig):
        changes.update({"synchronous": True, "freeze": True})  # paper rules 2 and 7
    changes.update(overrides or {})
    return agent_config(name, changes)


def make_learner(cfg: Any, n_states: int, n_actions: int, takeover_trial: int = -1
                 ) -> core.Learner:
    """The :class:`~simlab.agents.core.Learner` of an agent config for the fused loops.

    ``Q`` (S, A) float64 with the config's initial values (R-max: optimistic); the
    model a count or window model (a 1 x 1 stub for Q-learning); ``params`` the
    actor's :class:`~simlab.agents.core.AgentParams`. For the registry's
    ``passive-observer`` the observer's Q-learner is attached and acts from trial
    ``takeover_trial`` (-1: never); otherwise there is no observer.
    """
    actor = cfg.actor if isinstance(cfg, PassiveObserverConfig) else cfg
    if isinstance(actor, QLearningConfig):
        q = np.full((n_states, n_actions), actor.initial_value)
        model = count_model_new(1, 1, 1)
    elif isinstance(actor, RMaxConfig):
        q = rmax_q_init(n_states, n_actions, float(actor.r_max), float(actor.gamma))
        model = count_model_new(n_states, n_actions, actor.capacity)
    elif isinstance(actor, ModelBasedConfig):
        q = np.full((n_states, n_actions), actor.initial_value)
        if isinstance(actor, SlidingWindowConfig):
            cap = max(1, min(actor.capacity, n_states * n_actions))
            model = window_model_new(n_states, n_actions, actor.window, cap)
        else:
            model = count_model_new(n_states, n_actions, actor.capacity)
    else:
        raise ConfigError(f"unsupported agent config {type(cfg).__name__}", key="agent")
    params = agent_params(actor)
    lr = core.Learner(q, model, params, core.Observer(core.NO_OBSERVER_Q, params, -1))
    if isinstance(cfg, PassiveObserverConfig):
        lr = with_observer(lr, cfg.observer, takeover_trial)
    return lr


def with_observer(lr: core.Learner, observer: QLearningConfig, takeover_trial: int
                  ) -> core.Learner:
    """``lr`` watched by a passive Q-learner ``observer`` (its Q starts at the config's
    initial value, shape of ``lr.Q``), which acts from trial ``takeover_trial`` on
    (``-1``: never).

    Works for any acting agent (model-based, R-max, Q-learning): the fused loops update
    the observer on every transition the actor makes and, from the take-over on, let
    the observer act (its own selection rule) while the actor stops learning. The
    registry's ``passive-observer`` is this with an epsilon-greedy model-based actor;
    :mod:`simlab.visitlab.passive` uses it with R-max too.
    """
    if not isinstance(observer, QLearningConfig):
        raise ConfigError(f"expected a QLearningConfig, got {type(observer).__name__}",
                          key="observer")
    q_obs = np.full(lr.Q.shape, observer.initial_value)
    return lr._replace(observer=core.Observer(q_obs, agent_params(observer),
                                              int(takeover_trial)))


# --------------------------------------------------------------------------- kernels


@njit(cache=True)
def nav_train_chunk(env, lr, env_rng, agent_rng, t, trial0, returns):
    """Run ``len(returns)`` navigation trials (global index from ``trial0``) of
    :class:`~simlab.agents.core.Learner` ``lr`` on ``env``
    (:data:`~simlab.visitlab.envs.NavKernelArgs`), learning; fills ``returns``; returns
    the updated step counter ``t``."""
    n_cells = env.labels.shape[0]
    st = np.zeros(dyn.N_STATE, dtype=np.int64)
    for k in range(returns.shape[0]):
        trial = trial0 + k
        dyn.nav_reset(st, env_rng, n_cells, env.start_cell, env.goal_label, env.goal_labels)
        s = dyn.nav_obs(st, n_cells)
        total = 0.0
        for _ in range(env.max_steps):
            a = core.learner_act(lr, s, trial, core.NO_MASK, agent_rng)
            r = dyn.nav_step(env.walls_h, env.walls_v, env.labels, st, a)
            s_next = dyn.nav_obs(st, n_cells)
            t = core.learner_learn(lr, s, a, r, s_next, trial, core.NO_MASK, core.NO_TERMINAL,
                                   t)
            total += r
            s = s_next
        returns[k] = total
    return t


@njit(cache=True)
def social_train_chunk(env, lr, env_rng, agent_rng, t, trial0, returns):
    """Run ``len(returns)`` social trials on ``env``
    (:data:`~simlab.visitlab.envs.SocialKernelArgs`), learning; fills ``returns``;
    returns ``t``."""
    wh, wv, los, pcfg = env.walls_h, env.walls_v, env.los, env.pcfg
    n_cells = wv.shape[0] * wh.shape[1]
    st = np.zeros(dyn.N_STATE, dtype=np.int64)
    for k in range(returns.shape[0]):
        trial = trial0 + k
        dyn.social_reset(st, env_rng, n_cells, env.robot_start, env.human_start,
                         pcfg[P_SHARE] != 0)
        s = dyn.social_obs(wh, wv, los, pcfg, st)
        total = 0.0
        for _ in range(env.max_steps):
            a = core.learner_act(lr, s, trial, core.NO_MASK, agent_rng)
            r = dyn.social_step(wh, wv, los, pcfg, env.hp, env.redraw_p, st, a, env_rng)
            s_next = dyn.social_obs(wh, wv, los, pcfg, st)
            t = core.learner_learn(lr, s, a, r, s_next, trial, core.NO_MASK, core.NO_TERMINAL,
                                   t)
            total += r
            s = s_next
        returns[k] = total
    return t


@njit(cache=True)
def gth_train_chunk(env, lr, env_rng, agent_rng, t, trial0, returns):
    """Run ``len(returns)`` go-to-human trials on ``env``
    (:data:`~simlab.visitlab.envs.GthKernelArgs`), learning; fills ``returns``;
    returns ``t``."""
    wh, wv, los, pcfg = env.walls_h, env.walls_v, env.los, env.pcfg
    n_cells = wv.shape[0] * wh.shape[1]
    st = np.zeros(dyn.N_STATE, dtype=np.int64)
    for k in range(returns.shape[0]):
        trial = trial0 + k
        dyn.gth_reset(st, env_rng, n_cells, env.episode, env.robot_cell, env.human_cell,
                      env.robot_ori, env.human_ori, pcfg[P_SHARE] != 0)
        s = dyn.gth_obs(wh, wv, los, pcfg, st)
        total = 0.0
        for _ in range(env.max_steps):
            a = core.learner_act(lr, s, trial, core.NO_MASK, agent_rng)
            r = dyn.gth_step(wh, wv, los, pcfg, env.hp, env.human_moves, st, a, env_rng)
            s_next = dyn.gth_obs(wh, wv, los, pcfg, st)
            t = core.learner_learn(lr, s, a, r, s_next, trial, core.NO_MASK, core.NO_TERMINAL,
                                   t)
            total += r
            s = s_next
        returns[k] = total
    return t


# --------------------------------------------------------------------------- runner


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


def parse_value(text: str) -> Any:
    """The value a command-line word spells (``--set``, ``--start``, ``--goal``): ``none``
    / ``null`` -> None, ``true`` / ``false``, a whole or decimal number, else the text."""
    low = text.strip().lower()
    if low in ("none", "null"):
        return None
    if low in ("true", "false"):
        return low == "true"
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return text


def parse_overrides(items: Any) -> dict[str, Any]:
    """Agent overrides from ``KEY=VALUE`` words (``--set``, or a TOML list of them; values
    by :func:`parse_value`) or a table ``{key: value}`` (taken as is)."""
    if isinstance(items, dict):
        return dict(items)
    if not isinstance(items, list | tuple):
        raise ConfigError(f"expected a table or a list of KEY=VALUE, got {items!r}", key="--set")
    out: dict[str, Any] = {}
    for item in items:
        if not isinstance(item, str) or "=" not in item:
            raise ConfigError(f"expected KEY=VALUE, got {item!r}", key="--set")
        key, value = item.split("=", 1)
        out[key.strip()] = parse_value(value)
    return out


@dataclass(frozen=True, kw_only=True)
class VisitlabEnvOptions(CommandConfig):
    """The environment options of ``visitlab train`` and ``visitlab show`` (a field group:
    inherit it). :meth:`env_kwargs` turns them into the keyword arguments of
    :func:`make_env` / :func:`train`; options that do not apply to ``task`` are refused
    here, so a run never starts with an option it would ignore."""

    task: str = option("social", "module to run", choices=TASKS)
    variant: str = option("thesis", "thesis or paper settings", choices=("thesis", "paper"))
    human: str | None = option(
        None, "human preset(s), comma-separated: easy, medium, hard, H1, H2, H3 (social "
        "default: easy / H1; go-to-human default: a still human)")
    layout: str | None = option(
        None, "gridworld, gridworld-HxW, paper or lab (default: the task's)")
    layout_seed: int | None = option(None, "seed of a random lab layout")
    episode: str | None = option(
        None, "go-to-human episode variant (thesis Fig. 4.4; default random)",
        choices=("random", "fixed_positions", "fixed"))
    start: int | str | None = option(
        None, "navigation start: 'random' or a cell index (default: the variant's)", parse=str)
    goal: int | str | None = option(
        None, "navigation goal room: 'random' or a label (default: the variant's)", parse=str)
    steps: int | None = option(
        None, "steps per trial (default: thesis 50 nav / 40 others, paper 20)")
    seed: int = option(0, "root seed")

    def validate(self) -> None:
        validation.whole(self.seed, "seed")
        if self.steps is not None:
            validation.whole(self.steps, "steps", minimum=1)
        if self.episode is not None and self.task != "gotohuman":
            raise ConfigError("only the gotohuman task has episode variants", key="--episode")
        for key in ("start", "goal"):
            value = getattr(self, key)
            if value is not None and self.task != "nav":
                raise ConfigError("only the nav task has a start and a goal", key=f"--{key}")
            if isinstance(value, bool) or not isinstance(value, int | str | None):
                raise ConfigError(f"expected 'random', a number or a label, got {value!r}",
                                  key=key)
        if self.human is not None:
            if self.task == "nav":
                raise ConfigError("the navigation task has no human", key="--human")
            for name in self.humans():
                preset_human(name)  # an unknown preset is named before any run

    def humans(self) -> list[str | None]:
        """The human presets of ``human`` (``[None]``: the task's default)."""
        if self.human is None:
            return [None]
        return [h.strip() for h in self.human.split(",") if h.strip()]

    def env_kwargs(self, human: str | None = None) -> dict[str, Any]:
        """Keyword arguments of the env: the options given (``steps`` as ``max_steps``;
        ``start`` / ``goal`` words by :func:`parse_value`), and ``human`` when not None."""
        kw: dict[str, Any] = {}
        for key in ("layout", "layout_seed", "episode"):
            if getattr(self, key) is not None:
                kw[key] = getattr(self, key)
        for key in ("start", "goal"):
            value = getattr(self, key)
            if value is not None:
                kw[key] = parse_value(value) if isinstance(value, str) else value
        if self.steps is not None:
            kw["max_steps"] = self.steps
        if human is not None:
            kw["human"] = human
        return kw


@dataclass(frozen=True, kw_only=True)
class ShowConfig(VisitlabEnvOptions):
    """Options of ``simlab visitlab show``: one episode of :func:`make_env`'s env with a
    random policy, or greedy on a Q table of a ``visitlab train`` curves file."""

    COMMAND = "visitlab show"

    q: Path | None = option(None, "curves.npz from 'visitlab train': act greedily with its Q")
    run: int = option(0, "run index in the curves file")
    seed_index: int = option(0, "seeded run whose Q to use")
    png: Any | None = option(None, "also save the last frame as a PNG")
    overwrite: bool = option(False, "replace an existing --png")

    def validate(self) -> None:
        super().validate()
        validation.spelled_path(self.png, "png")


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
    task: str = "social",
    agent: str = "mb-egreedy",
    trials: int | None = None,
    seeds: int = 10,
    seed: int = 0,
    variant: str = "thesis",
    progress: bool = True,
    agent_overrides: dict[str, Any] | None = None,
    initial_q: np.ndarray | None = None,
    workers: int = 1,
    **env_kwargs: Any,
) -> TrainResult:
    """Train one agent on one Visit-the-lab task for ``seeds`` seeded runs.

    Args:
        task: ``"nav"``, ``"social"`` or ``"gotohuman"``.
        agent: a registry name (:data:`simlab.agents.registry.AGENTS`).
        trials: trials per run (default: thesis counts — nav 2000, social 40,000,
            go-to-human 2000).
        seeds: number of independent runs; ``seed`` the root of the SeedSequence.
        variant: ``"thesis"`` or ``"paper"`` (env and agent settings).
        agent_overrides: config fields to change (e.g. ``{"plan_every": 1000}``,
            ``{"q_init": 0.0}``, ``{"actor.epsilon": 0.1}``).
        initial_q: starting Q table, ``(S, A)`` for every seed or ``(seeds, S, A)``
            (e.g. continue learning with another human); the model starts empty.
        workers: processes running seeds in parallel (results do not depend on it).
        env_kwargs: passed to the env (e.g. ``human="medium"``, ``layout="lab"``,
            ``episode="fixed"``, ``max_steps=40``).

    ``simlab visitlab train`` (every agent and human of a :class:`VisitlabTrainConfig`,
    files written into its ``out``) is :func:`train_command`.
    """
    from simlab.base.guards import array_bytes, check_memory

    validation.choice(task, TASKS, "task")
    if trials is None:
        trials = {"nav": 2000, "social": 40_000, "gotohuman": 2000}[task]
    for key, value in (("trials", trials), ("seeds", seeds), ("workers", workers)):
        validation.whole(value, key, minimum=1)
    env = make_env(task, variant=variant, **env_kwargs)
    cfg = loop_agent_config(agent, task, variant, agent_overrides)
    n_states, n_actions = env.observation_space.n, env.action_space.n
    q0s = _initial_qs(initial_q, seeds, n_states, n_actions)
    check_memory(array_bytes((seeds, trials)) + array_bytes((seeds, n_states, n_actions)),
                 what=f"learning curves of {seeds} seeds x {trials} trials and their Q-tables",
                 key="trials", fix="fewer --trials or --seeds")
    spec = EnvSpec(task, variant, dict(env_kwargs))
    jobs = [(spec, cfg, trials, g, q0)
            for g, q0 in zip(seed_generators(seed, seeds), q0s, strict=True)]
    start = time.perf_counter()
    returns, qs = _run_seeds(jobs, (n_states, n_actions), workers,
                             progress and f"{task} {agent}")
    wall = time.perf_counter() - start
    human = getattr(env, "human", None)
    label = agent if human is None or task != "social" else f"{agent} / {human.name}"
    config = {
        "task": task,
        "variant": variant,
        "agent": agent,
        "agent_config": config_to_dict(cfg),
        "trials": int(trials),
        "seeds": int(seeds),
        "seed": int(seed),
        "max_steps": int(env.max_steps),
        "layout": env.layout.name,
        "human": None if human is None else asdict(human),
        "initial_q": initial_q is not None,
        "env_kwargs": {k: (v if isinstance(v, int | float | str | bool | type(None)) else repr(v))
                       for k, v in env_kwargs.items()},
    }
    return TrainResult(label, returns, qs, config, wall)


@dataclass(frozen=True, kw_only=True)
class VisitlabTrainConfig(VisitlabEnvOptions):
    """Options of ``simlab visitlab train`` / :func:`train_command`: every agent of
    ``agent`` with every human of ``human`` (comma-separated), trained by :func:`train`
    and saved together into ``out``. ``agent_overrides`` is ``--set KEY=VALUE``
    (repeatable, so the CLI module adds it): a TOML ``set`` / ``agent_overrides`` table,
    or a list of ``KEY=VALUE``."""

    COMMAND = "visitlab train"
    ARGUMENTS = ("task", "agent")

    agent: str = option(
        "mb-egreedy", "agent name(s), comma-separated: q-learning, q-softmax, mb-egreedy, "
        "vi-softmax, rmax, sliding-window, passive-observer")
    trials: int | None = option(
        None, "trials per seed (default: nav 2000, social 40000, gotohuman 2000)")
    seeds: int = option(10, "independent runs")
    agent_overrides: Any | None = option(
        None, "agent parameter overrides {key: value} (--set on the command line)",
        flag="set", cli=False)
    workers: int = option(1, "processes for the seeds")
    out: Path = option(help="output directory")
    title: str = option("", "plot title")
    overwrite: bool = option(False, "replace existing output files")
    progress: bool = option(True, "progress bar (--no-progress hides it)")

    def validate(self) -> None:
        super().validate()
        if self.trials is not None:
            validation.whole(self.trials, "trials", minimum=1)
        validation.whole(self.seeds, "seeds", minimum=1)
        validation.whole(self.workers, "workers", minimum=1)
        if self.agent_overrides is not None:
            object.__setattr__(self, "agent_overrides", parse_overrides(self.agent_overrides))
        if not self.agents():
            raise ConfigError("no agent named", key="agent")
        for name in self.agents():  # unknown agents and overrides named before any run
            loop_agent_config(name, self.task, self.variant, self.agent_overrides)

    def agents(self) -> list[str]:
        """The agent names of ``agent``."""
        return [a.strip() for a in self.agent.split(",") if a.strip()]


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
                res = train(cfg.task, agent, trials=cfg.trials, seeds=cfg.seeds, seed=cfg.seed,
                            variant=cfg.variant, progress=cfg.progress,
                            agent_overrides=dict(cfg.agent_overrides or {}),
                            workers=cfg.workers, **cfg.env_kwargs(human))
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
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        pool.shutdown(wait=True)
    return returns, qs


# --------------------------------------------------------------------------- one seed, observers, models


def model_state(model: Any) -> dict[str, np.ndarray]:
    """A count model as plain arrays (picklable, npz-ready): the observed triples
    ``s``, ``a``, ``s_next``, ``count`` (n,) int64 in the model's order, ``r_sum``
    (S, A) float64, and ``shape`` = (S, A). :func:`model_from_state` rebuilds it."""
    from simlab.agents.kernels import count_model_triples
    from simlab.agents.sparse_model import CountModel

    if not isinstance(model, CountModel):
        raise ConfigError(f"only count models can be carried over, got {type(model).__name__}",
                          key="model")
    ss, aa, nn, cc = count_model_triples(model)
    return {"s": ss, "a": aa, "s_next": nn, "count": cc, "r_sum": model.r_sum.copy(),
            "shape": np.array([model.n_states, model.n_actions], dtype=np.int64)}


def model_from_state(state: dict[str, np.ndarray]) -> Any:
    """The count model saved by :func:`model_state` (same counts, rewards and order)."""
    from simlab.agents.kernels import count_model_load

    n_states, n_actions = (int(x) for x in state["shape"])
    model = count_model_new(n_states, n_actions, max(1, len(state["s"])))
    count_model_load(model, *(np.ascontiguousarray(state[k], dtype=np.int64)
                              for k in ("s", "a", "s_next", "count")),
                     np.ascontiguousarray(state["r_sum"], dtype=np.float64))
    return model


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
