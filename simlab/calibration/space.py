"""The searched parameters, as data: name, bounds and scale of each.

A :class:`ParameterSpace` maps points of the unit cube ``[0, 1]^d`` (where the optimiser
works) to values of named fields of a parameter record (``PrimitiveParams`` for the physics
simulator, ``KinematicParams`` for the kinematic one). New primitive fields (noise, the
drive-until-state-change mode) are new entries, nothing else. A TOML file::

    [parameters.drive_time]
    low = 0.2
    high = 1.5            # seconds
    [parameters.slow_speed]
    low = 0.05
    high = 0.22
    scale = "log"         # "linear" (default) or "log" (both bounds > 0)
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from simlab import validation
from simlab.errors import ConfigError

SCALES = ("linear", "log")


@dataclass(frozen=True)
class ParamSpec:
    """One searched field: ``low <= value <= high`` on a linear or log scale."""

    name: str
    low: float
    high: float
    scale: str = "linear"

    def __post_init__(self) -> None:
        key = f"parameters.{self.name}"
        for bound in ("low", "high"):
            validation.number(getattr(self, bound), f"{key}.{bound}")
        if not self.low < self.high:
            raise ConfigError(f"low ({self.low}) must be < high ({self.high})", key=key)
        validation.choice(self.scale, SCALES, f"{key}.scale")
        if self.scale == "log" and self.low <= 0:
            raise ConfigError("a log scale needs low > 0", key=key)

    def value(self, u: float) -> float:
        """Value at ``u`` in [0, 1] (clipped)."""
        u = min(max(float(u), 0.0), 1.0)
        if self.scale == "log":
            v = math.exp(math.log(self.low) + u * math.log(self.high / self.low))
            return float(min(max(v, self.low), self.high))  # no rounding past a bound
        return float(self.low + u * (self.high - self.low))

    def unit(self, value: float) -> float:
        """Inverse of :meth:`value` (clipped to [0, 1])."""
        if self.scale == "log":
            u = math.log(max(value, self.low) / self.low) / math.log(self.high / self.low)
        else:
            u = (value - self.low) / (self.high - self.low)
        return min(max(u, 0.0), 1.0)


@dataclass(frozen=True)
class ParameterSpace:
    """Ordered searched fields; ``d = len(specs)``."""

    specs: tuple[ParamSpec, ...]

    def __post_init__(self) -> None:
        if not self.specs:
            raise ConfigError("no parameter to search", key="parameters")
        names = [p.name for p in self.specs]
        if len(set(names)) != len(names):
            raise ConfigError(f"a parameter is listed twice: {names}", key="parameters")

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.specs)

    @property
    def dim(self) -> int:
        return len(self.specs)

    def values(self, u: ArrayLike) -> dict[str, float]:
        """``{name: value}`` of a unit-cube point ``u`` ``(d,)``."""
        u = np.asarray(u, dtype=np.float64).ravel()
        if u.size != self.dim:
            raise ValueError(f"expected {self.dim} coordinates, got {u.size}")
        return {p.name: p.value(x) for p, x in zip(self.specs, u, strict=True)}

    def unit(self, values: Mapping[str, float]) -> NDArray[np.float64]:
        """Unit-cube point ``(d,)`` of ``{name: value}``."""
        return np.array([p.unit(float(values[p.name])) for p in self.specs])

    def check_fields(self, base: Any) -> None:
        """Raise ConfigError unless every name is a numeric field of the record ``base``."""
        fields = {f.name for f in dataclasses.fields(base)}
        for p in self.specs:
            if p.name not in fields:
                raise ConfigError(f"{type(base).__name__} has no field {p.name!r}",
                                  key=f"parameters.{p.name}",
                                  fix="fields: " + ", ".join(sorted(fields)))
            if not isinstance(getattr(base, p.name), int | float):
                raise ConfigError(f"{p.name!r} is not a number", key=f"parameters.{p.name}")

    def apply(self, base: Any, u: ArrayLike) -> Any:
        """``base`` with the fields of point ``u`` replaced (validated by the record)."""
        return dataclasses.replace(base, **self.values(u))

    def to_json(self) -> list[dict[str, Any]]:
        return [dataclasses.asdict(p) for p in self.specs]


def space_from_mapping(table: Mapping[str, Any], *, where: str = "parameters") -> ParameterSpace:
    """A space from ``{name: {low, high, scale}}`` (the ``[parameters]`` TOML table)."""
    if not isinstance(table, Mapping) or not table:
        raise ConfigError("expected a non-empty table of parameters", key=where)
    specs = []
    for name, entry in table.items():
        if not isinstance(entry, Mapping):
            raise ConfigError("expected a table with low and high", key=f"{where}.{name}")
        unknown = set(entry) - {"low", "high", "scale"}
        if unknown or "low" not in entry or "high" not in entry:
            raise ConfigError(f"expected keys low, high[, scale], got {sorted(entry)}",
                              key=f"{where}.{name}")
        specs.append(ParamSpec(str(name), entry["low"], entry["high"],
                               str(entry.get("scale", "linear"))))
    return ParameterSpace(tuple(specs))


def load_space(path: str | os.PathLike[str]) -> ParameterSpace:
    """Read a space TOML file (module docstring); errors name the file and key."""
    from simlab.io import read_toml

    path = Path(path)
    doc = read_toml(path, what="parameter space file")
    try:
        return space_from_mapping(doc.get("parameters", {}))
    except ConfigError as exc:
        raise ConfigError(exc.problem, path=path, key=exc.key, fix=exc.fix) from None


def default_space(primitives: Sequence[int], simulator: str = "physics") -> ParameterSpace:
    """The default search: the drive time, plus what sets blocking (physics) or noise.

    Decision: the speeds are not searched by default. A primitive's length is about
    ``speed * drive_time``, so T alone cannot tell a faster, shorter move from a slower,
    longer one (a ridge the optimiser wanders along); the speeds are the robot's published
    figures, set with ``--primitives``, and can still be searched with ``--space``.
    ``primitives`` (the real actions' simlab primitives) only decides which drive-time
    range makes sense: fast-only tables use a shorter one. Physics adds the obstacle
    detector's margin (it sets the blocked rate); kinematic its two noise levels. The
    decision latency is not searched: it changes the rate of transitions, not T, and is set
    in closed form when the real hours are known.
    """
    prims = np.asarray(primitives)
    high = 2.0 if (prims < 8).any() else 1.2
    specs = [ParamSpec("drive_time", 0.2, high, "log")]
    if simulator == "physics":
        specs.append(ParamSpec("detector_margin", 0.0, 0.15))
    else:
        specs += [ParamSpec("distance_noise", 0.0, 0.5), ParamSpec("heading_noise", 0.0, 0.5)]
    return ParameterSpace(tuple(specs))
