"""The options of ``simlab train``: the task asked of the agent (:class:`TrainTask`) and the
command's configuration (:class:`TrainConfig`, from which the CLI is generated).

The task modes and the unvisited rule are decided in :mod:`simlab.training.train`'s
module docstring (thesis 3.2.5 and 4.5).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from simlab.base import validation as v
from simlab.base.errors import ConfigError
from simlab.base.options import CommandConfig, option

__all__ = ["TASK_MODES", "TrainConfig", "TrainTask", "param_pair"]

#: Task modes of :class:`TrainTask` (the first is the default).
TASK_MODES = ("per-step", "episodic")


@dataclasses.dataclass(frozen=True)
class TrainTask:
    """What the agent is asked to do (see the module docstring's decisions).

    Attributes:
        mode: ``per-step`` (default, +1 per step arriving in the goal) or ``episodic``
            (+1 on arrival, then restart from the start states).
        goal_states: state ids of one goal area (instead of the MDP's named goals).
        start_states: start states, drawn uniformly (default: all states).
        unvisited: ``mask`` or ``self-loop`` to override the MDP's rule (None: the MDP's).
    """

    mode: str = "per-step"
    goal_states: tuple[int, ...] | None = None
    start_states: tuple[int, ...] | None = None
    unvisited: str | None = None

    def __post_init__(self) -> None:
        if self.mode not in TASK_MODES:
            raise ConfigError(f"unknown task {self.mode!r}", key="task",
                              fix="use 'per-step' or 'episodic'")
        for key in ("goal_states", "start_states"):
            object.__setattr__(self, key, v.state_ids(getattr(self, key), key))
        both = set(self.goal_states or ()) & set(self.start_states or ())
        if self.mode == "episodic" and both:
            raise ConfigError(f"start state {min(both)} is a goal state: an episode starting "
                              "there ends before its first step, so nothing is learned or "
                              "scored", key="start_states",
                              fix="give start states apart from the goal states")
        if self.unvisited is not None and self.unvisited not in ("mask", "self-loop"):
            raise ConfigError(f"unknown rule {self.unvisited!r}", key="unvisited",
                              fix="use 'mask' or 'self-loop'")

    def as_dict(self) -> dict[str, Any]:
        return {"mode": self.mode,
                "goal_states": None if self.goal_states is None else list(self.goal_states),
                "start_states": None if self.start_states is None else list(self.start_states)}


def param_pair(text: str) -> tuple[str, Any]:
    """``KEY=VALUE`` of ``--param`` (VALUE as JSON, else as a plain string)."""
    import argparse
    import json

    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    try:
        parsed = json.loads(value)
    except json.JSONDecodeError:
        parsed = value  # plain strings: --param selection=softmax
    return key.strip(), parsed


def _param_item(item: Any) -> tuple[str, Any]:
    """One ``"KEY=VALUE"`` of a list of overrides (an options file's ``param = [...]``)."""
    import argparse

    try:
        if not isinstance(item, str):
            raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {item!r}")
        return param_pair(item)
    except argparse.ArgumentTypeError as exc:
        raise ConfigError(str(exc), key="param", fix='e.g. param = ["tau=0.05"]') from None


_AGENTS = "q-learning, q-softmax, mb-egreedy, vi-softmax, rmax, sliding-window, passive-observer"


@dataclasses.dataclass(frozen=True, kw_only=True)
class TrainConfig(CommandConfig):
    """Options of ``simlab train`` / :func:`simlab.training.train.train`.

    ``task`` is a :class:`TrainTask` (Python) or its mode (``--task``); with a mode,
    ``goal_states``, ``start_states`` and ``unvisited`` complete it (``validate`` makes
    ``task`` the :class:`TrainTask`). ``params`` is a dict of hyper-parameter overrides;
    ``--param KEY=VALUE`` (repeatable) is added by the CLI module. The fields:

    * ``mdp``: ``mdp.npz`` path (``simlab estimate``) or an
      :class:`~simlab.data.mdp.EmpiricalMDP`.
    * ``agent``: a registered agent name (:mod:`simlab.agents.registry`).
    * ``goals``: ``"all"``, a comma-separated string or a list of goal names.
    * ``episodes``, ``runs``, ``seed``, ``horizon``, ``start``: training budget,
      independent runs, root seed, steps per episode, fixed start state (``None``: uniform).
    * ``params``: hyper-parameter overrides of the agent's preset (``{"tau": 0.05}``).
    * ``bounds``, ``arena``: heat-map extent ``(x_min, y_min, x_max, y_max)`` m, or an arena
      (name, path or config) to take it from; default: the MDP file's ``bounds`` or the
      centres' extent.
    * ``occupancy_map``: optional ``map.yaml`` path or occupancy map under the heat maps.
    * ``out``: output directory (created); ``None`` writes nothing and only returns.
    * ``plots``, ``overwrite``, ``progress``: write PNGs; replace existing outputs; show a
      progress bar.
    * ``pool`` (Python only) or ``workers``: a process executor, or the number of processes,
      sharing the work with this process
      (:func:`simlab.training.loop.train_goals_shared`); the outputs are
      the same bytes as without.
    * ``task`` (a :class:`TrainTask` or its mode) with ``goal_states``, ``start_states``,
      ``unvisited``: task mode, goal/start states, unvisited rule (default: per-step, the
      MDP's goals and rule).
    """

    COMMAND = "train"

    mdp: Any = option(help="mdp.npz written by simlab estimate (or an EmpiricalMDP)")
    agent: str = option("vi-softmax", f"agent name ({_AGENTS})")
    goals: Any | None = option("all", "'all' or comma-separated goal names", parse=str)
    episodes: int = option(2000, "episodes per run")
    runs: int = option(10, "independent runs per goal")
    seed: int = option(0, "root seed")
    out: Path | None = option(None, "output directory (Python: None writes nothing) "
                              "(required)")
    horizon: int = option(50, "steps per episode")
    start: int | None = option(None, "fixed start state (default: uniform over states)")
    params: Any | None = option(None, "hyper-parameter overrides {name: value}", cli=False,
                                flag="param")
    bounds: tuple[float, ...] | None = option(
        None, "heat-map extent XMIN YMIN XMAX YMAX in metres (default: from --arena or the "
        "centres)")
    arena: Any | None = option(None, "arena name or TOML for the heat-map extent", parse=str)
    occupancy_map: Any | None = option(None, "map.yaml drawn under the heat maps", flag="map",
                                       parse=str)
    goal_states: Any | None = option(
        None, "train one goal made of these state ids, e.g. 18 or 18,19 (named s18, "
        "s18+19); no arena needed (default: the MDP's named goals)", parse=str)
    start_states: Any | None = option(
        None, "start states drawn uniformly, e.g. 0,32 (default: all states, or --start)",
        parse=str)
    task: Any | None = option(
        None, "per-step: +1 per step arriving in the goal, fixed-length episodes (thesis; "
        "default); episodic: +1 on arrival, then restart from the start states (real robot)",
        parse=str, metavar="{per-step,episodic}")
    unvisited: str | None = option(
        None, "unvisited (s, a): mask = never chosen, self-loop = the old free stay "
        "(default: the rule stored in the MDP, mask for old files)",
        choices=("mask", "self-loop"))
    plots: bool = option(True, "the PNG figures (--no-plots skips them)")
    overwrite: bool = option(False, "replace existing outputs")
    progress: bool = option(True, "progress bar (--no-progress hides it)")
    workers: int = option(1, "processes sharing the goals and figures (1: this one only; N "
                          "starts N-1 worker processes)")
    pool: Any | None = option(
        None, "a concurrent.futures process executor (e.g. simlab.base.parallel.spawn_worker()) "
        "whose workers train and draw part of the goals; the caller owns it (a simlab "
        "WorkerPool gets a goal per process at a time, any other executor one)", cli=False)

    def validate(self) -> None:
        if self.arena is not None:
            from simlab.physics.arena import check_arena_option

            check_arena_option(self.arena)
        if self.goals is not None and not (isinstance(self.goals, str) or (
                isinstance(self.goals, list | tuple)
                and all(isinstance(g, str) for g in self.goals))):
            raise ConfigError(f"expected goal names, got {self.goals!r}", key="goals",
                              fix="'all', names such as \"g1,g2\", or a list of names")
        v.whole(self.episodes, "episodes", minimum=1)
        v.whole(self.runs, "runs", minimum=1)
        v.whole(self.seed, "seed")
        v.whole(self.horizon, "horizon", minimum=1)
        v.whole(self.workers, "workers", minimum=1)
        v.executor(self.pool)
        if self.pool is not None and self.workers != 1:
            raise ConfigError("give either a pool or workers", key="workers")
        if self.bounds is not None and len(self.bounds) != 4:
            raise ConfigError(f"expected 4 numbers XMIN YMIN XMAX YMAX, got {self.bounds}",
                              key="bounds")
        if isinstance(self.params, list | tuple):  # `param = ["tau=0.05"]`, as on the CLI
            object.__setattr__(self, "params", dict(_param_item(p) for p in self.params))
        if self.params is not None and not isinstance(self.params, dict):
            raise ConfigError(f"expected a table of overrides, got {self.params!r}",
                              key="params", fix='e.g. params = {tau = 0.05} or '
                              'param = ["tau=0.05"]')
        extra = (self.goal_states, self.start_states, self.unvisited)
        if isinstance(self.task, TrainTask):
            if any(x is not None for x in extra):
                raise ConfigError("give goal_states/start_states/unvisited in the TrainTask",
                                  key="task")
            task = self.task
        else:
            task = TrainTask(mode="per-step" if self.task is None else self.task,
                             goal_states=self.goal_states, start_states=self.start_states,
                             unvisited=self.unvisited)
        object.__setattr__(self, "task", task)
        if task.goal_states is not None and self.goals not in (None, "all"):
            raise ConfigError("give either goals or goal_states", key="goal_states")
