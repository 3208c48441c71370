"""The primitive options shared by the physics commands (``collect``, ``drive``, ``replay``,
``pipeline``): ``--primitives FILE.toml`` and the direct flags that override it.

Inherit :class:`PrimitiveOptions` in a command's config (it is a field group, a frozen
keyword-only dataclass) and call :meth:`PrimitiveOptions.primitive_params`. Every field
defaults to None = "not given": the command's own default parameters apply when none is
given, so a command can tell "no primitive settings" from "the built-in ones".

:class:`TwinEnsembleOptions` adds ``--ensemble`` to the commands whose work comes in
independent units (``collect``'s walks, ``online --arena``'s runs): domain randomisation
over calibrate's twin ensemble, each unit driving one member drawn by
:func:`ensemble_members`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from simlab.base.errors import ConfigError
from simlab.base.options import CommandConfig, option

__all__ = ["ENSEMBLE_STREAM", "PRIMITIVE_FIELDS", "PrimitiveOptions", "TwinEnsembleOptions",
           "ensemble_members"]

_FROM = " (default: from --primitives or built-in)"

#: The direct flags: field names of both this group and ``PrimitiveParams``.
PRIMITIVE_FIELDS = ("drive_time", "slow_speed", "fast_speed", "decision_latency", "mode",
                    "max_drive_time")


@dataclass(frozen=True, kw_only=True)
class PrimitiveOptions(CommandConfig):
    """Primitive settings: a ``[primitives]`` TOML file and per-field overrides (s, m/s)."""

    primitives: Path | None = option(
        None, "primitive settings ([primitives] table; default: built-in PrimitiveParams)",
        metavar="FILE.toml")
    drive_time: float | None = option(
        None, "s of straight driving per primitive (fixed mode)" + _FROM)
    slow_speed: float | None = option(None, "m/s of the slow actions" + _FROM)
    fast_speed: float | None = option(None, "m/s of the fast actions" + _FROM)
    decision_latency: float | None = option(
        None, "s of idle time between primitives" + _FROM)
    mode: str | None = option(None, "primitive mode: fixed or until_state_change" + _FROM,
                              choices=("fixed", "until_state_change"))
    max_drive_time: float | None = option(
        None, "s, timeout of until_state_change" + _FROM)

    @property
    def primitive_options_given(self) -> bool:
        """Whether the file or any direct flag was given."""
        return self.primitives is not None or any(
            getattr(self, f) is not None for f in PRIMITIVE_FIELDS)

    def primitive_params(self):  # -> PrimitiveParams | None
        """The ``PrimitiveParams`` of ``primitives`` (built-in when None) overridden by the
        direct fields; None when none of them is given (the command's default applies).
        The values themselves are checked by ``PrimitiveParams``."""
        if not self.primitive_options_given:
            return None
        from simlab.physics.motion import PrimitiveParams

        base = PrimitiveParams() if self.primitives is None else PrimitiveParams.from_toml(
            self.primitives)
        return base.replace(**{f: getattr(self, f) for f in PRIMITIVE_FIELDS})


#: First spawn key of the member draws (``SeedSequence(seed, spawn_key=(ENSEMBLE_STREAM,
#: unit))``): "twin" in ASCII, far from the keys of collect's walks (``(walk, part)``, walks
#: < 1000) and of online's runs (``(run, k)``), so a member draw never reuses their streams.
ENSEMBLE_STREAM = 0x7477696E


def ensemble_members(seed: int, units: int, size: int) -> list[int]:
    """The member (index into an ensemble of ``size``) of each of ``units`` units of work,
    uniformly: unit ``u`` draws from ``SeedSequence(seed, spawn_key=(ENSEMBLE_STREAM, u))``
    alone, so its member depends on the seed and its own index, not on how many units or
    worker processes there are."""
    import numpy as np

    return [int(np.random.default_rng(np.random.SeedSequence(
        int(seed), spawn_key=(ENSEMBLE_STREAM, u))).integers(size)) for u in range(units)]


@dataclass(frozen=True, kw_only=True)
class TwinEnsembleOptions(PrimitiveOptions):
    """The primitive options and ``--ensemble``: each unit of work (a walk of ``collect``,
    a run of ``online --arena``) drives one member of the ``[[ensemble]]`` of
    ``--primitives`` (the twin ensemble of ``simlab calibrate``), drawn by
    :func:`ensemble_members` from the command's seed. The direct flags override every
    member alike. Off by default: on the ISIR lab the ensemble's pooled data transferred
    only marginally better than the winner's (docs, calibration page)."""

    ensemble: bool = option(
        False, "domain randomisation: each walk (collect) or run (online --arena) drives a "
        "member of the [[ensemble]] of --primitives, calibrate's twin ensemble, drawn by "
        "seed (default: the [primitives] table alone)")

    def check_ensemble(self) -> None:
        """:class:`ConfigError` for ``--ensemble`` without a ``--primitives`` file."""
        if self.ensemble and self.primitives is None:
            raise ConfigError("--ensemble draws from the [[ensemble]] of a primitives file, "
                              "and none is given", key="ensemble",
                              fix="add --primitives lab/calib/primitives.toml (written by "
                              "simlab calibrate), or drop --ensemble")

    def primitive_ensemble(self) -> tuple[Any, ...] | None:
        """The members (``PrimitiveParams``, the winner first) of the ``[[ensemble]]`` of
        ``primitives``, each overridden by the direct fields; None without ``ensemble``.
        A file without ``[[ensemble]]`` is a ConfigError naming it."""
        if not self.ensemble:
            return None
        self.check_ensemble()
        from simlab.physics.motion import PrimitiveParams

        overrides = {f: getattr(self, f) for f in PRIMITIVE_FIELDS}
        return tuple(m.replace(**overrides)
                     for m in PrimitiveParams.ensemble_from_toml(self.primitives))
