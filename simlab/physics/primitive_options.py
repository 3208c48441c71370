"""The primitive options shared by the physics commands (``collect``, ``drive``, ``replay``,
``pipeline``): ``--primitives FILE.toml`` and the direct flags that override it.

Inherit :class:`PrimitiveOptions` in a command's config (it is a field group, a frozen
keyword-only dataclass) and call :meth:`PrimitiveOptions.primitive_params`. Every field
defaults to None = "not given": the command's own default parameters apply when none is
given, so a command can tell "no primitive settings" from "the built-in ones".
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from simlab.base.options import CommandConfig, option

__all__ = ["PRIMITIVE_FIELDS", "PrimitiveOptions"]

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
