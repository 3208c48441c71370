"""The checks every input goes through: whole numbers, numbers in a range, probabilities,
choices, true/false, files and directories.

One home for the messages, so that every bad value reads the same way wherever it comes
from (a CLI option, a TOML table, a Python keyword): each check raises
:class:`~simlab.base.errors.ConfigError` naming the field (``key``), the file when there is one
(``path``), what was expected and what was found, and returns the value in its canonical
type (``int`` for whole numbers, ``float`` for numbers, :class:`~pathlib.Path` for paths).

NumPy scalars count as the Python numbers they hold; ``True``/``False`` are never numbers
(a TOML ``seed = true`` is a mistake, not 1).
"""

from __future__ import annotations

import math
import numbers
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base.errors import ConfigError

__all__ = [
    "boolean",
    "choice",
    "discount",
    "existing_dir",
    "existing_file",
    "number",
    "positive",
    "probability",
    "whole",
]

Where = str | os.PathLike[str] | None


def _is_whole(value: Any) -> bool:
    # 3.0 is refused like 3.5: a float where a count belongs is a mistake worth a message
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def whole(value: Any, key: str, *, minimum: int | None = 0, maximum: int | None = None,
          path: Where = None, fix: str | None = None) -> int:
    """``value`` as an ``int`` in ``[minimum, maximum]`` (``None``: unbounded).

    Accepts Python and NumPy integers; refuses booleans, floats (also ``3.0``) and strings.
    """
    if not _is_whole(value) or (minimum is not None and int(value) < minimum) \
            or (maximum is not None and int(value) > maximum):
        raise ConfigError(f"expected a whole number{_range(minimum, maximum)}, got {value!r}",
                          key=key, path=path, fix=fix)
    return int(value)


def number(value: Any, key: str, *, low: float | None = None, high: float | None = None,
           low_open: bool = False, high_open: bool = False, path: Where = None,
           fix: str | None = None) -> float:
    """``value`` as a finite ``float`` in the interval given by ``low``/``high``.

    ``low_open``/``high_open`` exclude the bound itself (``low=0, low_open=True``: > 0).
    """
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool) \
        and math.isfinite(float(value))
    if ok:
        v = float(value)
        ok = (low is None or (v > low if low_open else v >= low)) and \
             (high is None or (v < high if high_open else v <= high))
    if not ok:
        raise ConfigError(f"expected a finite number{_interval(low, high, low_open, high_open)}"
                          f", got {value!r}", key=key, path=path, fix=fix)
    return float(value)


def positive(value: Any, key: str, *, allow_zero: bool = False, path: Where = None,
             fix: str | None = None) -> float:
    """A finite number > 0 (``>= 0`` with ``allow_zero``)."""
    return number(value, key, low=0.0, low_open=not allow_zero, path=path, fix=fix)


def probability(value: Any, key: str, *, path: Where = None, fix: str | None = None) -> float:
    """A probability in [0, 1]."""
    if not (isinstance(value, numbers.Real) and not isinstance(value, bool)
            and 0.0 <= float(value) <= 1.0):
        raise ConfigError(f"expected a probability in [0, 1], got {value!r}", key=key,
                          path=path, fix=fix)
    return float(value)


def discount(value: Any, key: str = "gamma", *, path: Where = None) -> float:
    """A discount factor in [0, 1)."""
    if not (isinstance(value, numbers.Real) and not isinstance(value, bool)
            and 0.0 <= float(value) < 1.0):
        raise ConfigError(f"expected a discount factor in [0, 1), got {value!r}", key=key,
                          path=path)
    return float(value)


def boolean(value: Any, key: str, *, path: Where = None) -> bool:
    """``True`` or ``False`` (NumPy booleans too; never 0/1 or strings)."""
    if isinstance(value, bool | np.bool_):
        return bool(value)
    raise ConfigError(f"expected true or false, got {value!r}", key=key, path=path)


def executor(value: Any, key: str = "pool") -> Any:
    """None or an executor (anything with ``submit``, e.g. a ``concurrent.futures`` pool):
    a Python-only option, which a TOML file cannot give."""
    if value is None or callable(getattr(value, "submit", None)):
        return value
    raise ConfigError(f"expected a process executor from Python, got {value!r}", key=key,
                      fix=f"remove {key!r} from the options file (Python callers pass e.g. "
                          "simlab.base.parallel.spawn_worker())")


def choice(value: Any, allowed: Iterable[str], key: str, *, path: Where = None) -> str:
    """One of ``allowed`` (exact, case-sensitive)."""
    allowed = tuple(allowed)
    if not isinstance(value, str) or value not in allowed:
        raise ConfigError(f"expected one of {', '.join(allowed)}; got {value!r}", key=key,
                          path=path)
    return value


def existing_file(value: Any, key: str | None = None, *, what: str = "file",
                  fix: str = "check the path") -> Path:
    """A path to an existing regular file (a directory there is called one, not "not
    found")."""
    p = _path(value, key)
    if not p.is_file():
        problem = f"{what} not found" if not p.exists() else f"expected a {what}, found a " \
            "directory" if p.is_dir() else f"expected a {what}"
        raise ConfigError(problem, path=p, key=key, fix=fix)
    return p


def existing_dir(value: Any, key: str, *, what: str = "directory") -> Path:
    """A path to an existing directory."""
    p = _path(value, key)
    if not p.is_dir():
        problem = f"{what} not found" if not p.exists() else f"expected a {what}, found a file"
        raise ConfigError(problem, path=p, key=key, fix="check the path")
    return p


def spelled_path(value: Any, key: str) -> Any:
    """An optional path option kept as the user spelled it, not made a :class:`Path` (the
    "wrote ..." lines and the records print it as given: ``./f.png`` stays ``./f.png``):
    a non-empty text or path-like, or None; returned unchanged."""
    if value is not None:
        _path(value, key)
    return value


def _path(value: Any, key: str | None) -> Path:
    if not isinstance(value, str | os.PathLike) or not str(value):
        raise ConfigError(f"expected a path, got {value!r}", key=key)
    return Path(value)


def _range(minimum: int | None, maximum: int | None) -> str:
    if minimum is not None and maximum is not None:
        return f" in [{minimum}, {maximum}]"
    if minimum is not None:
        return f" >= {minimum}"
    if maximum is not None:
        return f" <= {maximum}"
    return ""


def _interval(low: float | None, high: float | None, low_open: bool, high_open: bool) -> str:
    parts = []
    if low is not None:
        parts.append(f"{'>' if low_open else '>='} {low:g}")
    if high is not None:
        parts.append(f"{'<' if high_open else '<='} {high:g}")
    return (" " + " and ".join(parts)) if parts else ""


def state_ids(value: Any, key: str) -> tuple[int, ...] | None:
    """State ids given as ``"18,34"``, one integer or a sequence of integers (None stays
    None); each a whole number >= 0, none listed twice. Ranges are the caller's (it knows
    the number of states)."""
    if value is None:
        return None
    if isinstance(value, str):
        items: list[Any] = [p.strip() for p in value.split(",") if p.strip()]
    elif isinstance(value, int | np.integer) and not isinstance(value, bool):
        items = [value]
    else:
        try:
            items = list(value)
        except TypeError:
            items = [value]
    try:
        if any(isinstance(x, bool | float | np.floating) for x in items):
            raise ValueError
        ids = tuple(int(x) for x in items)
    except (TypeError, ValueError):
        raise ConfigError(f"expected state ids such as 18,34, got {value!r}", key=key) \
            from None
    if not ids:
        raise ConfigError("no state given", key=key, fix="e.g. 18 or 18,34")
    if any(i < 0 for i in ids):
        raise ConfigError(f"state ids are >= 0, got {list(ids)}", key=key)
    if len(set(ids)) != len(ids):
        raise ConfigError(f"a state is listed twice in {list(ids)}", key=key)
    return ids


def table_of(cls: Any, value: Any, key: str, *, path: Where = None) -> Any:
    """An instance of the dataclass ``cls`` built from ``value``, a table of a config file
    (a dict of field names): an unknown field or a value of the wrong kind is a
    ConfigError naming ``key.field`` (not a ``TypeError`` from the constructor). Numeric
    fields (a float or int default) need numbers; the constructor's own checks follow."""
    import dataclasses

    if isinstance(value, cls):
        return value
    if not isinstance(value, dict):
        raise ConfigError(f"expected a table of {cls.__name__} fields, got {value!r}",
                          key=key, path=path)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = sorted(set(value) - set(fields))
    if unknown:
        raise ConfigError(f"unknown field(s) {', '.join(unknown)} of {cls.__name__}",
                          key=f"{key}.{unknown[0]}", path=path,
                          fix=f"allowed: {', '.join(fields)}")
    for name, item in value.items():
        default = fields[name].default
        if isinstance(default, int | float) and not isinstance(default, bool):
            number(item, f"{key}.{name}", path=path)
    try:
        return cls(**value)
    except ConfigError as exc:
        raise ConfigError(exc.problem, key=f"{key}.{(exc.key or '').split('.')[-1]}",
                          path=path, fix=exc.fix) from None
    except (TypeError, ValueError) as exc:
        raise ConfigError(str(exc), key=key, path=path) from None

