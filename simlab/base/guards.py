"""The ONE memory-estimate guard: refuse a request before allocating it.

A 2 km arena mapped at 1 cm, a 100000 x 100000 grid, 10^12 trials or a count table of a
huge state count would otherwise end in a ``MemoryError`` (or the OOM killer) after
minutes of work. Callers estimate the bytes their request needs from its shape and call
:func:`check_memory` first; the refusal names the field and the figure.

Decision: the budget is half of the memory the kernel
reports as available (``MemAvailable`` in ``/proc/meminfo``, else the physical memory,
else 8 GiB), overridable with the environment variable ``SIMLAB_MEMORY_LIMIT`` (bytes,
or with a K/M/G/T suffix). A run is refused only when its dominant arrays alone exceed it,
so the estimate is a lower bound and the guard never refuses a run that would fit.
"""

from __future__ import annotations

import math
import os

from simlab.base.errors import ConfigError

__all__ = ["array_bytes", "check_memory", "format_bytes", "memory_budget"]

_SUFFIXES = {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}


def _parse_bytes(text: str) -> int:
    text = text.strip().upper().removesuffix("B").removesuffix("I")
    suffix = text[-1] if text and text[-1] in _SUFFIXES else ""
    number = text[: len(text) - len(suffix)]
    try:
        value = float(number) * _SUFFIXES[suffix]
    except ValueError:
        raise ConfigError(f"expected a number of bytes such as 4G, got {text!r}",
                          key="SIMLAB_MEMORY_LIMIT") from None
    if not (math.isfinite(value) and value > 0):
        raise ConfigError(f"expected a size > 0, got {text!r}", key="SIMLAB_MEMORY_LIMIT")
    return int(value)


def _available_bytes() -> int:
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return 8 << 30


def memory_budget() -> int:
    """Bytes a single request may allocate (see the module docstring)."""
    env = os.environ.get("SIMLAB_MEMORY_LIMIT")
    if env:
        return _parse_bytes(env)
    return _available_bytes() // 2


def format_bytes(n: float) -> str:
    """``1.5 GiB``-style text of a byte count."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if abs(n) < 1024 or unit == "PiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.1f} EiB"  # pragma: no cover


def array_bytes(shape: tuple[float, ...], itemsize: int = 8) -> float:
    """Bytes of an array of ``shape`` (floats allowed, so huge shapes do not overflow)."""
    total = float(itemsize)
    for n in shape:
        total *= max(float(n), 0.0)
    return total


def check_memory(nbytes: float, *, what: str, key: str | None = None,
                 fix: str = "ask for less", path: str | os.PathLike[str] | None = None) -> None:
    """Raise :class:`ConfigError` if ``nbytes`` exceeds :func:`memory_budget`.

    Args:
        nbytes: estimated bytes of the request's dominant arrays.
        what: what would be allocated, e.g. ``"a 200000 x 200000 occupancy grid"``.
        key: the option or field the user can change.
        fix: how to ask for less.
        path: the file the request came from, if any.
    """
    budget = memory_budget()
    if not math.isfinite(nbytes) or nbytes > budget:
        raise ConfigError(
            f"{what} needs about {format_bytes(nbytes)}, more than the "
            f"{format_bytes(budget)} this machine can give (SIMLAB_MEMORY_LIMIT)",
            key=key, fix=fix, path=path,
        )
