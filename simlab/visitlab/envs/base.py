"""Shared base of the Visit-the-lab Gymnasium envs (thin wrappers over the kernels).

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

from simlab.base.errors import ConfigError
from simlab.visitlab import dynamics as dyn
from simlab.visitlab.grid import Layout
from simlab.visitlab.humans import Human
from simlab.visitlab.humans import human as get_human
from simlab.visitlab.perception import Perception, percepts
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


def check_variant(variant: str) -> str:
    if variant not in VARIANTS:
        raise ConfigError(f"expected one of {VARIANTS}, got {variant!r}", key="variant")
    return variant


#: ``max_steps`` value meaning "the variant's default trial length".
VARIANT_STEPS = "variant"


def check_steps(max_steps: Any, default: int) -> int | None:
    """Trial length: ``"variant"`` -> ``default``; ``None`` -> no limit of the env's own
    (it never truncates; Gymnasium's ``TimeLimit`` does, see
    :data:`simlab.envs.ENV_LIMITS`); else an integer >= 1."""
    if isinstance(max_steps, str) and max_steps == VARIANT_STEPS:
        return default
    if max_steps is None:
        return None
    if isinstance(max_steps, bool) or not isinstance(max_steps, int | np.integer) or max_steps < 1:
        raise ConfigError(f"expected an integer >= 1, None (no limit) or {VARIANT_STEPS!r}, "
                          f"got {max_steps!r}", key="max_steps")
    return int(max_steps)


def fused_steps(max_steps: int | None) -> int:
    """The trial length of a fused loop (which needs one)."""
    if max_steps is None:
        raise ConfigError("the fused training loops need a trial length", key="max_steps",
                          fix="pass max_steps=N (or leave the variant's default)")
    return int(max_steps)


def cell_option(value: Any, layout: Layout, key: str, named: dict[str, int]) -> int:
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


def goal_option(goal: Any, layout: Layout) -> int:
    """A goal label of ``layout``, or ``"random"`` -> -1."""
    if goal == "random":
        return -1
    if isinstance(goal, int | np.integer) and not isinstance(goal, bool) \
            and int(goal) in layout.goal_labels:
        return int(goal)
    raise ConfigError(f"expected 'random' or one of {layout.goal_labels}, got {goal!r}",
                      key="goal")


def direction_option(value: Any, key: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or not 0 <= value < 8:
        raise ConfigError(f"expected a direction 0-7, got {value!r}", key=key)
    return int(value)


def reset_options(options: dict | None, defaults: dict[str, Any]) -> dict[str, Any]:
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


def centre(layout: Layout) -> int:
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


class VisitLabEnv(gym.Env):
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
        self.max_steps: int | None = None

    def _truncated(self) -> bool:
        """The env's own limit reached (never with ``max_steps=None``)."""
        return self.max_steps is not None and self._t >= self.max_steps

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


def resolve_human(value: Human | str | None, default: str) -> Human:
    return get_human(default if value is None else value)
