"""``simlab drive``: random motion primitives in an arena, headless by default."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from simlab.base import validation
from simlab.base.errors import ConfigError
from simlab.base.io import atomic_write, ensure_new
from simlab.base.options import command, option
from simlab.physics.arena import ArenaConfig
from simlab.physics.driver import DecisionDriver
from simlab.physics.motion import N_ACTIONS, PrimitiveParams
from simlab.physics.primitive_options import PrimitiveOptions
from simlab.physics.rate import rate_option, resolve_rate
from simlab.physics.render import render_topdown
from simlab.physics.world import World


@dataclass(frozen=True)
class DriveSummary:
    """What a random drive did. Distances in metres, times in seconds.

    ``sim_time`` includes the decision latency between primitives; ``stepped_time`` is
    the physics time actually simulated; ``trail`` (steps + 1, 3) the true poses.
    """

    arena: str
    steps: int
    seed: int
    distance: float
    blocked: int
    sim_time: float
    stepped_time: float
    wall_time: float
    trail: NDArray[np.float64]
    png: str | None = None

    @property
    def real_time_factor(self) -> float:
        """Stepped simulated seconds per wall second."""
        return self.stepped_time / self.wall_time if self.wall_time > 0 else float("inf")


@dataclass(frozen=True, kw_only=True)
class DriveConfig(PrimitiveOptions):
    """Options of ``simlab drive`` / :func:`drive`. The primitive options
    (:class:`PrimitiveOptions`) and ``params`` are two ways to give the primitive
    parameters: the flags for the command line, ``params`` (a ``PrimitiveParams`` or a
    ``[primitives]`` TOML path) from Python; giving both is refused."""

    COMMAND = "drive"
    ARGUMENTS = ("arena", "steps", "seed")

    arena: ArenaConfig | str = option("table", "built-in arena name or .toml path")
    steps: int = option(100, "number of primitives")
    seed: int = option(0, "random seed")
    gui: bool = option(False, "open the PyBullet GUI (needs a display)")
    png: Any | None = option(None, "write a top-down picture of the trajectory here")
    overwrite: bool = option(False, "replace an existing --png file")
    progress: bool = option(True, "progress bar (--no-progress hides it)")
    states: Any | None = option(
        None, "states file (JSON of `simlab discretize`); needed by --mode "
        "until_state_change (default: none)")
    params: Any | None = option(
        None, "PrimitiveParams or [primitives] TOML path (Python and TOML only; default: "
        "built-in)", cli=False)
    physics_hz: float | None = rate_option()

    def validate(self) -> None:
        # png stays as spelled: the summary reports it so
        validation.spelled_path(self.png, "png")
        validation.whole(self.steps, "steps")
        resolve_rate(self.physics_hz)
        if self.primitive_options_given and self.params is not None:
            raise ConfigError("give the primitive parameters once: params or the "
                              "primitive options", key="params")
        if self.params is not None and not isinstance(self.params,
                                                      PrimitiveParams | str | os.PathLike):
            raise ConfigError(f"expected a [primitives] TOML path (or, from Python, a "
                              f"PrimitiveParams), got {self.params!r}", key="params",
                              fix='params = "primitives.toml", a file with a [primitives] '
                                  "table")

    def resolved_params(self) -> PrimitiveParams:
        """The primitive parameters of the drive: the primitive options, else ``params``,
        else the built-in ones."""
        if self.primitive_options_given:
            return self.primitive_params()
        if isinstance(self.params, str | os.PathLike):
            return PrimitiveParams.from_toml(self.params)
        return self.params or PrimitiveParams()


@command(DriveConfig)
def drive(cfg: DriveConfig) -> DriveSummary:
    """Execute ``steps`` uniformly random primitives; optionally save a top-down PNG.

    Takes a :class:`DriveConfig` or its fields (``drive("table", 100, 0, png=...)``).
    ``params`` or the primitive options: the primitive parameters (default: built-in).
    ``states``: a states file or discretizer, required by ``mode = "until_state_change"``.
    """
    arena, steps, seed, png = cfg.arena, cfg.steps, cfg.seed, cfg.png
    if png is not None:
        ensure_new(png, overwrite=cfg.overwrite, what="PNG output")
    params = cfg.resolved_params()
    state_of = None
    if params.mode == "until_state_change":
        from simlab.physics.inputs import load_discretizer

        disc = load_discretizer(cfg.states)
        state_of = lambda xy: int(np.asarray(disc.state_of(np.asarray(xy)[None, :2]))[0])  # noqa: E731
    policy_seq, noise_seq = np.random.SeedSequence(seed).spawn(2)
    policy_rng, noise_rng = np.random.default_rng(policy_seq), np.random.default_rng(noise_seq)
    t0 = time.perf_counter()
    def choose(_pose: NDArray[np.float64], _state: int | None) -> int:
        return int(policy_rng.integers(N_ACTIONS))

    with World(arena, gui=cfg.gui, physics_hz=resolve_rate(cfg.physics_hz)) as world:
        driver = DecisionDriver(world, params, watch_state=state_of)
        trail = [world.pose()]
        blocked = 0
        stepped = 0.0
        for _ in tqdm(range(steps), desc="drive", unit="primitive", disable=not cfg.progress):
            res = driver.step(choose, noise_rng).result
            trail.append(res.pose_after)
            blocked += res.blocked
            stepped += res.duration
        wall = time.perf_counter() - t0
        path = np.array(trail)
        distance = float(np.hypot(*np.diff(path[:, :2], axis=0).T).sum()) if steps else 0.0
        if png is not None:
            import cv2

            image = render_topdown(world.arena, world.robot_spec, path[-1], trail=path)
            ok, buf = cv2.imencode(".png", cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
            if not ok:  # pragma: no cover - opencv failure
                raise RuntimeError("PNG encoding failed")
            with atomic_write(png, "wb") as fh:
                fh.write(buf.tobytes())
        return DriveSummary(
            arena=world.arena.name, steps=steps, seed=seed, distance=distance, blocked=blocked,
            sim_time=stepped + steps * params.decision_latency, stepped_time=stepped,
            wall_time=wall, trail=path, png=None if png is None else str(png),
        )
