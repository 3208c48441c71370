"""The physics step: the rate every world steps at, the coarsest rate the primitives allow,
and the solver iterations each rate needs.

Measured by ``benchmarks/step_size.py`` (each rate against a 960 Hz reference: the end pose
of every primitive, the obstacle detector and wall contacts, the LIDAR's scan times, and
the transition matrix of a fixed-budget walk against the 200 Hz one beside its bootstrap
floor). Its figures are in the README's speed table and in :data:`DEFAULT_HZ`'s comment.

A coarser step needs more solver iterations: Bullet's iterative solver (projected
Gauss-Seidel) warm-starts from the previous step's impulses, which a coarse step changes
more, so the wheel motors converge less per iteration; with too few the turns in place
drift, the braking creeps for longer and every primitive ends elsewhere.
:data:`ITERATIONS` gives each rate the fewest iterations whose primitives end no farther
from the reference than 200 Hz with 5 iterations (the settings the datasets before the rate
was recorded were made with, :data:`RECORDLESS_HZ`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from simlab.base.errors import ConfigError
from simlab.base.options import option

__all__ = ["DEFAULT_HZ", "MIN_HZ", "RECORDLESS_HZ", "SETTINGS", "StepSettings", "check_rate",
           "rate_option", "resolve_rate", "settings_for"]

#: Physics steps per simulated second of every world unless another rate is asked for.
DEFAULT_HZ = 200.0
#: The coarsest rate allowed (measured faithful with its settings; coarser is refused).
MIN_HZ = 40.0
#: ``(rate Hz, solver iterations, contact processing threshold m or None)``, finest first:
#: a rate takes the settings of the first row at or below it (None: Bullet's default,
#: every point of a contact manifold goes to the solver).
SETTINGS: tuple[tuple[float, int, float | None], ...] = (
    (200.0, 5, None), (100.0, 10, 0.0), (50.0, 20, 0.0), (40.0, 40, 0.0))
#: The rate of every physics dataset whose manifest predates the rate's record.
RECORDLESS_HZ = 200.0


@dataclass(frozen=True)
class StepSettings:
    """What a physics step is: ``hz`` steps per simulated second, the constraint solver's
    ``solver_iterations`` and the robot's ``contact_threshold`` (m: the manifold points
    farther apart than this are left out of the solver; None: Bullet's default, all)."""

    hz: float
    solver_iterations: int
    contact_threshold: float | None

    def to_json(self) -> dict[str, Any]:
        """The record of manifests and reports."""
        return {"hz": self.hz, "solver_iterations": self.solver_iterations,
                "contact_threshold": self.contact_threshold}


def settings_for(hz: float) -> StepSettings:
    """The settings a step of ``hz`` Hz needs (:data:`SETTINGS`; a rate between two rows
    takes the coarser row's, a rate below the last its)."""
    row = next((r for r in SETTINGS if hz >= r[0] - 1e-9), SETTINGS[-1])
    return StepSettings(float(hz), row[1], row[2])


def check_rate(hz: Any, key: str = "physics_hz") -> float:
    """``hz`` as a float of at least :data:`MIN_HZ` Hz, else :class:`ConfigError` naming
    ``key`` and the minimum."""
    if isinstance(hz, bool) or not isinstance(hz, int | float) or not math.isfinite(hz):
        raise ConfigError(f"expected a rate in Hz, got {hz!r}", key=key,
                          fix=f"give {MIN_HZ:g} Hz or more (default {DEFAULT_HZ:g})")
    if hz < MIN_HZ - 1e-9:
        raise ConfigError(
            f"{hz:g} Hz is too coarse for the motion primitives: the minimum is {MIN_HZ:g} Hz "
            "(the coarsest rate whose primitives were measured to end where 200 Hz's do)",
            key=key, fix=f"give {MIN_HZ:g} Hz or more (default {DEFAULT_HZ:g})")
    return float(hz)


def rate_option() -> Any:
    """The ``--physics-hz`` field of a physics command's config (None: the command's default
    rate; read it with :func:`resolve_rate`)."""
    return option(None, f"physics steps per simulated second (default {DEFAULT_HZ:g}; at least "
                  f"{MIN_HZ:g})", metavar="HZ")


def resolve_rate(hz: Any, default: float | None = None) -> float:
    """The rate given (``hz``), else ``default``, else :data:`DEFAULT_HZ`; checked
    (:func:`check_rate`)."""
    return check_rate(hz if hz is not None else (DEFAULT_HZ if default is None else default))
