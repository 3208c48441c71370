"""The physics step: the rate every world steps at, the coarsest rate allowed, and the
solver settings each rate needs.

Measured by ``benchmarks/step_size.py`` (2-core VM, load 4-10; 3 walks of 8,448 transitions
per rate, 128 primitives per setting): each rate and setting against a 960 Hz reference
(the end pose of every primitive, the turn's heading, the pace, the overshoot of the
commanded speeds), the obstacle detector and wall contacts, the LIDAR's scan times, and the
transition matrix of the walk against 200 Hz walks beside its bootstrap floor.

* A coarser step needs more solver iterations. Bullet's iterative solver warm-starts from
  the previous step's impulses, which a coarse step changes more: with 5 iterations, 120 Hz
  primitives last 24 % longer (the braking creeps) and end 15 mm off, 50 Hz ones 40 mm. Too
  many iterations overshoot instead: the converged wheel motors jerk the base past the
  speed limits from rest (200 Hz with 15 or more: 20-35 %; the drive tests allow 5 %).
* In a coarse step the wheels' contact manifolds keep the points of the previous steps,
  lifted off the floor but still handed to the solver (6-8 points instead of 3); a contact
  processing threshold of 0 on the robot leaves them out (no impulse is lost: they are
  separated), so a step costs 20-30 % less below 200 Hz. 200 Hz keeps Bullet's default.
* Each row of :data:`SETTINGS` is the cheapest setting measured as faithful as 200 Hz with 5
  iterations (today's settings, every dataset's before the rate was recorded): primitive
  end positions at most 10 % (+0.5 mm) farther from the reference, headings within the
  primitive tests' 3 degrees, mean duration within 2 %, speed overshoot within 5 %.

=========  ===============  ==============  ===========  =======  ===========  ==========
rate (Hz)  settings         end error max/  walk TV      floor    detector     CPU per
                            mean (mm)       (control     97.5 %   agrees with  transition
                                            0.106)                200 Hz       (x 200 Hz)
=========  ===============  ==============  ===========  =======  ===========  ==========
200        5 it             8.7 / 4.9       0.106        0.108    -            1.00
120        10 it, cpt 0     7.1 / 3.8       0.108        0.108    99.8 %       1.50
100        15 it, cpt 0     6.2 / 3.0       0.108 (*)    0.107    99.5 % (*)   1.68 (*)
60         20 it, cpt 0     7.5 / 3.5       0.111        0.107    99.2 %       2.06
50         30 it, cpt 0     6.8 / 3.3       0.109        0.108    99.5 %       2.19
40         40 it            6.1 / 3.0       0.110        0.107    99.8 %       1.63
=========  ===============  ==============  ===========  =======  ===========  ==========

(*) measured with 10 iterations, the benchmark's choice; at 100 Hz 10 iterations let the
wheel odometry drift 3.2 mm over 0.3 m, past the drive test's 1 %, and 15 (as cheap,
2.5 ms per primitive) pass every test. The tests of tests/physics pass at every row.

The walk's TV is judged by its excess over the control's (200 Hz walks of other seeds,
0.106) against the floor's spread (97.5 % - median, 0.004-0.005): every rate but 60 Hz
(excess 0.005) is indistinguishable from 200 Hz; no rate let the robot through a wall or
stuck in one (deepest penetration 5 mm at 40 Hz, 1.4 mm at 200 Hz), the scans keep their
0.2 s schedule at all of them. The default is 50 Hz: the fastest faithful rate (2.2x the
CPU per transition of 200 Hz); the lowest, 40 Hz, needs 40 iterations and Bullet's contacts
(with the threshold its start overshoots by 5.5 %) and is slower (1.6x). 40 Hz is the
minimum: nothing coarser was measured faithful. 2000 Hz is the maximum: twice the 960 Hz
reference every row was measured against, ten times the finest row. A finer step was never
measured and gains nothing the reference did not show, while every simulated second costs
its rate in steps (1e9 Hz ran until killed).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from simlab.base.errors import ConfigError
from simlab.base.options import option

__all__ = ["DEFAULT_HZ", "MAX_HZ", "MIN_HZ", "RECORDLESS_HZ", "SETTINGS", "StepSettings", "check_rate",
           "rate_option", "resolve_rate", "settings_for"]

#: Physics steps per simulated second of every world unless another rate is asked for:
#: the fastest rate measured faithful (module docstring).
DEFAULT_HZ = 50.0
#: The coarsest rate allowed: the coarsest measured faithful (coarser is refused).
MIN_HZ = 40.0
#: The finest rate allowed: twice the step-size benchmark's 960 Hz reference (module
#: docstring; finer is refused).
MAX_HZ = 2000.0
#: ``(rate Hz, solver iterations, contact processing threshold m or None)``, finest first:
#: a rate takes the settings of the first row at or below it (None: Bullet's default,
#: every point of a contact manifold goes to the solver). Each row is the cheapest setting
#: measured faithful at its rate (module docstring); 200 Hz keeps the settings every
#: dataset had before the rate was a setting.
SETTINGS: tuple[tuple[float, int, float | None], ...] = (
    (200.0, 5, None), (120.0, 10, 0.0), (100.0, 15, 0.0), (60.0, 20, 0.0), (50.0, 30, 0.0),
    (40.0, 40, None))
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
    """``hz`` as a float from :data:`MIN_HZ` to :data:`MAX_HZ` Hz, else :class:`ConfigError`
    naming ``key`` and the range."""
    fix = f"give {MIN_HZ:g} to {MAX_HZ:g} Hz (default {DEFAULT_HZ:g})"
    if isinstance(hz, bool) or not isinstance(hz, int | float) or not math.isfinite(hz):
        raise ConfigError(f"expected a rate in Hz, got {hz!r}", key=key, fix=fix)
    if hz < MIN_HZ - 1e-9:
        raise ConfigError(
            f"{hz:g} Hz is too coarse for the motion primitives: the minimum is {MIN_HZ:g} Hz "
            "(the coarsest rate whose primitives were measured to end where 200 Hz's do); "
            f"the range is {MIN_HZ:g} to {MAX_HZ:g} Hz", key=key, fix=fix)
    if hz > MAX_HZ + 1e-9:
        raise ConfigError(
            f"{hz:g} Hz is finer than any step measured: the maximum is {MAX_HZ:g} Hz (twice "
            "the 960 Hz reference of the step-size benchmark; every simulated second costs "
            f"its rate in steps); the range is {MIN_HZ:g} to {MAX_HZ:g} Hz", key=key, fix=fix)
    return float(hz)


def rate_option() -> Any:
    """The ``--physics-hz`` field of a physics command's config (None: the command's default
    rate; read it with :func:`resolve_rate`)."""
    return option(None, f"physics steps per simulated second (default {DEFAULT_HZ:g}; "
                  f"{MIN_HZ:g} to {MAX_HZ:g})", metavar="HZ")


def resolve_rate(hz: Any, default: float | None = None) -> float:
    """The rate given (``hz``), else ``default``, else :data:`DEFAULT_HZ`; checked
    (:func:`check_rate`)."""
    return check_rate(hz if hz is not None else (DEFAULT_HZ if default is None else default))
