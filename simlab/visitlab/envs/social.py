"""The Visit-the-lab social env (card in the class docstring)."""

from __future__ import annotations

from typing import Any

from gymnasium import spaces

from simlab.base.errors import ConfigError
from simlab.visitlab import dynamics as dyn
from simlab.visitlab.actions import N_SOCIAL_ACTIONS
from simlab.visitlab.envs.base import (
    PAPER_SOCIAL_GRID_SIZE,
    SOCIAL_GRID_SIZE,
    VARIANT_STEPS,
    SocialKernelArgs,
    VisitLabEnv,
    cell_option,
    centre,
    check_steps,
    check_variant,
    fused_steps,
    reset_options,
    resolve_human,
)
from simlab.visitlab.grid import Layout, gridworld, make_layout
from simlab.visitlab.humans import Human
from simlab.visitlab.perception import Perception, perception_for
from simlab.visitlab.render import Scene


class SocialEnv(VisitLabEnv):
    """``simlab/VisitLab-Social-v0`` — get the human's attention and lead them (thesis 2.1.2;
    paper Fig. 4).

    **Description**
        A robot and a human on a grid. The robot must engage the human (looks,
        HELLO, COME, POINTING) and then make them walk in the required direction.
        Dynamics: :mod:`simlab.visitlab.dynamics` (the exact rules and their order).
        At reset the robot is placed at random, the human at ``human_start``,
        orientations and the required direction random, the human not engaged; the
        required direction is redrawn with probability ``redraw_p`` per step.

    **Actions**
        ``Discrete(30)``: moves 0-23, STAY, LOOK_H, HELLO, COME, POINTING,
        GO_TO_HUMAN (here: placed two cells ahead of the human's gaze).

    **Observations**
        ``Discrete(2560)``: ``ravel_multi_index((interaction, distance, direction,
        angle), (8, 5, 8, 8))`` — interaction level 0-7, distance class 0-4, required
        direction 0-7, quantised direction robot -> human 0-7 (:func:`decode_social`).
        ``info``: positions, orientations, ``interaction`` level, ``engaged``,
        ``distance_class``, ``angle``, ``required_direction``, the percepts
        ``h_sees_r``/``h_looks_at_r``/``r_looks_at_h``, ``human_moved`` (direction or
        -1) and ``human_moved_required``.

    **Rewards**
        +1 when the level is 7 and the human moved in the required direction, else 0.

    **Termination**
        Never terminated. Truncated after ``max_steps`` steps (``"variant"``: the
        variant's length; ``None``: no limit of the env's own, Gymnasium's
        ``TimeLimit`` of the registration truncates).

    **Variants**
        ``thesis`` — Manhattan distance classes, easy human, 40 steps, a 41 x 41
        grid; ``paper`` — Chebyshev classes (the paper's), human H1, 20 steps, a
        140 x 140 grid and the paper rules 3-6 of
        :class:`~simlab.visitlab.perception.Perception` (continuous fields of view,
        gaze, GO_TO_HUMAN, shared cells; as the code published with Chartouny et al. 2024 applies them).
        Both: no inner walls, human starting at the centre, ``redraw_p`` 0.2.
    """

    def __init__(
        self,
        variant: str = "thesis",
        human: Human | str | None = None,
        layout: Layout | str | None = None,
        human_start: int | tuple[int, int] | str = "center",
        robot_start: int | tuple[int, int] | str = "random",
        max_steps: int | str | None = VARIANT_STEPS,
        redraw_p: float = 0.2,
        perception: Perception | None = None,
        layout_seed: int | None = None,
        render_mode: str | None = None,
    ) -> None:
        super().__init__(render_mode)
        self.variant = check_variant(variant)
        thesis = variant == "thesis"
        self.human = resolve_human(human, "easy" if thesis else "H1")
        size = SOCIAL_GRID_SIZE if thesis else PAPER_SOCIAL_GRID_SIZE
        self.layout = (gridworld(size, size, (1, 1)) if layout is None
                       else make_layout(layout, seed=layout_seed))
        self.perception = perception if perception is not None else perception_for(variant)
        named = {"random": -1, "center": centre(self.layout), "centre": centre(self.layout)}
        self.human_start = cell_option(human_start, self.layout, "human_start", named)
        self.robot_start = cell_option(robot_start, self.layout, "robot_start", {"random": -1})
        self.max_steps = check_steps(max_steps, 40 if thesis else 20)
        if not 0.0 <= float(redraw_p) <= 1.0:
            raise ConfigError(f"expected a probability in [0, 1], got {redraw_p!r}", key="redraw_p")
        self.redraw_p = float(redraw_p)
        self._hp = self.human.to_array()
        self._pcfg = self.perception.to_array()
        self._los = self.layout.los_table()
        self._moved_required = False
        self.observation_space = spaces.Discrete(dyn.N_SOCIAL_STATES)
        self.action_space = spaces.Discrete(N_SOCIAL_ACTIONS)

    def kernel_args(self) -> SocialKernelArgs:
        """The fixed inputs of the fused social loop
        (:func:`simlab.visitlab.fused.social_train_chunk`) as a
        :data:`SocialKernelArgs`."""
        lay = self.layout
        return SocialKernelArgs(lay.walls_h, lay.walls_v, self._los, self._pcfg, self._hp,
                                float(self.redraw_p), int(self.robot_start),
                                int(self.human_start), fused_steps(self.max_steps))

    def _obs(self) -> int:
        return int(dyn.social_obs(self.layout.walls_h, self.layout.walls_v, self._los, self._pcfg,
                                  self._st))

    def _info(self) -> dict[str, Any]:
        st = self._st
        info = self._positions()
        level, dist, angle, sees, looks, r_looks = self._percepts()
        engaged = int(st[dyn.S_ENGAGED])
        info.update(
            interaction=engaged if engaged >= 5 else int(level),
            engaged=engaged >= 5,
            percept_level=int(level),
            distance_class=int(dist),
            angle=int(angle),
            required_direction=int(st[dyn.S_REQ_DIR]),
            h_sees_r=bool(sees),
            h_looks_at_r=bool(looks),
            r_looks_at_h=bool(r_looks),
            human_moved=int(st[dyn.S_HUMAN_MOVE]),
            human_moved_required=bool(self._moved_required),
        )
        return info

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Options: ``robot_start``, ``human_start`` (cell, ``(row, col)`` or ``"random"``;
        the human also ``"center"``), for this episode only."""
        opt = reset_options(options, {"robot_start": self.robot_start,
                                       "human_start": self.human_start})
        named = {"random": -1, "center": centre(self.layout), "centre": centre(self.layout)}
        robot = cell_option(opt["robot_start"], self.layout, "options.robot_start",
                             {"random": -1}) if opt["robot_start"] != -1 else -1
        human = cell_option(opt["human_start"], self.layout, "options.human_start",
                             named) if opt["human_start"] != -1 else -1
        super().reset(seed=seed)
        self._t = 0
        self._moved_required = False
        dyn.social_reset(self._st, self.np_random, self.layout.n_cells, robot, human,
                         self.perception.share_cells)
        return self._obs(), self._info()

    def step(self, action: int):
        if not self.action_space.contains(action):
            raise ConfigError(f"expected an action in 0..29, got {action!r}", key="action")
        # "moved in the required direction" refers to the direction observed before the step
        required = int(self._st[dyn.S_REQ_DIR])
        reward = dyn.social_step(self.layout.walls_h, self.layout.walls_v, self._los, self._pcfg,
                                 self._hp, self.redraw_p, self._st, int(action), self.np_random)
        self._moved_required = int(self._st[dyn.S_HUMAN_MOVE]) == required
        self._t += 1
        return self._obs(), float(reward), False, self._truncated(), self._info()

    def _scene(self) -> Scene:
        info = self._info()
        return Scene(info["robot_cell"], info["robot_orientation"], info["human_cell"],
                     info["human_orientation"],
                     caption=f"t={self._t} level={info['interaction']} "
                             f"dist={info['distance_class']} req={info['required_direction']}")
