"""The Visit-the-lab go-to-human env (card in the class docstring)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces

from simlab.base.errors import ConfigError
from simlab.visitlab import dynamics as dyn
from simlab.visitlab.actions import N_MOVE_ACTIONS
from simlab.visitlab.envs.base import (
    VARIANT_STEPS,
    GthKernelArgs,
    VisitLabEnv,
    cell_option,
    centre,
    check_steps,
    check_variant,
    direction_option,
    fused_steps,
    reset_options,
    resolve_human,
)
from simlab.visitlab.grid import Layout, gridworld, make_layout
from simlab.visitlab.humans import Human
from simlab.visitlab.perception import Perception, perception_for
from simlab.visitlab.render import Scene


@dataclass(frozen=True)
class StartPoses:
    """Where robot and human start when the episode variant fixes it (thesis Fig. 4.4):
    cells as an index or ``(row, col)`` (the human's also ``"center"``), orientations
    0-7 (:mod:`simlab.visitlab.actions`). Default: robot at (2, 2) facing DOWN, human at
    the centre facing UP."""

    robot_cell: int | tuple[int, int] = (2, 2)
    human_cell: int | tuple[int, int] | str = "center"
    robot_ori: int = 1
    human_ori: int = 0


class GoToHumanEnv(VisitLabEnv):
    """``simlab/VisitLab-GoToHuman-v0`` — reach the human's facing field (thesis 2.1.3).

    **Description**
        The robot must get in front of a human: into the human's facing field, with
        line of sight, at distance class 1-3. ``episode`` (thesis Fig. 4.4):
        ``"random"`` — positions and orientations drawn each episode;
        ``"fixed_positions"`` — robot and human at the cells of ``start``
        (:class:`StartPoses`), orientations random; ``"fixed"`` — positions and
        orientations of ``start``. Default ``start``: robot at (2, 2) facing DOWN, human
        at the centre facing UP. The human stands still unless ``human`` is given (a
        preset name or :class:`Human`): then it walks and turns like a human who is
        not engaged (r_H, O_H, s_H).

    **Actions**
        ``Discrete(25)``: moves 0-23 and STAY 24.

    **Observations**
        ``Discrete(320)``: ``ravel_multi_index((human_orientation, distance, angle),
        (8, 5, 8))`` (:func:`decode_gth`).

    **Rewards**
        +1 per step that ends with the robot in the human's facing field (with line
        of sight) at distance class 1-3, else 0.

    **Termination**
        Never terminated. Truncated after ``max_steps`` steps (``"variant"``: the
        variant's length; ``None``: no limit of the env's own, Gymnasium's
        ``TimeLimit`` of the registration truncates).

    **Variants**
        ``thesis`` — Manhattan distance classes, 40 steps; ``paper`` — Chebyshev
        classes, 20 steps. Both: a 24 x 24 grid without inner walls.
    """

    def __init__(
        self,
        variant: str = "thesis",
        episode: str = "random",
        layout: Layout | str | None = None,
        human: Human | str | None = None,
        start: StartPoses = StartPoses(),
        max_steps: int | str | None = VARIANT_STEPS,
        perception: Perception | None = None,
        layout_seed: int | None = None,
        render_mode: str | None = None,
    ) -> None:
        super().__init__(render_mode)
        self.variant = check_variant(variant)
        thesis = variant == "thesis"
        if episode not in dyn.GTH_VARIANTS:
            raise ConfigError(f"expected one of {dyn.GTH_VARIANTS}, got {episode!r}", key="episode")
        self.episode = episode
        self._episode_code = dyn.GTH_VARIANTS.index(episode)
        self.layout = gridworld(24, 24) if layout is None else make_layout(layout, seed=layout_seed)
        self.perception = perception if perception is not None else perception_for(variant)
        self.human = None if human is None else resolve_human(human, "easy")
        named = {"center": centre(self.layout), "centre": centre(self.layout)}
        self.robot_cell = cell_option(start.robot_cell, self.layout, "start.robot_cell", {})
        self.human_cell = cell_option(start.human_cell, self.layout, "start.human_cell", named)
        if self.robot_cell == self.human_cell:
            raise ConfigError("robot and human cannot start on the same cell",
                              key="start.robot_cell")
        self.robot_ori = direction_option(start.robot_ori, "start.robot_ori")
        self.human_ori = direction_option(start.human_ori, "start.human_ori")
        self.max_steps = check_steps(max_steps, 40 if thesis else 20)
        self._hp = (self.human.to_array() if self.human is not None
                    else np.zeros(8, dtype=np.float64))
        self._pcfg = self.perception.to_array()
        self._los = self.layout.los_table()
        self.observation_space = spaces.Discrete(dyn.N_GTH_STATES)
        self.action_space = spaces.Discrete(N_MOVE_ACTIONS)

    def kernel_args(self) -> GthKernelArgs:
        """The fixed inputs of the fused go-to-human loop
        (:func:`simlab.visitlab.fused.gth_train_chunk`) as a :data:`GthKernelArgs`."""
        lay = self.layout
        return GthKernelArgs(lay.walls_h, lay.walls_v, self._los, self._pcfg, self._hp,
                             self.human is not None, int(self._episode_code),
                             int(self.robot_cell), int(self.human_cell), int(self.robot_ori),
                             int(self.human_ori), fused_steps(self.max_steps))

    def _obs(self) -> int:
        return int(dyn.gth_obs(self.layout.walls_h, self.layout.walls_v, self._los, self._pcfg,
                               self._st))

    def _info(self) -> dict[str, Any]:
        st = self._st
        info = self._positions()
        _, dist, angle, sees, looks, r_looks = self._percepts()
        info.update(distance_class=int(dist), angle=int(angle), h_sees_r=bool(sees),
                    h_looks_at_r=bool(looks), r_looks_at_h=bool(r_looks),
                    in_facing_field=bool(looks) and 1 <= dist <= 3,
                    human_moved=int(st[dyn.S_HUMAN_MOVE]))
        return info

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Options: ``robot_cell``, ``human_cell`` (cell or ``(row, col)``), ``robot_ori``,
        ``human_ori`` (0-7), for this episode only (the episode variant decides which of
        them a reset draws at random instead)."""
        opt = reset_options(options, {"robot_cell": self.robot_cell,
                                       "human_cell": self.human_cell,
                                       "robot_ori": self.robot_ori, "human_ori": self.human_ori})
        named = {"center": centre(self.layout), "centre": centre(self.layout)}
        robot = cell_option(opt["robot_cell"], self.layout, "options.robot_cell", {})
        human = cell_option(opt["human_cell"], self.layout, "options.human_cell", named)
        if robot == human and not self.perception.share_cells:
            raise ConfigError("robot and human cannot start on the same cell",
                              key="options.robot_cell")
        r_ori = direction_option(opt["robot_ori"], "options.robot_ori")
        h_ori = direction_option(opt["human_ori"], "options.human_ori")
        super().reset(seed=seed)
        self._t = 0
        dyn.gth_reset(self._st, self.np_random, self.layout.n_cells, self._episode_code,
                      robot, human, r_ori, h_ori, self.perception.share_cells)
        return self._obs(), self._info()

    def step(self, action: int):
        if not self.action_space.contains(action):
            raise ConfigError(f"expected an action in 0..24, got {action!r}", key="action")
        reward = dyn.gth_step(self.layout.walls_h, self.layout.walls_v, self._los, self._pcfg,
                              self._hp, self.human is not None, self._st, int(action),
                              self.np_random)
        self._t += 1
        return self._obs(), float(reward), False, self._truncated(), self._info()

    def _scene(self) -> Scene:
        info = self._info()
        return Scene(info["robot_cell"], info["robot_orientation"], info["human_cell"],
                     info["human_orientation"],
                     caption=f"t={self._t} dist={info['distance_class']} "
                             f"facing={info['in_facing_field']}")
