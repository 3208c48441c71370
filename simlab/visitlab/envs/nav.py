"""The Visit-the-lab navigation env (card in the class docstring)."""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from simlab.base.errors import ConfigError
from simlab.visitlab import dynamics as dyn
from simlab.visitlab.actions import N_MOVE_ACTIONS
from simlab.visitlab.envs.base import (
    VARIANT_STEPS,
    NavKernelArgs,
    VisitLabEnv,
    cell_option,
    check_steps,
    check_variant,
    fused_steps,
    goal_option,
    reset_options,
)
from simlab.visitlab.grid import Layout, make_layout
from simlab.visitlab.perception import perception_for
from simlab.visitlab.render import Scene


class NavEnv(VisitLabEnv):
    """``simlab/VisitLab-Nav-v0`` — navigation to a goal room (thesis 2.1.1).

    **Description**
        The robot moves on a grid of labelled rooms towards a goal room; the task is
        goal-conditioned (the goal room is part of the observation).

    **Actions**
        ``Discrete(25)``: moves 0-23 (8 directions x speeds 1-3) and STAY 24
        (:class:`~simlab.visitlab.actions.Action`).

    **Observations**
        ``Discrete(n_labels * n_cells)``: ``cell + goal_label * n_cells`` (the robot's
        cell and the goal room's label).

    **Rewards**
        +1 for every step that ends inside the goal room, else 0.

    **Termination**
        Never terminated. Truncated after ``max_steps`` steps (``"variant"``: the
        variant's length; ``None``: no limit of the env's own, Gymnasium's
        ``TimeLimit`` of the registration truncates, see :data:`simlab.envs.ENV_LIMITS`).

    **Variants**
        ``thesis`` — 24 x 24 gridworld without inner walls labelled in nine 8 x 8
        areas (Fig. 2.6), fixed start at the layout's start cell (top-left corner),
        fixed goal = the last goal label (lower-right area), 50 steps (Fig. 4.1).
        ``paper`` — the 24 x 24 nine-room layout with doors, random start and random
        goal room each episode, 20 steps.

    Args:
        layout: a :class:`Layout` or a name for :func:`make_layout` (``gridworld``,
            ``gridworld-HxW``, ``paper``, ``lab``); ``layout_seed`` seeds ``lab``.
        start: a cell index, ``(row, col)``, or ``"random"`` (uniform cell).
        goal: a goal label, or ``"random"`` (uniform among ``layout.goal_labels``).
    """

    def __init__(
        self,
        variant: str = "thesis",
        layout: Layout | str | None = None,
        start: int | tuple[int, int] | str | None = None,
        goal: int | str | None = None,
        max_steps: int | str | None = VARIANT_STEPS,
        layout_seed: int | None = None,
        render_mode: str | None = None,
    ) -> None:
        super().__init__(render_mode)
        self.variant = check_variant(variant)
        thesis = variant == "thesis"
        if layout is None:
            layout = "gridworld" if thesis else "paper"
        self.layout = make_layout(layout, seed=layout_seed)
        self.perception = perception_for(variant)
        if start is None:
            start = self.layout.start_cell if thesis else "random"
        self.start_cell = cell_option(start, self.layout, "start", {"random": -1})
        if goal is None:
            goal = self.layout.goal_labels[-1] if thesis else "random"
        self.goal_label = goal_option(goal, self.layout)
        self.max_steps = check_steps(max_steps, 50 if thesis else 20)
        self._goal_labels = np.array(self.layout.goal_labels, dtype=np.int64)
        self.observation_space = spaces.Discrete(self.layout.n_labels * self.layout.n_cells)
        self.action_space = spaces.Discrete(N_MOVE_ACTIONS)

    def kernel_args(self) -> NavKernelArgs:
        """The fixed inputs of the fused navigation loop
        (:func:`simlab.visitlab.fused.nav_train_chunk`) as a :data:`NavKernelArgs`."""
        lay = self.layout
        return NavKernelArgs(lay.walls_h, lay.walls_v, lay.cell_labels, int(self.start_cell),
                             int(self.goal_label), np.array(lay.goal_labels, dtype=np.int64),
                             fused_steps(self.max_steps))

    def _obs(self) -> int:
        return int(dyn.nav_obs(self._st, self.layout.n_cells))

    def _info(self) -> dict[str, Any]:
        info = self._positions()
        cell = int(self._st[dyn.S_ROBOT])
        info["goal_label"] = int(self._st[dyn.S_GOAL])
        info["room_label"] = int(self.layout.cell_labels[cell])
        info["in_goal"] = info["room_label"] == info["goal_label"]
        return info

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Options: ``start`` (cell, ``(row, col)`` or ``"random"``), ``goal`` (label or
        ``"random"``), for this episode only."""
        opt = reset_options(options, {"start": self.start_cell, "goal": self.goal_label})
        start = -1 if opt["start"] == -1 else cell_option(opt["start"], self.layout,
                                                           "options.start", {"random": -1})
        goal = -1 if opt["goal"] == -1 else goal_option(opt["goal"], self.layout)
        super().reset(seed=seed)
        self._t = 0
        dyn.nav_reset(self._st, self.np_random, self.layout.n_cells, start, goal,
                      self._goal_labels)
        return self._obs(), self._info()

    def step(self, action: int):
        if not self.action_space.contains(action):
            raise ConfigError(f"expected an action in 0..24, got {action!r}", key="action")
        reward = dyn.nav_step(self.layout.walls_h, self.layout.walls_v, self.layout.cell_labels,
                              self._st, int(action))
        self._t += 1
        return self._obs(), float(reward), False, self._truncated(), self._info()

    def _scene(self) -> Scene:
        info = self._info()
        return Scene(info["robot_cell"], info["robot_orientation"],
                     goal_label=info["goal_label"],
                     caption=f"t={self._t} goal={self.layout.room_names[info['goal_label']]}")
