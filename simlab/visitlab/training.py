"""Fused training loops: env step + agent update in one numba loop (thesis ch. 4).

The loops call the dynamics kernels of :mod:`simlab.visitlab.dynamics` and the
agent kernels of :mod:`simlab.agents.kernels` (action selection, Q-learning, the
sparse count model and sliding-window model with Bellman backups and value
iteration); no Python runs per step. Python calls a loop once per chunk of trials
(to drive a progress bar); the loop carries the step counter across chunks.

Agents (:data:`AGENTS`, parameters in :class:`AgentSpec`; thesis defaults
gamma 0.9, alpha 0.7, epsilon 0.05, tau 0.1):

* ``mf-egreedy`` / ``mf-softmax`` — Q-learning (eq. 1.12).
* ``mb-egreedy`` / ``mb-vi-softmax`` — model-based on the count model (eq.
  1.13-1.14): after each step one Bellman backup at the visited pair, and value
  iteration (at most ``max_sweeps`` sweeps) every ``plan_every`` steps (thesis
  Fig. 4.1: 50 sweeps every 10,000 steps).
* ``rmax`` — R-max: Q starts at ``r_max / (1 - gamma)``, greedy selection, a pair is
  known after ``m_known`` visits (nav 1, social 5 as in the paper), value iteration
  (``replan_sweeps`` sweeps) the step a pair becomes known, plus periodic planning.
* ``mb-window-egreedy`` — as ``mb-egreedy`` on a sliding-window model of the last
  ``window`` outcomes per pair (for humans that change).

Learning transitions cross the fixed-length trial boundary as time-outs: the last
transition of a trial bootstraps from its real next state (truncation is not
termination); the next trial starts from a reset state.

Randomness: each seeded run draws two generators from
``SeedSequence(seed).spawn(n_seeds)[i].spawn(2)`` — the environment's and the
agent's — so identical seeds give identical curves and Q tables.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np
from numba import njit

from simlab.agents.kernels import (
    count_model_new,
    model_based_update,
    model_value_iteration,
    q_learning_update,
    rmax_q_init,
    select_action,
    window_model_new,
)
from simlab.errors import ConfigError
from simlab.visitlab import dynamics as dyn

TASKS = ("nav", "social", "gotohuman")
KINDS = ("mf", "mb", "rmax")
SELECTIONS = ("greedy", "egreedy", "softmax")

# indices into the agent parameter array handed to the loops
(A_KIND, A_SELECT, A_ALPHA, A_GAMMA, A_EPS, A_TAU, A_PLAN_EVERY, A_SWEEPS, A_TOL, A_M_KNOWN,
 A_INCREMENTAL, A_REPLAN_SWEEPS) = range(12)
_N_AP = 12
_KIND_MF, _KIND_MB, _KIND_RMAX = 0, 1, 2


@dataclass(frozen=True)
class AgentSpec:
    """A tabular agent for the fused loops.

    Attributes:
        name: label used in curves and summaries.
        kind: ``"mf"`` (Q-learning), ``"mb"`` (count/window model) or ``"rmax"``.
        selection: ``"greedy"``, ``"egreedy"`` or ``"softmax"`` (ties at random).
        alpha: Q-learning step size (mf only).
        gamma: discount factor in [0, 1).
        epsilon: exploration rate of epsilon-greedy.
        tau: softmax temperature (reward units).
        plan_every: steps between value-iteration runs (mb, rmax); 0 never.
        max_sweeps: sweeps per value-iteration run.
        tol: value iteration stops when no Q entry changes by more than this.
        m_known: visits before a pair's model is used (R-max's m; 1 otherwise).
        incremental: one Bellman backup at the visited pair after every step (mb, rmax).
        replan_sweeps: R-max: sweeps run the step a pair becomes known.
        window: > 0 uses a sliding-window model of the last ``window`` outcomes.
        r_max: R-max's optimistic reward bound (Q starts at ``r_max / (1 - gamma)``).
    """

    name: str = "mf-egreedy"
    kind: str = "mf"
    selection: str = "egreedy"
    alpha: float = 0.7
    gamma: float = 0.9
    epsilon: float = 0.05
    tau: float = 0.1
    plan_every: int = 10_000
    max_sweeps: int = 50
    tol: float = 1e-3
    m_known: int = 1
    incremental: bool = True
    replan_sweeps: int = 1
    window: int = 0
    r_max: float = 1.0

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ConfigError(f"expected one of {KINDS}, got {self.kind!r}", key="kind")
        if self.selection not in SELECTIONS:
            raise ConfigError(f"expected one of {SELECTIONS}, got {self.selection!r}",
                              key="selection")
        for key, lo, hi in (("alpha", 0.0, 1.0), ("epsilon", 0.0, 1.0)):
            v = getattr(self, key)
            if not lo <= v <= hi:
                raise ConfigError(f"expected a value in [{lo}, {hi}], got {v}", key=key)
        if not 0.0 <= self.gamma < 1.0:
            raise ConfigError(f"expected a value in [0, 1), got {self.gamma}", key="gamma")
        if self.tau < 0:
            raise ConfigError(f"expected tau >= 0, got {self.tau}", key="tau")
        for key in ("plan_every", "max_sweeps", "replan_sweeps", "window"):
            if int(getattr(self, key)) < 0:
                raise ConfigError(f"expected an integer >= 0, got {getattr(self, key)}", key=key)
        if self.m_known < 1:
            raise ConfigError(f"expected an integer >= 1, got {self.m_known}", key="m_known")

    def to_array(self) -> np.ndarray:
        """Parameters for the loops, float64 shape (12,) (see the ``A_*`` indices)."""
        ap = np.zeros(_N_AP, dtype=np.float64)
        ap[A_KIND] = KINDS.index(self.kind)
        ap[A_SELECT] = SELECTIONS.index(self.selection)
        ap[A_ALPHA] = self.alpha
        ap[A_GAMMA] = self.gamma
        ap[A_EPS] = self.epsilon
        ap[A_TAU] = self.tau
        ap[A_PLAN_EVERY] = self.plan_every
        ap[A_SWEEPS] = self.max_sweeps
        ap[A_TOL] = self.tol
        ap[A_M_KNOWN] = self.m_known
        ap[A_INCREMENTAL] = 1.0 if self.incremental else 0.0
        ap[A_REPLAN_SWEEPS] = self.replan_sweeps
        return ap

    def initial_q(self, n_states: int, n_actions: int) -> np.ndarray:
        """Initial Q table, shape ``(n_states, n_actions)``: zeros, optimistic for R-max."""
        if self.kind == "rmax":
            return rmax_q_init(n_states, n_actions, self.r_max, self.gamma)
        return np.zeros((n_states, n_actions), dtype=np.float64)

    def new_model(self, n_states: int, n_actions: int) -> Any:
        """The agent's (empty) model: a count or window model (a 1 x 1 stub for mf)."""
        if self.kind == "mf":
            return count_model_new(1, 1, 1)
        if self.window > 0:
            return window_model_new(n_states, n_actions, self.window, 1024)
        return count_model_new(n_states, n_actions, 4096)


AGENTS: dict[str, AgentSpec] = {
    "mf-egreedy": AgentSpec("mf-egreedy", "mf", "egreedy"),
    "mf-softmax": AgentSpec("mf-softmax", "mf", "softmax"),
    "mb-egreedy": AgentSpec("mb-egreedy", "mb", "egreedy"),
    "mb-vi-softmax": AgentSpec("mb-vi-softmax", "mb", "softmax"),
    "rmax": AgentSpec("rmax", "rmax", "greedy", plan_every=1000),
    "mb-window-egreedy": AgentSpec("mb-window-egreedy", "mb", "egreedy", window=20),
}


def agent_spec(name: str | AgentSpec, task: str = "nav", variant: str = "thesis",
               **overrides: Any) -> AgentSpec:
    """An agent by name with the task/variant defaults, then ``overrides`` applied.

    Paper variant: alpha 0.5 and planning every 1000 steps. R-max: m = 1 for
    navigation and go-to-human, m = 5 for the social task (paper); on the social
    task it relies on the periodic planning and the per-step backups
    (``replan_sweeps=0``) because a sweep per newly known pair costs too much there.
    """
    if isinstance(name, AgentSpec):
        spec = name
    else:
        if name not in AGENTS:
            raise ConfigError(f"unknown agent {name!r}", key="agent",
                              fix=f"use one of {', '.join(AGENTS)}")
        spec = AGENTS[name]
        changes: dict[str, Any] = {}
        if variant == "paper":
            changes.update(alpha=0.5, plan_every=1000)
        if spec.kind == "rmax":
            changes["m_known"] = 5 if task == "social" else 1
            if task == "social":  # a sweep per newly known pair is too costly on 76,800 pairs
                changes["replan_sweeps"] = 0
        spec = replace(spec, **changes)
    return replace(spec, **overrides) if overrides else spec


# --------------------------------------------------------------------------- kernels


@njit(cache=True)
def _act(Q, s, ap, rng):
    return select_action(Q[s], int(ap[A_SELECT]), ap[A_EPS], ap[A_TAU], rng)


@njit(cache=True)
def _learn(Q, model, ap, s, a, r, s_next, t):
    kind = int(ap[A_KIND])
    gamma = ap[A_GAMMA]
    if kind == _KIND_MF:
        q_learning_update(Q, s, a, r, s_next, ap[A_ALPHA], gamma)
        return
    m_known = int(ap[A_M_KNOWN])
    model_based_update(model, Q, s, a, r, s_next, gamma, m_known, ap[A_INCREMENTAL] > 0.0,
                       kind == _KIND_RMAX, int(ap[A_REPLAN_SWEEPS]), ap[A_TOL])
    plan_every = int(ap[A_PLAN_EVERY])
    if plan_every > 0 and t % plan_every == 0:
        model_value_iteration(model, Q, gamma, int(ap[A_SWEEPS]), ap[A_TOL], m_known)


@njit(cache=True)
def nav_train_chunk(walls_h, walls_v, labels, start_cell, goal_label, goal_labels, n_steps,
                    Q, model, ap, env_rng, agent_rng, t, returns):
    """Run ``len(returns)`` navigation trials, learning; fills ``returns``; returns ``t``."""
    n_cells = labels.shape[0]
    st = np.zeros(dyn.N_STATE, dtype=np.int64)
    for k in range(returns.shape[0]):
        dyn.nav_reset(st, env_rng, n_cells, start_cell, goal_label, goal_labels)
        s = dyn.nav_obs(st, n_cells)
        total = 0.0
        for _ in range(n_steps):
            a = _act(Q, s, ap, agent_rng)
            r = dyn.nav_step(walls_h, walls_v, labels, st, a)
            s_next = dyn.nav_obs(st, n_cells)
            t += 1
            _learn(Q, model, ap, s, a, r, s_next, t)
            total += r
            s = s_next
        returns[k] = total
    return t


@njit(cache=True)
def social_train_chunk(walls_h, walls_v, los, pcfg, hp, redraw_p, robot_start, human_start,
                       n_steps, Q, model, ap, env_rng, agent_rng, t, returns):
    """Run ``len(returns)`` social trials, learning; fills ``returns``; returns ``t``."""
    n_cells = walls_v.shape[0] * walls_h.shape[1]
    st = np.zeros(dyn.N_STATE, dtype=np.int64)
    for k in range(returns.shape[0]):
        dyn.social_reset(st, env_rng, n_cells, robot_start, human_start)
        s = dyn.social_obs(walls_h, walls_v, los, pcfg, st)
        total = 0.0
        for _ in range(n_steps):
            a = _act(Q, s, ap, agent_rng)
            r = dyn.social_step(walls_h, walls_v, los, pcfg, hp, redraw_p, st, a, env_rng)
            s_next = dyn.social_obs(walls_h, walls_v, los, pcfg, st)
            t += 1
            _learn(Q, model, ap, s, a, r, s_next, t)
            total += r
            s = s_next
        returns[k] = total
    return t


@njit(cache=True)
def gth_train_chunk(walls_h, walls_v, los, pcfg, hp, human_moves, episode, robot_cell, human_cell,
                    robot_ori, human_ori, n_steps, Q, model, ap, env_rng, agent_rng, t, returns):
    """Run ``len(returns)`` go-to-human trials, learning; fills ``returns``; returns ``t``."""
    n_cells = walls_v.shape[0] * walls_h.shape[1]
    st = np.zeros(dyn.N_STATE, dtype=np.int64)
    for k in range(returns.shape[0]):
        dyn.gth_reset(st, env_rng, n_cells, episode, robot_cell, human_cell, robot_ori, human_ori)
        s = dyn.gth_obs(walls_h, walls_v, los, pcfg, st)
        total = 0.0
        for _ in range(n_steps):
            a = _act(Q, s, ap, agent_rng)
            r = dyn.gth_step(walls_h, walls_v, los, pcfg, hp, human_moves, st, a, env_rng)
            s_next = dyn.gth_obs(walls_h, walls_v, los, pcfg, st)
            t += 1
            _learn(Q, model, ap, s, a, r, s_next, t)
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


class _Runner:
    """Binds one env configuration to its fused chunk kernel."""

    def __init__(self, env: Any, task: str) -> None:
        self.env = env
        self.task = task
        lay = env.layout
        self.n_states = env.observation_space.n
        self.n_actions = env.action_space.n
        if task == "nav":
            self.fixed = (lay.walls_h, lay.walls_v, lay.cell_labels, env.start_cell, env.goal_label,
                          np.array(lay.goal_labels, dtype=np.int64), env.max_steps)
            self.kernel = nav_train_chunk
        elif task == "social":
            self.fixed = (lay.walls_h, lay.walls_v, env._los, env._pcfg, env._hp, env.redraw_p,
                          env.robot_start, env.human_start, env.max_steps)
            self.kernel = social_train_chunk
        else:
            self.fixed = (lay.walls_h, lay.walls_v, env._los, env._pcfg, env._hp,
                          env.human is not None, env._episode_code, env.robot_cell, env.human_cell,
                          env.robot_ori, env.human_ori, env.max_steps)
            self.kernel = gth_train_chunk

    def run(self, Q, model, ap, env_rng, agent_rng, t, returns) -> int:
        return int(self.kernel(*self.fixed, Q, model, ap, env_rng, agent_rng, t, returns))


def seed_generators(seed: int, n_seeds: int) -> list[tuple[np.random.Generator, np.random.Generator]]:
    """``(env_rng, agent_rng)`` of each seeded run, from ``SeedSequence(seed)``."""
    out = []
    for child in np.random.SeedSequence(seed).spawn(n_seeds):
        env_ss, agent_ss = child.spawn(2)
        out.append((np.random.default_rng(env_ss), np.random.default_rng(agent_ss)))
    return out


@dataclass
class TrainResult:
    """Learning curves of one agent on one task configuration, over several seeds.

    Attributes:
        label: short name for legends (agent, and human for the social task).
        returns: reward per trial, float64 ``(n_seeds, n_trials)``.
        q: final Q table of each seed, float64 ``(n_seeds, n_states, n_actions)``.
        config: task, agent, env and seed settings (JSON-serialisable).
        wall_time_s: wall-clock seconds of training (all seeds), in seconds.
    """

    label: str
    returns: np.ndarray
    q: np.ndarray
    config: dict[str, Any] = field(default_factory=dict)
    wall_time_s: float = 0.0

    @property
    def n_trials(self) -> int:
        return int(self.returns.shape[1])

    def summary(self) -> dict[str, Any]:
        """Plateau (mean of the last 10 % of trials) and when the curve gets there."""
        return summarize_curve(self.returns) | {"label": self.label,
                                                "wall_time_s": round(self.wall_time_s, 2)}


def summarize_curve(returns: np.ndarray) -> dict[str, Any]:
    """Numbers for a report from ``returns`` ``(n_seeds, n_trials)``.

    ``plateau``: mean reward per trial over the last 10 % of trials (mean over seeds;
    ``plateau_std``: std across seeds). ``trials_to_90pct``: first trial at which the
    seed-averaged curve, smoothed over ``n_trials / 100`` trials, reaches 90 % of the
    plateau (None if it never does or the plateau is 0). ``first_bins``: smoothed
    values of the first 10 bins.
    """
    returns = np.asarray(returns, dtype=np.float64)
    n_seeds, n_trials = returns.shape
    tail = max(1, n_trials // 10)
    per_seed = returns[:, -tail:].mean(axis=1)
    plateau = float(per_seed.mean())
    x, mean, _ = smooth_curve(returns)
    reach = None
    if plateau > 0:
        hits = np.flatnonzero(mean >= 0.9 * plateau)
        reach = int(x[hits[0]]) if hits.size else None
    return {
        "n_seeds": int(n_seeds),
        "n_trials": int(n_trials),
        "plateau": round(plateau, 3),
        "plateau_std": round(float(per_seed.std()), 3),
        "trials_to_90pct": reach,
        "first_bins": [round(float(v), 2) for v in mean[:10]],
    }


def smooth_curve(returns: np.ndarray, n_points: int = 100) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Thesis Fig. 4.1 smoothing: ``n_points`` bins of ``n_trials / n_points`` trials.

    Returns ``(x, mean, std)``: x = last trial index (1-based) of each bin; mean and
    std over all seeds and all trials of the bin (std shows the within-window
    variability, as in the thesis).
    """
    returns = np.asarray(returns, dtype=np.float64)
    n_seeds, n_trials = returns.shape
    n_points = max(1, min(n_points, n_trials))
    window = n_trials // n_points
    used = window * n_points
    binned = returns[:, :used].reshape(n_seeds, n_points, window)
    mean = binned.mean(axis=(0, 2))
    std = binned.std(axis=(0, 2))
    x = (np.arange(n_points) + 1) * window
    return x, mean, std


def _run_seed(task: str, variant: str, env_kwargs: dict[str, Any], spec: AgentSpec,
              trials: int, gens: tuple[np.random.Generator, np.random.Generator],
              q0: np.ndarray | None, chunk: int, on_chunk: Any = None
              ) -> tuple[np.ndarray, np.ndarray]:
    """One seeded run: returns ``(returns (trials,), final Q (S, A))``."""
    env = make_env(task, variant=variant, **env_kwargs)
    runner = _Runner(env, task)
    env_rng, agent_rng = gens
    Q = (spec.initial_q(runner.n_states, runner.n_actions) if q0 is None
         else np.array(q0, dtype=np.float64, order="C"))
    model = spec.new_model(runner.n_states, runner.n_actions)
    ap = spec.to_array()
    returns = np.zeros(trials, dtype=np.float64)
    t = 0
    for lo in range(0, trials, chunk):
        hi = min(trials, lo + chunk)
        t = runner.run(Q, model, ap, env_rng, agent_rng, t, returns[lo:hi])
        if on_chunk is not None:
            on_chunk(hi - lo)
    return returns, Q


def train(
    task: str = "social",
    agent: str | AgentSpec = "mb-egreedy",
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
        agent: a name in :data:`AGENTS` or an :class:`AgentSpec`.
        trials: trials per run (default: thesis counts — nav 2000, social 40,000,
            go-to-human 2000).
        seeds: number of independent runs; ``seed`` the root of the SeedSequence.
        variant: ``"thesis"`` or ``"paper"`` (env and agent defaults).
        agent_overrides: AgentSpec fields to change (e.g. ``{"plan_every": 1000}``).
        initial_q: starting Q table, ``(S, A)`` for every seed or ``(seeds, S, A)``
            (e.g. continue learning with another human); the model starts empty.
        workers: processes running seeds in parallel (results do not depend on it).
        env_kwargs: passed to the env (e.g. ``human="medium"``, ``layout="lab"``,
            ``episode="fixed"``, ``max_steps=40``).
    """
    if task not in TASKS:
        raise ConfigError(f"expected one of {TASKS}, got {task!r}", key="task")
    if trials is None:
        trials = {"nav": 2000, "social": 40_000, "gotohuman": 2000}[task]
    for key, value in (("trials", trials), ("seeds", seeds), ("workers", workers)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
            raise ConfigError(f"expected an integer >= 1, got {value!r}", key=key)
    env = make_env(task, variant=variant, **env_kwargs)
    spec = agent_spec(agent, task, variant, **(agent_overrides or {}))
    n_states, n_actions = env.observation_space.n, env.action_space.n
    q0s: list[np.ndarray | None] = [None] * seeds
    if initial_q is not None:
        q = np.asarray(initial_q, dtype=np.float64)
        if q.shape == (n_states, n_actions):
            q0s = [q] * seeds
        elif q.shape == (seeds, n_states, n_actions):
            q0s = list(q)
        else:
            raise ConfigError(f"expected shape {(n_states, n_actions)} or "
                              f"{(seeds, n_states, n_actions)}, got {q.shape}", key="initial_q")
    chunk = max(1, min(trials, 200_000 // env.max_steps))
    gens = seed_generators(seed, seeds)
    returns = np.zeros((seeds, trials), dtype=np.float64)
    qs = np.zeros((seeds, n_states, n_actions), dtype=np.float64)
    start = time.perf_counter()
    from tqdm.auto import tqdm

    with tqdm(total=seeds * trials, disable=not progress, unit="trial",
              desc=f"{task} {spec.name}") as bar:
        if workers == 1 or seeds == 1:
            for i in range(seeds):
                returns[i], qs[i] = _run_seed(task, variant, env_kwargs, spec, trials, gens[i],
                                              q0s[i], chunk, bar.update)
        else:
            from concurrent.futures import ProcessPoolExecutor, as_completed

            with ProcessPoolExecutor(max_workers=min(workers, seeds)) as pool:
                futures = {pool.submit(_run_seed, task, variant, env_kwargs, spec, trials,
                                       gens[i], q0s[i], chunk): i for i in range(seeds)}
                for fut in as_completed(futures):
                    i = futures[fut]
                    returns[i], qs[i] = fut.result()
                    bar.update(trials)
    wall = time.perf_counter() - start
    human = getattr(env, "human", None)
    label = spec.name if human is None or task != "social" else f"{spec.name} / {human.name}"
    config = {
        "task": task,
        "variant": variant,
        "agent": asdict(spec),
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
