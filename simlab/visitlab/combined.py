"""The combined Visit-the-lab architecture (thesis 3.1.1 and Fig. 3.1).

Three trained modules act together in one world: the robot must get the human's
attention and lead them to a goal room; when the human enters it, another room becomes
the goal. Every step:

1. **Required direction** (:func:`required_direction`). Row ``Q_nav[s_H]`` of the
   goal-conditioned navigation Q table at the *human's* cell for the current goal
   (``s_H = human_cell + goal * n_cells``) gives a value to each move 0-23; each is
   weighted by the speed coefficient of its speed, ``w = (w1, w2, w3)`` (thesis
   0.1, 0.1, 0.8; paper 1/3 each), and the weighted values are summed per direction
   (8 sums; STAY is ignored). The largest sum gives the required direction. The
   current one is kept while its sum stays among the best (within ``tie_tol``) so
   the robot is not sent back and forth between equally good directions; otherwise a
   best direction is drawn uniformly (ties broken at random, as everywhere in simlab).
2. **Social module** (thesis: it "governs the action selection"). Its observation is
   the social state of :mod:`simlab.visitlab.dynamics` (interaction level, distance
   class, required direction from step 1, angle); it picks an action 0-29 — greedily
   from its Q table, or with its own learning agent when it continues learning
   (:mod:`simlab.visitlab.adaptability`).
3. **Delegation of action 29.** If the social module picks GO_TO_HUMAN, the
   go-to-human module's greedy action ``argmax_a Q_G(s_G, a)`` (a move 0-24, ties at
   random) is executed in its place: one step of the option per decision, whatever
   the interaction level (the thesis's rule, Fig. 3.1). (In social *training*, action
   29 was the paper's simplification, a jump two cells ahead of the human's gaze.)
4. **World step**: exactly the social dynamics
   (:func:`simlab.visitlab.dynamics.social_step`) with the executed action and no
   random redraw of the required direction (it comes from navigation). The social
   reward (level 7 and the human moved in the required direction) is what a
   continuing social learner receives.
5. **Goal switch**: if the human's cell now lies in the goal room, one goal is
   counted and a new goal room is drawn uniformly among the *other* goal rooms. The
   required direction is then recomputed for the next step (so the next social
   observation already carries it).

A trial starts with robot and human on distinct uniformly random cells (or given
cells), random orientations, the human not engaged, and a goal drawn uniformly among
the goal rooms other than the human's. The metric is **goal rooms reached per trial**.
Trials have ``max_steps`` steps (default 100, twice the navigation trial: the thesis
does not give the length; long enough to lead a human through several rooms).

The modules must fit the world: the navigation table has ``n_labels * n_cells`` rows
on the combined world's layout (train it there with random starts and goals); the
social table ``(2560, 30)``; the go-to-human table ``(320, 25)``.

Everything per step runs in one numba loop (:func:`combined_chunk`), which also serves
the continued learning of the adaptability study and the episode recorder
(:func:`record_episodes`, :func:`write_episode_gif`: the thesis's Section 4.4
sequence, the robot approaching, HELLO, COME, leading, the goal changing).

Note for developers: :func:`combined_chunk` is compiled with ``cache=True`` and calls
the kernels of :mod:`simlab.visitlab.dynamics` and the agent steps of
:mod:`simlab.agents.core`; numba does not track dependencies between files, so simlab
keeps one numba cache directory per version of its source (:mod:`simlab.base._numba_cache`).
"""

from __future__ import annotations

import math
import os
from collections import namedtuple
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

from simlab.agents import core
from simlab.agents.kernels import greedy_action
from simlab.base import validation
from simlab.base.errors import ConfigError
from simlab.base.options import CommandConfig, option
from simlab.visitlab import dynamics as dyn
from simlab.visitlab.actions import ACTION_DIR, ACTION_SPEED, Action
from simlab.visitlab.grid import Layout, make_layout
from simlab.visitlab.humans import Human
from simlab.visitlab.humans import human as get_human
from simlab.visitlab.perception import Perception, perception_for

#: Thesis speed coefficients w = (p1, p2, p3) (Section 3.1.1).
THESIS_SPEED_WEIGHTS = (0.1, 0.1, 0.8)
#: The paper's speed coefficients (1/3 each).
PAPER_SPEED_WEIGHTS = (1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0)

# columns of an episode record (one row per step, see record_episode)
_GO_TO_HUMAN = 29

#: What :func:`combined_chunk` needs of a world and its frozen modules
#: (:meth:`CombinedTask.kernel_args`): walls, ``los`` table, ``labels`` (n_cells,) room
#: per cell, ``goal_labels`` (int64), ``pcfg`` perception array, ``hp`` human array,
#: ``nav_q`` / ``gth_q`` the frozen modules, ``weights`` (3,) speed coefficients,
#: ``tie_tol``, ``robot_start`` / ``human_start`` (-1: random), ``max_steps``.
CombinedKernelArgs = namedtuple("CombinedKernelArgs", [
    "walls_h", "walls_v", "los", "labels", "goal_labels", "pcfg", "hp", "nav_q", "gth_q",
    "weights", "tie_tol", "robot_start", "human_start", "max_steps"])
#: Outputs of :func:`combined_chunk`, one entry per trial: ``goals`` (goal rooms reached)
#: and ``rewards`` (social reward) float64 ``(n_trials,)``, and ``record`` (see there).
CombinedOut = namedtuple("CombinedOut", ["goals", "rewards", "record"])


# --------------------------------------------------------------------------- kernels


@njit(cache=True)
def direction_values(q_row: np.ndarray, weights: np.ndarray, out: np.ndarray) -> np.ndarray:
    """Weighted sum per direction: ``out[d] = sum_k w[k-1] * q_row[move(d, k)]``.

    ``q_row`` (>= 24,) navigation Q values of moves 0-23 (STAY and beyond ignored),
    ``weights`` (3,) speed coefficients, ``out`` (8,) written and returned.
    """
    for d in range(8):
        out[d] = 0.0
    for a in range(24):
        out[ACTION_DIR[a]] += weights[ACTION_SPEED[a] - 1] * q_row[a]
    return out


@njit(cache=True)
def required_direction(q_row: np.ndarray, weights: np.ndarray, current: int, tie_tol: float,
                       rng: np.random.Generator) -> int:
    """The required direction 0-7 for navigation Q row ``q_row`` (module docstring, 1).

    ``current`` (-1: none) is kept while its weighted sum is within ``tie_tol`` of the
    best; otherwise one of the best directions is drawn uniformly with ``rng`` (a draw
    only when several are best).
    """
    vals = np.empty(8, dtype=np.float64)
    direction_values(q_row, weights, vals)
    best = vals[0]
    for d in range(1, 8):
        if vals[d] > best:
            best = vals[d]
    if current >= 0 and vals[current] >= best - tie_tol:
        return current
    n_best = 0
    for d in range(8):
        if vals[d] >= best - tie_tol:
            n_best += 1
    k = 0 if n_best == 1 else rng.integers(0, n_best)
    for d in range(8):
        if vals[d] >= best - tie_tol:
            if k == 0:
                return d
            k -= 1
    return 0  # unreachable


@njit(cache=True)
def next_goal(goal_labels: np.ndarray, exclude: int, rng: np.random.Generator) -> int:
    """A goal label drawn uniformly among ``goal_labels`` other than ``exclude``
    (all of them if ``exclude`` is not one; the only one if there is a single goal)."""
    n = goal_labels.shape[0]
    n_other = 0
    for i in range(n):
        if goal_labels[i] != exclude:
            n_other += 1
    if n_other == 0:
        return goal_labels[0]
    k = rng.integers(0, n_other)
    for i in range(n):
        if goal_labels[i] != exclude:
            if k == 0:
                return goal_labels[i]
            k -= 1
    return goal_labels[0]  # unreachable


@njit(cache=True)
def combined_reset(world, st: np.ndarray, rng: np.random.Generator) -> None:
    """New combined trial in ``world`` (:data:`CombinedKernelArgs`; module docstring):
    positions ``world.robot_start`` / ``world.human_start`` (``-1`` = random), random
    orientations, human not engaged, a goal other than the human's room, and the
    required direction for it."""
    labels = world.labels
    n_cells = labels.shape[0]
    dyn.place_two_agents(st, rng, n_cells, world.robot_start, world.human_start)
    st[dyn.S_ROBOT_ORI] = rng.integers(0, 8)
    st[dyn.S_HUMAN_ORI] = rng.integers(0, 8)
    st[dyn.S_ENGAGED] = 0
    st[dyn.S_HUMAN_MOVE] = -1
    st[dyn.S_GOAL] = next_goal(world.goal_labels, labels[st[dyn.S_HUMAN]], rng)
    row = world.nav_q[st[dyn.S_HUMAN] + st[dyn.S_GOAL] * n_cells]
    st[dyn.S_REQ_DIR] = required_direction(row, world.weights, -1, world.tie_tol, rng)


@njit(cache=True)
def combined_step(world, st: np.ndarray, action: int, rng: np.random.Generator
                  ) -> tuple[float, int, bool]:
    """One combined step in ``world`` (:data:`CombinedKernelArgs`) for the social module's
    ``action`` (0-29); updates ``st``.

    Returns ``(social_reward, executed_action, goal_reached)`` (module docstring, 3-5).
    """
    wh, wv, los, pcfg, labels = world.walls_h, world.walls_v, world.los, world.pcfg, world.labels
    n_cells = labels.shape[0]
    executed = action
    if action == _GO_TO_HUMAN:
        g = dyn.gth_obs(wh, wv, los, pcfg, st)
        executed = greedy_action(world.gth_q[g], rng)
    reward = dyn.social_step(wh, wv, los, pcfg, world.hp, 0.0, st, executed, rng)
    reached = labels[st[dyn.S_HUMAN]] == st[dyn.S_GOAL]
    if reached:
        st[dyn.S_GOAL] = next_goal(world.goal_labels, st[dyn.S_GOAL], rng)
    row = world.nav_q[st[dyn.S_HUMAN] + st[dyn.S_GOAL] * n_cells]
    st[dyn.S_REQ_DIR] = required_direction(row, world.weights, st[dyn.S_REQ_DIR],
                                           world.tie_tol, rng)
    return reward, executed, reached


@njit(cache=True)
def combined_chunk(world, lr, learn, env_rng, agent_rng, t, trial0, out):
    """Run ``len(out.goals)`` combined trials (global index from ``trial0``) in ``world``
    (:data:`CombinedKernelArgs`).

    The social module is :class:`~simlab.agents.core.Learner` ``lr`` (greedy params for
    a frozen module); it learns from its social reward when ``learn``. Fills ``out``
    (:data:`CombinedOut`): ``goals`` and ``rewards`` per trial; ``record``
    ``(n_trials * (max_steps + 1), N_STATE + 4)`` int64, or ``(0, 0)``: per step the
    world state before the step and ``action, executed, reward, goal reached`` (a last
    row per trial holds the final state). Returns the step counter.
    """
    w = world
    record = out.record
    st = np.zeros(dyn.N_STATE, dtype=np.int64)
    nst = dyn.N_STATE
    row_i = 0
    for k in range(out.goals.shape[0]):
        trial = trial0 + k
        combined_reset(w, st, env_rng)
        s = dyn.social_obs(w.walls_h, w.walls_v, w.los, w.pcfg, st)
        n_goals = 0
        total = 0.0
        for _ in range(w.max_steps):
            a = core.learner_act(lr, s, trial, core.NO_MASK, agent_rng)
            if record.shape[0] > 0:
                record[row_i, :nst] = st
                record[row_i, nst] = a
            r, executed, reached = combined_step(w, st, a, env_rng)
            if record.shape[0] > 0:
                record[row_i, nst + 1] = executed
                record[row_i, nst + 2] = int(r)
                record[row_i, nst + 3] = 1 if reached else 0
                row_i += 1
            s_next = dyn.social_obs(w.walls_h, w.walls_v, w.los, w.pcfg, st)
            if learn:
                t = core.learner_learn(lr, s, a, r, s_next, trial, core.NO_MASK,
                                       core.NO_TERMINAL, t)
            if reached:
                n_goals += 1
            total += r
            s = s_next
        if record.shape[0] > 0:
            record[row_i, :nst] = st
            record[row_i, nst:] = -1
            row_i += 1
        out.goals[k] = n_goals
        out.rewards[k] = total
    return t


# --------------------------------------------------------------------------- Python API


def _check_weights(weights: Any) -> tuple[float, float, float]:
    try:
        w = tuple(float(x) for x in weights)
    except (TypeError, ValueError):
        raise ConfigError(f"expected three numbers, got {weights!r}", key="speed_weights") from None
    if len(w) != 3 or any(not math.isfinite(x) or x < 0 for x in w) or sum(w) <= 0:
        raise ConfigError(f"expected three non-negative numbers, not all 0, got {weights!r}",
                          key="speed_weights")
    return w  # type: ignore[return-value]


@dataclass(frozen=True, kw_only=True)
class CombinedConfig(CommandConfig):
    """Options of ``simlab visitlab combined``: a :class:`CombinedTask` run by
    :func:`evaluate` with the three trained Q tables of ``visitlab train`` curves files
    (:class:`Modules`), optionally one episode as a GIF (:func:`write_episode_gif`)."""

    COMMAND = "visitlab combined"

    nav: Path = option(help="curves.npz of the goal-conditioned navigation (random start "
                       "and goal) module ('visitlab train')", metavar="CURVES")
    social: Path = option(help="curves.npz of the social module ('visitlab train')",
                          metavar="CURVES")
    gotohuman: Path = option(help="curves.npz of the go-to-human module ('visitlab train')",
                             metavar="CURVES")
    run: int = option(0, "run index in each curves file")
    seed_index: int = option(0, "seeded run whose Q tables to use")
    human: str | None = option(
        None, "human preset (default: the social module's training human)")
    layout: str = option("gridworld", "the world (the navigation module's)")
    steps: int = option(100, "steps per trial")
    weights: Any = option("0.1,0.1,0.8", "speed coefficients w1,w2,w3 (thesis 0.1,0.1,0.8; "
                          "paper 1/3 each)", parse=str)
    trials: int = option(100, "trials")
    seed: int = option(0, "seed")
    gif: Any | None = option(
        None, "write the first trial with two goals or more (else the best) as a GIF")
    overwrite: bool = option(False, "replace an existing GIF")

    def validate(self) -> None:
        validation.whole(self.run, "run")
        validation.whole(self.seed_index, "seed_index")
        validation.whole(self.steps, "steps", minimum=1)
        validation.whole(self.trials, "trials", minimum=1)
        validation.whole(self.seed, "seed")
        self.speed_weights()
        validation.spelled_path(self.gif, "gif")

    def speed_weights(self) -> tuple[float, ...]:
        """``weights`` as numbers (a ``w1,w2,w3`` text or a list of numbers)."""
        words = self.weights.split(",") if isinstance(self.weights, str) else self.weights
        try:
            return tuple(float(x) for x in words)
        except (TypeError, ValueError):
            raise ConfigError(f"expected three numbers, got {self.weights!r}",
                              key="--weights") from None


@dataclass(frozen=True, eq=False)
class CombinedTask:
    """The world of the combined architecture and its settings.

    Attributes:
        layout: the world (a :class:`Layout` or a name for
            :func:`~simlab.visitlab.grid.make_layout`; default the thesis's 24 x 24
            gridworld with nine 8 x 8 rooms, the navigation module's world).
        human: the human (preset name or :class:`Human`).
        perception: distance classes and fields of view (default: thesis, Manhattan).
        speed_weights: speed coefficients (w1, w2, w3) of the required direction.
        max_steps: steps per trial.
        robot_start, human_start: cells (``-1``: uniformly random each trial).
        tie_tol: directions whose weighted sums are within this of the best are tied.
    """

    layout: Layout | str = "gridworld"
    human: Human | str = "easy"
    perception: Perception | None = None
    speed_weights: tuple[float, float, float] = THESIS_SPEED_WEIGHTS
    max_steps: int = 100
    robot_start: int = -1
    human_start: int = -1
    tie_tol: float = 1e-9

    def __post_init__(self) -> None:
        object.__setattr__(self, "layout", make_layout(self.layout))
        object.__setattr__(self, "human", get_human(self.human))
        if self.perception is None:
            object.__setattr__(self, "perception", perception_for("thesis"))
        object.__setattr__(self, "speed_weights", _check_weights(self.speed_weights))
        if (isinstance(self.max_steps, bool) or not isinstance(self.max_steps, int | np.integer)
                or self.max_steps < 1):
            raise ConfigError(f"expected an integer >= 1, got {self.max_steps!r}",
                              key="max_steps")
        n = self.layout.n_cells
        for key in ("robot_start", "human_start"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or not -1 <= v < n:
                raise ConfigError(f"expected -1 (random) or a cell in 0..{n - 1}, got {v!r}",
                                  key=key)
        if self.robot_start >= 0 and self.robot_start == self.human_start:
            raise ConfigError("robot and human cannot start on the same cell", key="robot_start")
        if not (isinstance(self.tie_tol, int | float) and self.tie_tol >= 0):
            raise ConfigError(f"expected a number >= 0, got {self.tie_tol!r}", key="tie_tol")

    def with_human(self, human: Human | str) -> CombinedTask:
        """The same task with another human."""
        return CombinedTask(self.layout, human, self.perception, self.speed_weights,
                            self.max_steps, self.robot_start, self.human_start, self.tie_tol)

    def check_modules(self, modules: Modules) -> None:
        """Raise :class:`ConfigError` if the Q tables do not fit this world."""
        lay = self.layout
        want = {"nav_q": (lay.n_labels * lay.n_cells, 25), "social_q": (dyn.N_SOCIAL_STATES, 30),
                "gth_q": (dyn.N_GTH_STATES, 25)}
        for key, shape in want.items():
            got = getattr(modules, key).shape
            if got != shape:
                raise ConfigError(f"expected shape {shape} for the {lay.name} world, got {got}",
                                  key=key, fix="train the navigation module on this layout"
                                  if key == "nav_q" else None)

    def kernel_args(self, modules: Modules) -> CombinedKernelArgs:
        """The world argument of :func:`combined_chunk` for ``modules``."""
        lay = self.layout
        return CombinedKernelArgs(lay.walls_h, lay.walls_v, lay.los_table(), lay.cell_labels,
                np.array(lay.goal_labels, dtype=np.int64), self.perception.to_array(),
                self.human.to_array(), modules.nav_q, modules.gth_q,
                np.array(self.speed_weights, dtype=np.float64), float(self.tie_tol),
                int(self.robot_start), int(self.human_start), int(self.max_steps))


@dataclass(frozen=True, eq=False)
class Modules:
    """The three trained Q tables (float64, C-contiguous copies).

    Attributes:
        nav_q: goal-conditioned navigation ``(n_labels * n_cells, 25)``.
        social_q: social module ``(2560, 30)``.
        gth_q: go-to-human module ``(320, 25)``.
    """

    nav_q: np.ndarray
    social_q: np.ndarray
    gth_q: np.ndarray

    def __post_init__(self) -> None:
        for key in ("nav_q", "social_q", "gth_q"):
            q = np.ascontiguousarray(getattr(self, key), dtype=np.float64)
            if q.ndim != 2 or not np.isfinite(q).all():
                raise ConfigError(f"expected a finite 2-D Q table, got shape {q.shape}", key=key)
            object.__setattr__(self, key, q)


def frozen_learner(social_q: np.ndarray, epsilon: float = 0.0) -> core.Learner:
    """A frozen social module acting on ``social_q`` (not copied): greedy (ties at
    random) for ``epsilon`` 0, else epsilon-greedy (``epsilon`` 1: uniformly random
    actions, the chance baseline). It never learns (call :func:`combined_chunk` with
    ``learn=False``)."""
    from simlab.agents.kernels import SELECT_EPSILON_GREEDY, SELECT_GREEDY

    if not 0.0 <= float(epsilon) <= 1.0:
        raise ConfigError(f"expected a probability in [0, 1], got {epsilon!r}", key="epsilon")
    selection = SELECT_EPSILON_GREEDY if epsilon > 0 else SELECT_GREEDY
    p = core.AgentParams(core.KIND_MF, int(selection), 0.0, 0.0, float(epsilon), 0.0, 1, False,
                         False, 0, 1, 0.0, False, False, False)
    return core.Learner(social_q, core.NO_MODEL, p, core.Observer(core.NO_OBSERVER_Q, p, -1))


def new_out(trials: int, record: np.ndarray | None = None) -> CombinedOut:
    """Zeroed :data:`CombinedOut` for ``trials`` trials (no record unless given)."""
    return CombinedOut(np.zeros(trials, dtype=np.float64), np.zeros(trials, dtype=np.float64),
                       np.zeros((0, 0), dtype=np.int64) if record is None else record)


@dataclass(frozen=True, eq=False)
class CombinedRun:
    """One seeded run: goal rooms reached and social reward per trial, ``(trials,)``
    each; for a learning run also the social agent's final Q table ``(2560, 30)`` and
    model (:func:`~simlab.visitlab.fused.model_state` arrays), else None."""

    goals: np.ndarray
    social_rewards: np.ndarray
    q: np.ndarray | None = None
    model: dict[str, np.ndarray] | None = None


def evaluate(task: CombinedTask, modules: Modules, trials: int,
             gens: tuple[np.random.Generator, np.random.Generator], *,
             epsilon: float = 0.0) -> CombinedRun:
    """Run the frozen architecture for ``trials`` trials: the social module acts
    greedily (``epsilon`` > 0: epsilon-greedy; 1: uniformly random, the chance level).

    ``gens`` = ``(env_rng, agent_rng)`` (e.g. from
    :func:`~simlab.visitlab.training.seed_generators`).
    """
    task.check_modules(modules)
    _check_trials(trials)
    out = new_out(trials)
    combined_chunk(task.kernel_args(modules), frozen_learner(modules.social_q.copy(), epsilon),
                   False, gens[0], gens[1], 0, 0, out)
    return CombinedRun(out.goals, out.rewards)


def _check_trials(trials: int) -> None:
    if isinstance(trials, bool) or not isinstance(trials, int | np.integer) or trials < 1:
        raise ConfigError(f"expected an integer >= 1, got {trials!r}", key="trials")


# --------------------------------------------------------------------------- episodes


@dataclass(frozen=True, eq=False)
class Episode:
    """One recorded combined trial.

    Attributes:
        states: world states, int64 ``(max_steps + 1, N_STATE)`` (row ``t`` before
            step ``t``; the last row after the trial), see
            :mod:`simlab.visitlab.dynamics` for the columns.
        actions: the social module's action per step ``(max_steps,)``.
        executed: the action executed (the go-to-human module's for 29).
        rewards: social reward per step.
        reached: 1 where the human entered the goal room.
    """

    states: np.ndarray
    actions: np.ndarray
    executed: np.ndarray
    rewards: np.ndarray
    reached: np.ndarray

    @property
    def goals(self) -> int:
        return int(self.reached.sum())


def record_episodes(task: CombinedTask, modules: Modules, trials: int,
                    gens: tuple[np.random.Generator, np.random.Generator]) -> list[Episode]:
    """Run ``trials`` greedy trials like :func:`evaluate` (same streams, same goals) and
    return each one step by step."""
    task.check_modules(modules)
    _check_trials(trials)
    T = task.max_steps
    record = np.zeros((trials * (T + 1), dyn.N_STATE + 4), dtype=np.int64)
    combined_chunk(task.kernel_args(modules), frozen_learner(modules.social_q.copy()), False,
                   gens[0], gens[1], 0, 0, new_out(trials, record))
    out = []
    n = dyn.N_STATE
    for k in range(trials):
        rows = record[k * (T + 1):(k + 1) * (T + 1)]
        out.append(Episode(rows[:, :n].copy(), rows[:T, n].copy(), rows[:T, n + 1].copy(),
                           rows[:T, n + 2].copy(), rows[:T, n + 3].copy()))
    return out


def _action_name(a: int) -> str:
    return Action(int(a)).name.replace("_", "-") if 0 <= a < 30 else "-"


def _room_edges(layout: Layout, label: int, cell_px: int
                ) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """Pixel segments on the grid lines between cells of room ``label`` and other cells
    (``label`` -1: between any two rooms)."""
    lab = layout.labels
    h, w = lab.shape
    segs = []
    for r in range(h):
        for c in range(w):
            for dr, dc in ((0, 1), (1, 0)):
                r2, c2 = r + dr, c + dc
                if r2 >= h or c2 >= w or lab[r, c] == lab[r2, c2]:
                    continue
                if label >= 0 and label not in (lab[r, c], lab[r2, c2]):
                    continue
                if dc:  # vertical line left of column c2
                    segs.append(((c2 * cell_px, r * cell_px), (c2 * cell_px, (r + 1) * cell_px)))
                else:
                    segs.append(((c * cell_px, r2 * cell_px), ((c + 1) * cell_px, r2 * cell_px)))
    return segs


def episode_frames(task: CombinedTask, episode: Episode, cell_px: int = 18) -> list[np.ndarray]:
    """RGB frames (uint8) of an episode: the world (room borders in grey, the goal room
    tinted and outlined in blue, fields of view, walls), robot (red) and human (blue)
    with orientations, and a caption strip with the step, the action (and the delegated
    move), the interaction level, the required direction and the goals reached so far."""
    import cv2

    from simlab.visitlab.actions import DIRECTION_NAMES
    from simlab.visitlab.render import Scene, render_rgb

    lay = task.layout
    los, pcfg = lay.los_table(), task.perception.to_array()
    frames = []
    goals = 0
    T = len(episode.actions)
    for t in range(T + 1):
        st = episode.states[t]
        level = int(dyn.interaction_level(lay.walls_h, lay.walls_v, los, pcfg, st))
        img = render_rgb(lay, task.perception,
                         Scene(int(st[dyn.S_ROBOT]), int(st[dyn.S_ROBOT_ORI]),
                               int(st[dyn.S_HUMAN]), int(st[dyn.S_HUMAN_ORI]),
                               goal_label=int(st[dyn.S_GOAL])), cell_px=cell_px)
        for p0, p1 in _room_edges(lay, -1, cell_px):
            cv2.line(img, p0, p1, (150, 150, 150), 1)
        for p0, p1 in _room_edges(lay, int(st[dyn.S_GOAL]), cell_px):
            cv2.line(img, p0, p1, (30, 90, 200), 3)
        strip = np.full((44, img.shape[1], 3), 255, dtype=np.uint8)
        if t < T:
            a, ex = int(episode.actions[t]), int(episode.executed[t])
            act = _action_name(a) + (f" -> {_action_name(ex)}" if a != ex else "")
        else:
            act = "end of trial"
        line1 = f"t={t:3d}  {act}"
        line2 = (f"level {level}  required {DIRECTION_NAMES[int(st[dyn.S_REQ_DIR])]}  "
                 f"goal room {int(st[dyn.S_GOAL])}  goals {goals}")
        cv2.putText(strip, line1, (6, 17), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1,
                    cv2.LINE_AA)
        cv2.putText(strip, line2, (6, 37), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1,
                    cv2.LINE_AA)
        frames.append(np.concatenate([img, strip], axis=0))
        if t < T:
            goals += int(episode.reached[t])
    return frames


def write_episode_gif(task: CombinedTask, episode: Episode, path: str | os.PathLike[str], *,
                      fps: float = 4.0, cell_px: int = 18, overwrite: bool = False) -> Path:
    """Write the episode as an animated GIF (atomically; refuses to replace a file
    unless ``overwrite``). Returns the path."""
    import imageio.v3 as iio

    from simlab.base.io import atomic_write, ensure_new

    path = ensure_new(path, overwrite=overwrite, what="episode GIF")
    frames = episode_frames(task, episode, cell_px=cell_px)
    data = iio.imwrite("<bytes>", np.stack(frames), extension=".gif",
                       duration=int(1000 / fps), loop=0)
    with atomic_write(path, "wb") as fh:
        fh.write(data)
    return path
