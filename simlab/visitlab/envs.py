"""Gymnasium environments of the Visit-the-lab modules (thin wrappers over the kernels).

Each env keeps the world-state array of :mod:`simlab.visitlab.dynamics` and calls
the same numba kernels as the fused training loops, passing ``self.np_random``
(seeded by ``reset(seed=...)``), so an env and a kernel loop driven by the same
seed and actions produce the same trajectory. Trials have a fixed length: an
episode ends with ``truncated=True`` after ``max_steps`` steps and is never
``terminated``. Render modes: ``"ansi"`` (text) and ``"rgb_array"``.

``variant="thesis"`` or ``"paper"`` sets the defaults listed in each card; every
default can be overridden by a keyword argument.
"""

from __future__ import annotations

from collections import namedtuple
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from simlab.errors import ConfigError
from simlab.visitlab import dynamics as dyn
from simlab.visitlab.actions import N_MOVE_ACTIONS, N_SOCIAL_ACTIONS
from simlab.visitlab.grid import Layout, gridworld, make_layout
from simlab.visitlab.humans import Human
from simlab.visitlab.humans import human as get_human
from simlab.visitlab.perception import Perception, perception_for, percepts
from simlab.visitlab.render import Scene, render_rgb, render_text

VARIANTS = ("thesis", "paper")

#: Default world of the social module: a wall-free grid large enough that a
#: 40-step trial started at the centre rarely meets the border.
SOCIAL_GRID_SIZE = 41
#: The paper code's social grid (paper rule 6): 140 x 140, the human at the centre.
PAPER_SOCIAL_GRID_SIZE = 140

#: What the fused navigation loop needs of a :class:`NavEnv` (``NavEnv.kernel_args()``):
#: walls ``walls_h`` / ``walls_v``, ``labels`` (n_cells,) room label per cell,
#: ``start_cell`` (-1: random), ``goal_label`` (-1: random), ``goal_labels`` (int64),
#: ``max_steps`` steps per trial.
NavKernelArgs = namedtuple("NavKernelArgs", ["walls_h", "walls_v", "labels", "start_cell",
                                             "goal_label", "goal_labels", "max_steps"])
#: What the fused social loop needs of a :class:`SocialEnv`: walls, ``los`` line-of-sight
#: table, ``pcfg`` perception array, ``hp`` human array, ``redraw_p`` probability of a
#: new required direction per step, ``robot_start`` / ``human_start`` cells (-1:
#: random), ``max_steps``.
SocialKernelArgs = namedtuple("SocialKernelArgs", ["walls_h", "walls_v", "los", "pcfg", "hp",
                                                   "redraw_p", "robot_start", "human_start",
                                                   "max_steps"])
#: What the fused go-to-human loop needs of a :class:`GoToHumanEnv`: walls, ``los``,
#: ``pcfg``, ``hp`` (zeros without a human), ``human_moves`` (a human is given),
#: ``episode`` (index in ``dynamics.GTH_VARIANTS``), start cells and orientations,
#: ``max_steps``.
GthKernelArgs = namedtuple("GthKernelArgs", ["walls_h", "walls_v", "los", "pcfg", "hp",
                                             "human_moves", "episode", "robot_cell",
                                             "human_cell", "robot_ori", "human_ori",
                                             "max_steps"])


def _check_variant(variant: str) -> str:
    if variant not in VARIANTS:
        raise ConfigError(f"expected one of {VARIANTS}, got {variant!r}", key="variant")
    return variant


def _check_steps(max_steps: int) -> int:
    if isinstance(max_steps, bool) or not isinstance(max_steps, int | np.integer) or max_steps < 1:
        raise ConfigError(f"expected an integer >= 1, got {max_steps!r}", key="max_steps")
    return int(max_steps)


def _cell_option(value: Any, layout: Layout, key: str, named: dict[str, int]) -> int:
    """A cell index, or a named choice (``"random"`` -> -1, ``"center"`` -> the centre)."""
    if isinstance(value, str):
        if value in named:
            return named[value]
        raise ConfigError(f"expected a cell index or one of {tuple(named)}, got {value!r}",
                          key=key)
    if isinstance(value, tuple) and len(value) == 2:
        return layout.cell(int(value[0]), int(value[1]))
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise ConfigError(f"expected a cell index, got {value!r}", key=key)
    if not 0 <= int(value) < layout.n_cells:
        raise ConfigError(f"cell {value} is outside 0..{layout.n_cells - 1}", key=key)
    return int(value)


def _goal_option(goal: Any, layout: Layout) -> int:
    """A goal label of ``layout``, or ``"random"`` -> -1."""
    if goal == "random":
        return -1
    if isinstance(goal, int | np.integer) and not isinstance(goal, bool) \
            and int(goal) in layout.goal_labels:
        return int(goal)
    raise ConfigError(f"expected 'random' or one of {layout.goal_labels}, got {goal!r}",
                      key="goal")


def _direction_option(value: Any, key: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or not 0 <= value < 8:
        raise ConfigError(f"expected a direction 0-7, got {value!r}", key=key)
    return int(value)


def _reset_options(options: dict | None, defaults: dict[str, Any]) -> dict[str, Any]:
    """``defaults`` updated by ``reset(options=...)``; unknown keys are refused by name.

    Options apply to the episode that this ``reset`` starts only (Gymnasium's convention);
    the env's constructor settings stay the defaults of later resets.
    """
    options = dict(options or {})
    unknown = sorted(set(options) - set(defaults))
    if unknown:
        raise ConfigError(f"unknown reset option(s) {unknown}", key=f"options.{unknown[0]}",
                          fix=f"allowed: {sorted(defaults)}")
    return {**defaults, **options}


def _centre(layout: Layout) -> int:
    return layout.cell(layout.height // 2, layout.width // 2)


def decode_social(obs: int) -> tuple[int, int, int, int]:
    """``(interaction, distance, direction, angle)`` of a social observation."""
    return tuple(int(x) for x in np.unravel_index(int(obs), dyn.SOCIAL_DIMS))  # type: ignore[return-value]


def encode_social(interaction: int, distance: int, direction: int, angle: int) -> int:
    """Social observation index of ``(interaction, distance, direction, angle)``."""
    return int(np.ravel_multi_index((interaction, distance, direction, angle), dyn.SOCIAL_DIMS))


def decode_gth(obs: int) -> tuple[int, int, int]:
    """``(human_orientation, distance, angle)`` of a go-to-human observation."""
    return tuple(int(x) for x in np.unravel_index(int(obs), dyn.GTH_DIMS))  # type: ignore[return-value]


class _VisitLabEnv(gym.Env):
    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["ansi", "rgb_array"], "render_fps": 4}

    layout: Layout
    perception: Perception

    def __init__(self, render_mode: str | None) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError(f"expected one of {self.metadata['render_modes']} or None, "
                              f"got {render_mode!r}", key="render_mode")
        self.render_mode = render_mode
        self._st = dyn.new_state()
        self._t = 0

    def _scene(self) -> Scene:  # pragma: no cover - overridden
        raise NotImplementedError

    def render(self) -> str | np.ndarray | None:
        if self.render_mode is None:
            return None
        scene = self._scene()
        if self.render_mode == "ansi":
            return render_text(self.layout, self.perception, scene)
        return render_rgb(self.layout, self.perception, scene)

    @property
    def world_state(self) -> np.ndarray:
        """A copy of the kernel world-state array (see :mod:`simlab.visitlab.dynamics`)."""
        return self._st.copy()

    def _percepts(self) -> tuple:
        """The robot's percepts of the human now (level, distance, angle, human sees robot,
        human looks at robot, robot looks at human); envs with a human only."""
        st = self._st
        return percepts(self.layout.walls_h, self.layout.walls_v, self._los, self._pcfg,
                        st[dyn.S_ROBOT], st[dyn.S_ROBOT_ORI], st[dyn.S_HUMAN],
                        st[dyn.S_HUMAN_ORI])

    def _positions(self) -> dict[str, Any]:
        st = self._st
        out: dict[str, Any] = {
            "t": self._t,
            "robot_cell": int(st[dyn.S_ROBOT]),
            "robot_pos": self.layout.rowcol(int(st[dyn.S_ROBOT])),
            "robot_orientation": int(st[dyn.S_ROBOT_ORI]),
        }
        if st[dyn.S_HUMAN] >= 0:
            out["human_cell"] = int(st[dyn.S_HUMAN])
            out["human_pos"] = self.layout.rowcol(int(st[dyn.S_HUMAN]))
            out["human_orientation"] = int(st[dyn.S_HUMAN_ORI])
        return out


class NavEnv(_VisitLabEnv):
    """``simlab/VisitLab-Nav-v0`` — navigation to a goal room (thesis 2.1.1, SPEC B1).

    **Observation** ``Discrete(n_labels * n_cells)``: ``cell + goal_label * n_cells``
    (goal-conditioned; the state of the robot is its cell, the percept the goal
    room's label). **Actions** ``Discrete(25)``: moves 0-23 and STAY 24
    (:class:`~simlab.visitlab.actions.Action`). **Reward** +1 for every step that
    ends inside the goal room. **Episode**: ``max_steps`` steps, then truncated.

    Variants: ``thesis`` — 24 x 24 gridworld without inner walls labelled in nine
    8 x 8 areas (Fig. 2.6), fixed start at the layout's start cell (top-left corner),
    fixed goal = the last goal label (lower-right area), 50 steps (Fig. 4.1).
    ``paper`` — the 24 x 24 nine-room layout with doors, random start and random goal
    room each episode, 20 steps.

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
        max_steps: int | None = None,
        layout_seed: int | None = None,
        render_mode: str | None = None,
    ) -> None:
        super().__init__(render_mode)
        self.variant = _check_variant(variant)
        thesis = variant == "thesis"
        if layout is None:
            layout = "gridworld" if thesis else "paper"
        self.layout = make_layout(layout, seed=layout_seed)
        self.perception = perception_for(variant)
        if start is None:
            start = self.layout.start_cell if thesis else "random"
        self.start_cell = _cell_option(start, self.layout, "start", {"random": -1})
        if goal is None:
            goal = self.layout.goal_labels[-1] if thesis else "random"
        self.goal_label = _goal_option(goal, self.layout)
        self.max_steps = _check_steps(max_steps if max_steps is not None else (50 if thesis else 20))
        self._goal_labels = np.array(self.layout.goal_labels, dtype=np.int64)
        self.observation_space = spaces.Discrete(self.layout.n_labels * self.layout.n_cells)
        self.action_space = spaces.Discrete(N_MOVE_ACTIONS)

    def kernel_args(self) -> NavKernelArgs:
        """The fixed inputs of the fused navigation loop
        (:func:`simlab.visitlab.training.nav_train_chunk`) as a :data:`NavKernelArgs`."""
        lay = self.layout
        return NavKernelArgs(lay.walls_h, lay.walls_v, lay.cell_labels, int(self.start_cell),
                             int(self.goal_label), np.array(lay.goal_labels, dtype=np.int64),
                             int(self.max_steps))

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
        opt = _reset_options(options, {"start": self.start_cell, "goal": self.goal_label})
        start = -1 if opt["start"] == -1 else _cell_option(opt["start"], self.layout,
                                                           "options.start", {"random": -1})
        goal = -1 if opt["goal"] == -1 else _goal_option(opt["goal"], self.layout)
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
        return self._obs(), float(reward), False, self._t >= self.max_steps, self._info()

    def _scene(self) -> Scene:
        info = self._info()
        return Scene(info["robot_cell"], info["robot_orientation"],
                     goal_label=info["goal_label"],
                     caption=f"t={self._t} goal={self.layout.room_names[info['goal_label']]}")


class SocialEnv(_VisitLabEnv):
    """``simlab/VisitLab-Social-v0`` — get the human's attention and lead them (SPEC B3).

    **Observation** ``Discrete(2560)``: ``ravel_multi_index((interaction, distance,
    direction, angle), (8, 5, 8, 8))`` — interaction level 0-7, distance class 0-4,
    required direction 0-7, quantised direction robot -> human 0-7
    (:func:`decode_social`). **Actions** ``Discrete(30)``: moves 0-23, STAY, LOOK_H,
    HELLO, COME, POINTING, GO_TO_HUMAN (here: placed two cells ahead of the human's
    gaze). **Reward** +1 when the level is 7 and the human moved in the required
    direction. Dynamics: :mod:`simlab.visitlab.dynamics` (the exact rules and their
    order). **Episode**: ``max_steps`` steps, then truncated; at reset the robot is
    placed at random, the human at ``human_start``, orientations and the required
    direction random, the human not engaged.

    Variants: ``thesis`` — Manhattan distance classes, easy human, 40 steps, a
    41 x 41 grid; ``paper`` — Chebyshev classes (paper code), human H1, 20 steps, the
    paper code's 140 x 140 grid and the paper rules 3-6 of
    :class:`~simlab.visitlab.perception.Perception` (continuous fields of view, gaze,
    GO_TO_HUMAN, shared cells). Both: no inner walls, human starting at the centre,
    required direction redrawn with probability 0.2 per step.

    ``info``: positions, orientations, ``interaction`` level, ``engaged``,
    ``distance_class``, ``angle``, ``required_direction``, the percepts
    ``h_sees_r``/``h_looks_at_r``/``r_looks_at_h``, ``human_moved`` (direction or -1)
    and ``human_moved_required``.
    """

    def __init__(
        self,
        variant: str = "thesis",
        human: Human | str | None = None,
        layout: Layout | str | None = None,
        human_start: int | tuple[int, int] | str = "center",
        robot_start: int | tuple[int, int] | str = "random",
        max_steps: int | None = None,
        redraw_p: float = 0.2,
        perception: Perception | None = None,
        layout_seed: int | None = None,
        render_mode: str | None = None,
    ) -> None:
        super().__init__(render_mode)
        self.variant = _check_variant(variant)
        thesis = variant == "thesis"
        self.human = _resolve_human(human, "easy" if thesis else "H1")
        size = SOCIAL_GRID_SIZE if thesis else PAPER_SOCIAL_GRID_SIZE
        self.layout = (gridworld(size, size, (1, 1)) if layout is None
                       else make_layout(layout, seed=layout_seed))
        self.perception = perception if perception is not None else perception_for(variant)
        named = {"random": -1, "center": _centre(self.layout), "centre": _centre(self.layout)}
        self.human_start = _cell_option(human_start, self.layout, "human_start", named)
        self.robot_start = _cell_option(robot_start, self.layout, "robot_start", {"random": -1})
        self.max_steps = _check_steps(max_steps if max_steps is not None else (40 if thesis else 20))
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
        (:func:`simlab.visitlab.training.social_train_chunk`) as a
        :data:`SocialKernelArgs`."""
        lay = self.layout
        return SocialKernelArgs(lay.walls_h, lay.walls_v, self._los, self._pcfg, self._hp,
                                float(self.redraw_p), int(self.robot_start),
                                int(self.human_start), int(self.max_steps))

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
        opt = _reset_options(options, {"robot_start": self.robot_start,
                                       "human_start": self.human_start})
        named = {"random": -1, "center": _centre(self.layout), "centre": _centre(self.layout)}
        robot = _cell_option(opt["robot_start"], self.layout, "options.robot_start",
                             {"random": -1}) if opt["robot_start"] != -1 else -1
        human = _cell_option(opt["human_start"], self.layout, "options.human_start",
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
        return self._obs(), float(reward), False, self._t >= self.max_steps, self._info()

    def _scene(self) -> Scene:
        info = self._info()
        return Scene(info["robot_cell"], info["robot_orientation"], info["human_cell"],
                     info["human_orientation"],
                     caption=f"t={self._t} level={info['interaction']} "
                             f"dist={info['distance_class']} req={info['required_direction']}")


class GoToHumanEnv(_VisitLabEnv):
    """``simlab/VisitLab-GoToHuman-v0`` — reach the human's facing field (SPEC B5).

    **Observation** ``Discrete(320)``: ``ravel_multi_index((human_orientation,
    distance, angle), (8, 5, 8))`` (:func:`decode_gth`). **Actions** ``Discrete(25)``
    (moves and STAY). **Reward** +1 per step that ends with the robot in the human's
    facing field (with line of sight) at distance class 1-3. **Episode**:
    ``max_steps`` steps, then truncated.

    ``episode`` (thesis Fig. 4.4): ``"random"`` — positions and orientations drawn
    each episode; ``"fixed_positions"`` — robot at ``robot_cell``, human at
    ``human_cell``, orientations random; ``"fixed"`` — positions and orientations
    fixed (``robot_ori``, ``human_ori``). Defaults: robot at (2, 2) facing DOWN,
    human at the centre facing UP.

    The human stands still unless ``human`` is given (a preset name or
    :class:`Human`): then it walks and turns like a human who is not engaged
    (r_H, O_H, s_H).

    Variants: ``thesis`` — Manhattan distance classes, 40 steps; ``paper`` —
    Chebyshev classes, 20 steps. Both: a 24 x 24 grid without inner walls.
    """

    def __init__(
        self,
        variant: str = "thesis",
        episode: str = "random",
        layout: Layout | str | None = None,
        human: Human | str | None = None,
        robot_cell: int | tuple[int, int] = (2, 2),
        human_cell: int | tuple[int, int] | str = "center",
        robot_ori: int = 1,
        human_ori: int = 0,
        max_steps: int | None = None,
        perception: Perception | None = None,
        layout_seed: int | None = None,
        render_mode: str | None = None,
    ) -> None:
        super().__init__(render_mode)
        self.variant = _check_variant(variant)
        thesis = variant == "thesis"
        if episode not in dyn.GTH_VARIANTS:
            raise ConfigError(f"expected one of {dyn.GTH_VARIANTS}, got {episode!r}", key="episode")
        self.episode = episode
        self._episode_code = dyn.GTH_VARIANTS.index(episode)
        self.layout = gridworld(24, 24) if layout is None else make_layout(layout, seed=layout_seed)
        self.perception = perception if perception is not None else perception_for(variant)
        self.human = None if human is None else _resolve_human(human, "easy")
        named = {"center": _centre(self.layout), "centre": _centre(self.layout)}
        self.robot_cell = _cell_option(robot_cell, self.layout, "robot_cell", {})
        self.human_cell = _cell_option(human_cell, self.layout, "human_cell", named)
        if self.robot_cell == self.human_cell:
            raise ConfigError("robot and human cannot start on the same cell", key="robot_cell")
        self.robot_ori = _direction_option(robot_ori, "robot_ori")
        self.human_ori = _direction_option(human_ori, "human_ori")
        self.max_steps = _check_steps(max_steps if max_steps is not None else (40 if thesis else 20))
        self._hp = (self.human.to_array() if self.human is not None
                    else np.zeros(8, dtype=np.float64))
        self._pcfg = self.perception.to_array()
        self._los = self.layout.los_table()
        self.observation_space = spaces.Discrete(dyn.N_GTH_STATES)
        self.action_space = spaces.Discrete(N_MOVE_ACTIONS)

    def kernel_args(self) -> GthKernelArgs:
        """The fixed inputs of the fused go-to-human loop
        (:func:`simlab.visitlab.training.gth_train_chunk`) as a :data:`GthKernelArgs`."""
        lay = self.layout
        return GthKernelArgs(lay.walls_h, lay.walls_v, self._los, self._pcfg, self._hp,
                             self.human is not None, int(self._episode_code),
                             int(self.robot_cell), int(self.human_cell), int(self.robot_ori),
                             int(self.human_ori), int(self.max_steps))

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
        opt = _reset_options(options, {"robot_cell": self.robot_cell,
                                       "human_cell": self.human_cell,
                                       "robot_ori": self.robot_ori, "human_ori": self.human_ori})
        named = {"center": _centre(self.layout), "centre": _centre(self.layout)}
        robot = _cell_option(opt["robot_cell"], self.layout, "options.robot_cell", {})
        human = _cell_option(opt["human_cell"], self.layout, "options.human_cell", named)
        if robot == human and not self.perception.share_cells:
            raise ConfigError("robot and human cannot start on the same cell",
                              key="options.robot_cell")
        r_ori = _direction_option(opt["robot_ori"], "options.robot_ori")
        h_ori = _direction_option(opt["human_ori"], "options.human_ori")
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
        return self._obs(), float(reward), False, self._t >= self.max_steps, self._info()

    def _scene(self) -> Scene:
        info = self._info()
        return Scene(info["robot_cell"], info["robot_orientation"], info["human_cell"],
                     info["human_orientation"],
                     caption=f"t={self._t} dist={info['distance_class']} "
                             f"facing={info['in_facing_field']}")


def _resolve_human(value: Human | str | None, default: str) -> Human:
    return get_human(default if value is None else value)
