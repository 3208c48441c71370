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
from typing import Any

from simlab.base.errors import ConfigError
from simlab.base.options import option

__all__ = ["DEFAULT_HZ", "ITERATIONS", "MIN_HZ", "RECORDLESS_HZ", "check_rate",
           "iterations_for", "rate_option", "rate_record", "resolve_rate"]

#: Physics steps per simulated second of every world unless another rate is asked for.
DEFAULT_HZ = 200.0
#: The coarsest rate allowed: the primitives' heading control ticks at 60 Hz
#: (``PrimitiveParams.fine_hz``), and a control tick cannot be shorter than a step.
MIN_HZ = 60.0
#: ``(rate Hz, solver iterations)``, finest first: a rate takes the iterations of the
#: first row at or below it.
ITERATIONS: tuple[tuple[float, int], ...] = ((200.0, 5), (120.0, 10), (60.0, 20))
#: The rate of every physics dataset whose manifest predates the rate's record.
RECORDLESS_HZ = 200.0


def iterations_for(hz: float) -> int:
    """The solver iterations a step of ``hz`` Hz needs (:data:`ITERATIONS`)."""
    for rate, iterations in ITERATIONS:
        if hz >= rate - 1e-9:
            return iterations
    return ITERATIONS[-1][1]


def check_rate(hz: Any, key: str = "physics_hz") -> float:
    """``hz`` as a float of at least :data:`MIN_HZ` Hz, else :class:`ConfigError` naming
    ``key`` and the minimum."""
    if isinstance(hz, bool) or not isinstance(hz, int | float) or not math.isfinite(hz):
        raise ConfigError(f"expected a rate in Hz, got {hz!r}", key=key,
                          fix=f"give {MIN_HZ:g} Hz or more (default {DEFAULT_HZ:g})")
    if hz < MIN_HZ - 1e-9:
        raise ConfigError(
            f"{hz:g} Hz is too coarse for the motion primitives: the minimum is {MIN_HZ:g} Hz "
            f"(their heading control ticks at {MIN_HZ:g} Hz and a tick cannot be shorter "
            "than a physics step)", key=key, fix=f"give {MIN_HZ:g} Hz or more "
            f"(default {DEFAULT_HZ:g})")
    return float(hz)


def rate_record(hz: float, iterations: int) -> dict[str, Any]:
    """The JSON record of a physics step (manifests, reports)."""
    return {"hz": float(hz), "solver_iterations": int(iterations)}


def rate_option() -> Any:
    """The ``--physics-hz`` field of a physics command's config (None: the command's default
    rate; read it with :func:`resolve_rate`)."""
    return option(None, f"physics steps per simulated second (default {DEFAULT_HZ:g}; at least "
                  f"{MIN_HZ:g}: the primitives' control rate)", metavar="HZ")


def resolve_rate(hz: Any, default: float | None = None) -> float:
    """The rate given (``hz``), else ``default``, else :data:`DEFAULT_HZ`; checked
    (:func:`check_rate`)."""
    return check_rate(hz if hz is not None else (DEFAULT_HZ if default is None else default))
