"""Training harness: run agents for ``runs`` seeds x ``episodes`` on a dense tabular MDP.

The task is one :class:`EpisodeTask`: the MDP ``T`` (S, A, S) (rows sum to 1), a reward
on arrival ``reward_next`` (S,) — for the empirical navigation task, 1.0 in the goal
area —, episodes of ``horizon`` steps starting in a state drawn from ``start`` (default
uniform; an int fixes the start state), and the constraints below. Every run of every
agent, and the evaluation, face the same task.

Seeding: ``seed`` (int or ``SeedSequence``) is spawned into one child per run;
each run's child is spawned again into an env stream and an agent stream. Same
seed, same results, bit for bit; runs are independent.

Constraints (masked actions and the episodic task of :mod:`simlab.training.train`),
fields of the :class:`EpisodeTask`:

* ``valid`` (S, A) bool, None = every action valid: agents draw only among the
  valid actions of a state and plan/bootstrap with maxima over valid actions (a
  state with none falls back to all); the evaluation's optimum and greedy policies
  use valid actions only. An all-True mask gives bit-identical results to None.
* ``terminal`` (S,) bool, None = no terminal state: arriving in a terminal state
  earns its ``reward_next``, then the episode ends early and the next starts from
  the start distribution; nothing is bootstrapped from a terminal state. The
  evaluation makes terminal states absorbing with no further reward.

Two execution paths give identical numbers (tested): ``fused=True`` runs the
compiled loops of :mod:`simlab.training.fused` on the agent's own arrays (the
default; millions of steps per second), ``fused=False`` calls the agent's
``act``/``update`` from Python (any :class:`~simlab.agents.agents.TabularAgent`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from simlab.agents import core
from simlab.agents import kernels as K
from simlab.agents.agents import (
    ModelBasedAgent,
    PassiveObserverAgent,
    QLearningAgent,
    RMaxAgent,
    TabularAgent,
)
from simlab.agents.config import config_to_dict
from simlab.agents.planning import (
    expected_return,
    greedy_policy,
    optimal_finite_horizon_return,
    reward_on_arrival,
    value_iteration,
)
from simlab.agents.registry import agent_config, make_agent
from simlab.base.errors import ConfigError
from simlab.training import fused

__all__ = [
    "GoalEvaluation",
    "TrainingResult",
    "evaluate_q",
    "run_episodes",
    "start_distribution",
    "train_runs",
]


def start_distribution(n_states: int, start: int | np.ndarray | None = None) -> np.ndarray:
    """(S,) start-state probabilities: uniform (``None``), one state (int), or given."""
    if start is None:
        return np.full(n_states, 1.0 / n_states)
    if isinstance(start, int | np.integer):
        if not 0 <= int(start) < n_states:
            raise ConfigError(f"expected a state in [0, {n_states}), got {start}", key="start")
        p = np.zeros(n_states)
        p[int(start)] = 1.0
        return p
    p = np.asarray(start, dtype=float)
    if p.shape != (n_states,) or np.any(p < 0) or not np.isclose(p.sum(), 1.0):
        raise ConfigError("expected an (S,) probability vector", key="start")
    return p


def _check_task(T: np.ndarray, reward_next: np.ndarray) -> None:
    if T.ndim != 3 or T.shape[0] != T.shape[2]:
        raise ConfigError(f"expected an (S, A, S) array, got {T.shape}", key="T")
    if reward_next.shape != (T.shape[0],):
        raise ConfigError(
            f"expected shape ({T.shape[0]},), got {reward_next.shape}", key="reward_next"
        )


def _takeover_episode(agent: TabularAgent, n_episodes: int, takeover: int | None) -> int:
    if not isinstance(agent, PassiveObserverAgent):
        return -1
    if agent.controlling == "observer":
        return 0
    if takeover is None:
        return round(agent.config.takeover_fraction * n_episodes)
    return int(takeover)


@dataclass(frozen=True, eq=False)
class EpisodeTask:
    """What the agents face: an MDP, its reward, the episodes and the constraints (see the
    module docstring).

    Attributes:
        T: (S, A, S) transition probabilities, rows summing to 1.
        reward_next: (S,) reward for arriving in each state.
        horizon: steps per episode (fewer when a terminal state is reached).
        start: the start state (int), an (S,) start distribution, or None (uniform).
        valid: (S, A) bool, the actions a state may take; None: every action.
        terminal: (S,) bool, the states that end an episode; None: none does.
    """

    T: np.ndarray
    reward_next: np.ndarray
    horizon: int = 50
    start: int | np.ndarray | None = None
    valid: np.ndarray | None = None
    terminal: np.ndarray | None = None


def run_episodes(
    agent: TabularAgent,
    task: EpisodeTask,
    n_episodes: int,
    env_rng: np.random.Generator,
    *,
    fused_loop: bool = True,
    takeover_episode: int | None = None,
) -> np.ndarray:
    """Train ``agent`` on ``task`` for ``n_episodes``; returns (n_episodes,) reward per
    episode.

    A :class:`~simlab.agents.agents.PassiveObserverAgent` hands control to its
    observer at ``takeover_episode`` (default: its config's
    ``takeover_fraction`` of ``n_episodes``). ``fused_loop=False`` uses the
    agent's Python methods (slow, any agent); both paths draw the same numbers.
    """
    T = np.asarray(task.T, dtype=np.float64)
    reward_next = np.asarray(task.reward_next, dtype=np.float64)
    _check_task(T, reward_next)
    cdf = np.cumsum(T, axis=2)
    start_cdf = np.cumsum(start_distribution(T.shape[0], task.start))
    takeover = _takeover_episode(agent, n_episodes, takeover_episode)
    S, A = T.shape[:2]
    agent.constrain(task.valid, task.terminal)
    compiled = fused.MdpTask(cdf, reward_next, start_cdf, int(task.horizon),
                             core.as_mask(task.valid, S, A), core.as_terminal(task.terminal, S))
    if fused_loop and isinstance(agent, _FUSABLE):
        return _run_fused(agent, compiled, n_episodes, takeover, env_rng)
    return _run_python(agent, compiled, n_episodes, takeover, env_rng)


_FUSABLE = (QLearningAgent, ModelBasedAgent, RMaxAgent, PassiveObserverAgent)


def _run_python(agent, task, n_episodes, takeover, env_rng):
    totals = np.zeros(n_episodes)
    ends = task.terminal.shape[0] > 0
    for ep in range(n_episodes):
        if ep == takeover:
            agent.take_over()
        s = int(K.sample_from_cdf(task.start_cdf, env_rng))
        total = 0.0
        for _ in range(task.horizon):
            a = agent.act(s)
            s_next = int(K.sample_from_cdf(task.cdf[s, a], env_rng))
            r = float(task.reward_next[s_next])
            agent.update(s, a, r, s_next)
            total += r
            s = s_next
            if ends and task.terminal[s]:
                break
        totals[ep] = total
        agent.end_episode()
    return totals


def _run_fused(agent, task, n_episodes, takeover, env_rng):
    if isinstance(agent, PassiveObserverAgent):
        actor, obs = agent.actor, agent.observer
        observer = fused.Observer(obs.Q, obs.params, int(takeover))
    else:
        actor = agent
        observer = fused.Observer(np.zeros((0, agent.n_actions)), agent.params, -1)
    model = getattr(actor, "model", core.NO_MODEL)
    steps0 = int(getattr(actor, "steps", 0))
    totals, steps = fused.run_loop(task, actor.Q, model, actor.params, observer,
                                   int(n_episodes), steps0, env_rng, agent.rng)
    if hasattr(actor, "steps"):
        actor.steps = int(steps)
    if isinstance(agent, PassiveObserverAgent) and 0 <= takeover < n_episodes:
        agent.take_over()
    return totals


@dataclass(frozen=True)
class GoalEvaluation:
    """Exact evaluation of learned Q-tables on the true MDP (expected ``horizon``-step returns)."""

    optimal_return: float
    """Return of the greedy policy of value iteration on the true MDP (same gamma)."""
    upper_bound: float
    """Best return of any (time-dependent) policy over the horizon."""
    greedy_returns: np.ndarray
    """(runs,) return of the greedy policy of each run's learned Q."""
    Q_star: np.ndarray
    """(S, A) optimal Q of the true MDP (value iteration, same gamma)."""


def evaluate_q(task: EpisodeTask, Q_runs: np.ndarray, gamma: float) -> GoalEvaluation:
    """Evaluate learned ``Q_runs`` (runs, S, A) against the optimum of ``task``'s true MDP
    (expected ``task.horizon``-step returns from its start distribution).

    ``task.valid`` / ``task.terminal``: see the module docstring (invalid actions are
    priced out of the optimum with a reward of -1e9; greedy policies pick valid actions).
    """
    T = np.array(task.T, dtype=np.float64)
    S, A = T.shape[:2]
    horizon = task.horizon
    mask = core.as_mask(task.valid, S, A)
    ends = core.as_terminal(task.terminal, S)
    if ends.size:
        T[ends] = 0.0
        for s in np.flatnonzero(ends):
            T[s, :, s] = 1.0
    R = reward_on_arrival(T, task.reward_next)
    if ends.size:
        R[ends] = 0.0
    if mask.size:
        mask = mask | ~mask.any(axis=1, keepdims=True)  # no valid action: all allowed
        R = np.where(mask, R, -1e9)
    p0 = start_distribution(S, task.start)
    Q_star, _, _ = value_iteration(T, R, gamma, tol=1e-10)
    optimal = expected_return(T, R, greedy_policy(Q_star), horizon, p0)
    bound = optimal_finite_horizon_return(T, R, horizon, p0)

    def masked(Q: np.ndarray) -> np.ndarray:
        return np.where(mask, Q, -np.inf) if mask.size else Q

    greedy = np.array([expected_return(T, R, greedy_policy(masked(Q)), horizon, p0)
                       for Q in Q_runs])
    return GoalEvaluation(optimal, bound, greedy, Q_star)


@dataclass(frozen=True)
class TrainingResult:
    """Outcome of :func:`train_runs` for one task."""

    agent: str
    """Registered agent name."""
    config: dict[str, Any]
    """The agent's hyper-parameters (JSON-ready)."""
    rewards: np.ndarray
    """(runs, episodes) total reward of every episode."""
    Q_runs: np.ndarray
    """(runs, S, A) final Q-table of every run (the observer's for a passive observer)."""
    gamma: float
    """Discount factor the agent used."""
    extra: dict[str, np.ndarray] = field(default_factory=dict)
    """Other per-run arrays (``actor_Q_runs`` for a passive observer)."""


def train_runs(
    task: EpisodeTask,
    agent: str = "vi-softmax",
    *,
    episodes: int = 2000,
    runs: int = 10,
    seed: int | np.random.SeedSequence = 0,
    overrides: dict[str, Any] | None = None,
    fused_loop: bool = True,
    on_run_done: Callable[[], None] | None = None,
) -> TrainingResult:
    """Train ``runs`` independent copies of ``agent`` on ``task`` for ``episodes`` each.

    ``overrides`` change the registered preset's hyper-parameters
    (``{"tau": 0.05}``). ``on_run_done`` is called after each run (progress bars).
    """
    horizon = task.horizon
    for name, value, low in (("episodes", episodes, 1), ("runs", runs, 1), ("horizon", horizon, 1)):
        if not (isinstance(value, int | np.integer) and value >= low):
            raise ConfigError(f"expected an integer >= {low}, got {value!r}", key=name)
    T = np.asarray(task.T, dtype=np.float64)
    _check_task(T, np.asarray(task.reward_next, dtype=np.float64))
    S, A = T.shape[:2]
    cfg = agent_config(agent, overrides)
    root = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    rewards = np.zeros((runs, episodes))
    Q_runs = np.zeros((runs, S, A))
    actor_Q = []
    for i, child in enumerate(root.spawn(runs)):
        env_seq, agent_seq = child.spawn(2)
        ag = make_agent(agent, S, A, np.random.default_rng(agent_seq), config=cfg)
        rewards[i] = run_episodes(ag, task, episodes, np.random.default_rng(env_seq),
                                  fused_loop=fused_loop)
        Q_runs[i] = ag.Q
        if isinstance(ag, PassiveObserverAgent):
            actor_Q.append(ag.actor.Q.copy())
        if on_run_done is not None:
            on_run_done()
    extra = {"actor_Q_runs": np.array(actor_Q)} if actor_Q else {}
    return TrainingResult(agent, config_to_dict(cfg), rewards, Q_runs, float(cfg.gamma), extra)
