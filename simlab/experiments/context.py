"""What a runner receives (:class:`RunContext`) and returns (:class:`RunResult`).

See the contract in :mod:`simlab.experiments`.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base.errors import ConfigError


def experiment_seed(root_seed: int, name: str) -> np.random.SeedSequence:
    """The root SeedSequence of experiment ``name``: ``SeedSequence(root_seed,
    spawn_key=(crc32(name),))`` — independent of which other experiments run."""
    return np.random.SeedSequence(int(root_seed), spawn_key=(zlib.crc32(name.encode()),))


@dataclass(frozen=True)
class RunContext:
    """Everything a runner needs besides its params and budget.

    Attributes:
        name: the experiment's name.
        out: its output folder ``DIR/<name>/`` (exists and is empty when the runner starts).
        seed: its root SeedSequence (:func:`experiment_seed`).
        root_seed: the integer seed of the whole reproduction (``--seed``).
        budget_name: ``"quick"`` or ``"full"``.
        cache: ``DIR/_cache/``, shared by the experiments of one output folder.
        progress: whether to show progress bars.
        backend_name: ``"local"`` or ``"ray"``.
        executor: runs :meth:`map` jobs (private to the framework; use :meth:`map`).
        logger: receives :meth:`log` lines (None: silent).
    """

    name: str
    out: Path
    seed: np.random.SeedSequence
    root_seed: int
    budget_name: str
    cache: Path
    progress: bool
    backend_name: str
    executor: Any = field(repr=False)
    logger: Callable[[str], None] | None = field(default=None, repr=False)

    def seeds(self, n: int) -> list[np.random.SeedSequence]:
        """The first ``n`` children of :attr:`seed` (``spawn_key + (i,)``), without
        mutating it: the same list on every call."""
        return [np.random.SeedSequence(self.seed.entropy, spawn_key=(*self.seed.spawn_key, i),
                                       pool_size=self.seed.pool_size) for i in range(int(n))]

    def map(self, fn: Callable[..., Any], kwargs_list: Sequence[Mapping[str, Any]], *,
            desc: str | None = None) -> list[Any]:
        """``[fn(**kw) for kw in kwargs_list]`` run in parallel on the backend, in order.

        ``fn`` must be a module-level function; arguments and results picklable.
        """
        if not callable(fn) or getattr(fn, "__qualname__", "").count("<") > 0:
            raise ValueError("ctx.map needs a module-level function (no lambda or closure)")
        return self.executor.map(fn, [dict(kw) for kw in kwargs_list],
                                 desc=desc or self.name, progress=self.progress)

    @property
    def workers(self) -> int:
        """How many jobs :meth:`map` runs at once."""
        return int(self.executor.workers)

    def log(self, message: str) -> None:
        """One line to the console (prefixed with the experiment's name)."""
        if self.logger is not None:
            self.logger(f"  [{self.name}] {message}")


def _metric_value(key: str, v: Any) -> float | int | bool | None:
    if v is None or isinstance(v, bool):
        return v
    if isinstance(v, np.bool_):
        return bool(v)
    if isinstance(v, int | np.integer):
        return int(v)
    if isinstance(v, float | np.floating):
        f = float(v)
        return None if math.isnan(f) else f
    raise ConfigError(f"metric values must be numbers, booleans or None, got "
                      f"{type(v).__name__}", key=f"metrics.{key}",
                      fix="put structured data in RunResult.details")


@dataclass(frozen=True)
class RunResult:
    """What a runner returns.

    Attributes:
        metrics: flat ``{name: number | bool | None}`` (NaN is stored as None); what the
            ``[[expect]]`` checks read.
        figures: paths of the figures written (under ``ctx.out``).
        notes: sentences for the reader of ``results.md``.
        details: JSON-ready extra data saved in ``result.json``.
    """

    metrics: Mapping[str, float | int | bool | None]
    figures: Sequence[str | Path] = ()
    notes: Sequence[str] = ()
    details: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.metrics, Mapping):
            raise ConfigError("RunResult.metrics must be a mapping", key="metrics")
        clean = {str(k): _metric_value(str(k), v) for k, v in self.metrics.items()}
        object.__setattr__(self, "metrics", clean)
        object.__setattr__(self, "figures", tuple(Path(p) for p in self.figures))
        object.__setattr__(self, "notes", tuple(str(n) for n in self.notes))
