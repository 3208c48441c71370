"""The experiment TOML schema: loading, validation and the checks (``[[expect]]``).

See the contract in :mod:`simlab.experiments` for the file format. Everything here is
pure: :func:`load_experiment` reads one file into a frozen :class:`ExperimentSpec`
(raising :class:`~simlab.base.errors.ConfigError` naming the file and the key), and
:meth:`Check.evaluate` compares a runner's metrics with one check.
"""

from __future__ import annotations

import math
import os
import re
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from simlab.base import validation
from simlab.base.errors import ConfigError
from simlab.base.io import NESTED_TOO_DEEPLY

BUDGETS = ("quick", "full")
#: Operators comparing a metric with a number.
NUMBER_OPS = (">=", ">", "<=", "<", "==", "approx")
#: Operators comparing a metric with another metric (times ``factor``).
METRIC_OPS = ("greater_than_metric", "less_than_metric")
OPS = (*NUMBER_OPS, "between", *METRIC_OPS)

_NAME = re.compile(r"^[a-z0-9][a-z0-9_.-]*$")
_RUNNER = re.compile(r"^[a-z0-9_]+\.[a-z0-9_.]+$")
_TOP_KEYS = {"name", "title", "reference", "claim", "runner", "params", "budget", "expect"}
_REQUIRED = ("name", "title", "reference", "claim", "runner")
_CHECK_KEYS = {"metric", "op", "value", "thesis", "budgets", "tol", "rel_tol", "factor"}

PASS, FAIL, NOT_CHECKED = "PASS", "FAIL", "not checked"


@dataclass(frozen=True)
class CheckOutcome:
    """One check evaluated on one run: ``status`` PASS, FAIL or "not checked"; ``ours``
    the metric's value (None if missing); ``detail`` a short human explanation."""

    status: str
    ours: float | None
    detail: str


@dataclass(frozen=True)
class Check:
    """One ``[[expect]]`` table.

    Attributes:
        metric: name of the runner metric compared.
        op: one of :data:`OPS`.
        value: a number, ``(low, high)`` for ``between``, a metric name for ``*_metric``.
        thesis: the thesis statement the check encodes (shown in ``results.md``).
        budgets: budgets at which the check applies.
        tol, rel_tol: tolerances of ``approx`` (absolute, relative).
        factor: multiplier of the other metric for ``*_metric`` operators.
    """

    metric: str
    op: str
    value: Any
    thesis: str
    budgets: tuple[str, ...] = BUDGETS
    tol: float = 0.0
    rel_tol: float = 0.0
    factor: float = 1.0

    def describe(self) -> str:
        """The check in symbols, e.g. ``fast_minus_slow_bits > 0``."""
        if self.op == "between":
            lo, hi = self.value
            return f"{format_number(lo)} <= {self.metric} <= {format_number(hi)}"
        if self.op == "approx":
            tol = []
            if self.tol:
                tol.append(f"± {format_number(self.tol)}")
            if self.rel_tol:
                tol.append(f"± {self.rel_tol:.0%}")
            return f"{self.metric} ≈ {format_number(self.value)} ({' or '.join(tol)})"
        if self.op in METRIC_OPS:
            sym = ">" if self.op == "greater_than_metric" else "<"
            other = (self.value if self.factor == 1.0
                     else f"{format_number(self.factor)} × {self.value}")
            return f"{self.metric} {sym} {other}"
        return f"{self.metric} {self.op} {format_number(self.value)}"

    def evaluate(self, metrics: Mapping[str, Any], budget: str) -> CheckOutcome:
        """Compare ``metrics[self.metric]`` with the check at ``budget``."""
        ours = _as_float(metrics.get(self.metric))
        if budget not in self.budgets:
            return CheckOutcome(NOT_CHECKED, ours,
                                f"checked at the {'/'.join(self.budgets)} budget only")
        if self.metric not in metrics:
            return CheckOutcome(FAIL, None, f"the runner returned no metric {self.metric!r}")
        if ours is None or math.isnan(ours):
            return CheckOutcome(FAIL, None, f"{self.metric} has no value")
        if self.op in METRIC_OPS:
            other = _as_float(metrics.get(self.value))
            if other is None or math.isnan(other):
                return CheckOutcome(FAIL, ours, f"the metric {self.value!r} has no value")
            bound = self.factor * other
            ok = ours > bound if self.op == "greater_than_metric" else ours < bound
            return CheckOutcome(PASS if ok else FAIL, ours,
                                f"{format_number(ours)} vs {format_number(bound)}")
        ok = _compare(self.op, ours, self.value, self.tol, self.rel_tol)
        return CheckOutcome(PASS if ok else FAIL, ours, f"{format_number(ours)}")


def _compare(op: str, x: float, v: Any, tol: float, rel_tol: float) -> bool:
    if op == ">=":
        return x >= v
    if op == ">":
        return x > v
    if op == "<=":
        return x <= v
    if op == "<":
        return x < v
    if op == "==":
        return x == v
    if op == "approx":
        return abs(x - v) <= max(tol, rel_tol * abs(v))
    if op == "between":
        return v[0] <= x <= v[1]
    raise AssertionError(op)  # validated on load


def _as_float(v: Any) -> float | None:
    if v is None or isinstance(v, str):
        return None
    try:
        return float(v)
    except (TypeError, ValueError):
        return None


def format_number(v: Any) -> str:
    """A number for people: integers as such, otherwise 4 significant digits."""
    if isinstance(v, bool) or v is None or isinstance(v, str):
        return str(v)
    f = float(v)
    if math.isnan(f):
        return "NaN"
    if math.isinf(f):
        return "inf" if f > 0 else "-inf"
    if f == int(f) and abs(f) < 1e15:
        return f"{int(f):,}" if abs(f) >= 10000 else str(int(f))
    if abs(f) >= 1000:
        return f"{f:,.0f}"
    return f"{f:.4g}"


@dataclass(frozen=True)
class ExperimentSpec:
    """One experiment file, validated.

    Attributes:
        name: unique name, also the output folder.
        title, reference, claim: what the result is, where in the thesis, its claim.
        runner: registry key of the runner.
        params: the ``[params]`` table.
        budgets: ``{"quick": {...}, "full": {...}}``, each with ``seeds`` >= 1.
        checks: the ``[[expect]]`` tables.
        path: the file read.
    """

    name: str
    title: str
    reference: str
    claim: str
    runner: str
    params: Mapping[str, Any] = field(default_factory=dict)
    budgets: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    checks: tuple[Check, ...] = ()
    path: Path | None = None

    def budget(self, name: str) -> dict[str, Any]:
        """A copy of the ``[budget.<name>]`` table."""
        if name not in BUDGETS:
            raise ConfigError(f"unknown budget {name!r}", key="budget",
                              fix=f"choose one of {', '.join(BUDGETS)}")
        return dict(self.budgets[name])


def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _parse_check(raw: Any, i: int, path: Path) -> Check:
    where = f"expect[{i}]"
    if not isinstance(raw, dict):
        raise ConfigError("expected a table ([[expect]])", path=path, key=where)
    unknown = sorted(set(raw) - _CHECK_KEYS)
    if unknown:
        raise ConfigError(f"unknown key(s) {', '.join(unknown)}", path=path, key=where,
                          fix=f"allowed: {', '.join(sorted(_CHECK_KEYS))}")
    for key in ("metric", "op", "value", "thesis"):
        if key not in raw:
            raise ConfigError("missing", path=path, key=f"{where}.{key}")
    metric, op, value, thesis = raw["metric"], raw["op"], raw["value"], raw["thesis"]
    if not isinstance(metric, str) or not metric:
        raise ConfigError("expected a metric name", path=path, key=f"{where}.metric")
    if not isinstance(thesis, str) or not thesis.strip():
        raise ConfigError("expected the thesis statement the check encodes", path=path,
                          key=f"{where}.thesis")
    if op not in OPS:
        raise ConfigError(f"unknown operator {op!r}", path=path, key=f"{where}.op",
                          fix=f"choose one of {', '.join(OPS)}")
    if op in NUMBER_OPS and not _is_number(value):
        raise ConfigError(f"operator {op!r} needs a number, got {value!r}", path=path,
                          key=f"{where}.value")
    if op == "between":
        if not (isinstance(value, list) and len(value) == 2 and all(map(_is_number, value))
                and value[0] <= value[1]):
            raise ConfigError(f"'between' needs [low, high] with low <= high, got {value!r}",
                              path=path, key=f"{where}.value")
        value = (value[0], value[1])
    if op in METRIC_OPS and (not isinstance(value, str) or not value):
        raise ConfigError(f"operator {op!r} needs the name of another metric, got {value!r}",
                          path=path, key=f"{where}.value")
    tol = raw.get("tol", 0.0)
    rel_tol = raw.get("rel_tol", 0.0)
    for key, v in (("tol", tol), ("rel_tol", rel_tol)):
        validation.number(v, f"{where}.{key}", low=0.0, path=path)
    if ("tol" in raw or "rel_tol" in raw) and op != "approx":
        raise ConfigError("tol/rel_tol apply to op = 'approx' only", path=path, key=where)
    if op == "approx" and tol == 0 and rel_tol == 0:
        raise ConfigError("'approx' needs tol or rel_tol > 0", path=path, key=where,
                          fix="use op = '==' for an exact comparison")
    factor = raw.get("factor", 1.0)
    validation.number(factor, f"{where}.factor", path=path)
    if "factor" in raw and op not in METRIC_OPS:
        raise ConfigError(f"factor applies to {' and '.join(METRIC_OPS)} only", path=path,
                          key=f"{where}.factor")
    budgets = raw.get("budgets", list(BUDGETS))
    if (not isinstance(budgets, list) or not budgets
            or any(b not in BUDGETS for b in budgets)):
        raise ConfigError(f"expected a non-empty list of {', '.join(BUDGETS)}, got {budgets!r}",
                          path=path, key=f"{where}.budgets")
    return Check(metric=metric, op=op, value=value, thesis=thesis.strip(),
                 budgets=tuple(b for b in BUDGETS if b in budgets), tol=float(tol),
                 rel_tol=float(rel_tol), factor=float(factor))


def parse_experiment(data: Mapping[str, Any], path: str | os.PathLike[str]) -> ExperimentSpec:
    """Validate a parsed TOML document (``path`` is used in error messages)."""
    path = Path(path)
    unknown = sorted(set(data) - _TOP_KEYS)
    if unknown:
        raise ConfigError(f"unknown key(s) {', '.join(unknown)}", path=path,
                          fix=f"allowed: {', '.join(sorted(_TOP_KEYS))}")
    for key in _REQUIRED:
        if key not in data:
            raise ConfigError("missing", path=path, key=key)
        if not isinstance(data[key], str) or not data[key].strip():
            raise ConfigError(f"expected a non-empty string, got {data[key]!r}", path=path,
                              key=key)
    name = data["name"]
    if not _NAME.match(name):
        raise ConfigError(f"{name!r}: use lower-case letters, digits, '_', '.', '-'",
                          path=path, key="name")
    runner = data["runner"]
    if not _RUNNER.match(runner):
        raise ConfigError(f"{runner!r} is not a runner key of the form 'group.name'",
                          path=path, key="runner")
    params = data.get("params", {})
    if not isinstance(params, dict):
        raise ConfigError("expected a table [params]", path=path, key="params")
    budget = data.get("budget")
    if not isinstance(budget, dict):
        raise ConfigError("missing: [budget.quick] and [budget.full]", path=path, key="budget")
    unknown = sorted(set(budget) - set(BUDGETS))
    if unknown:
        raise ConfigError(f"unknown budget(s) {', '.join(unknown)}", path=path, key="budget",
                          fix=f"use {' and '.join(BUDGETS)}")
    budgets: dict[str, dict[str, Any]] = {}
    for b in BUDGETS:
        table = budget.get(b)
        if not isinstance(table, dict):
            raise ConfigError("missing table", path=path, key=f"budget.{b}")
        seeds = table.get("seeds")
        if seeds is None:
            raise ConfigError("missing", path=path, key=f"budget.{b}.seeds")
        validation.whole(seeds, f"budget.{b}.seeds", minimum=1, path=path)
        budgets[b] = dict(table)
    raw_checks = data.get("expect", [])
    if not isinstance(raw_checks, list):
        raise ConfigError("expected an array of tables [[expect]]", path=path, key="expect")
    checks = tuple(_parse_check(c, i, path) for i, c in enumerate(raw_checks))
    return ExperimentSpec(name=name, title=data["title"].strip(),
                          reference=data["reference"].strip(), claim=data["claim"].strip(),
                          runner=runner, params=dict(params), budgets=budgets, checks=checks,
                          path=path)


def load_experiment(path: str | os.PathLike[str], *, resolve_runner: bool = False
                    ) -> ExperimentSpec:
    """Read and validate one experiment TOML.

    With ``resolve_runner`` the runner key is also looked up in the registry (importing its
    module), so an unknown runner fails here, naming the file.
    """
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except FileNotFoundError:
        raise ConfigError("no such experiment file", path=path) from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"not valid TOML: {exc}", path=path) from None
    except RecursionError:
        raise ConfigError(NESTED_TOO_DEEPLY, path=path) from None
    spec = parse_experiment(data, path)
    if resolve_runner:
        from simlab.experiments.registry import get_runner

        try:
            get_runner(spec.runner)
        except ConfigError as exc:
            raise ConfigError(exc.problem, path=path, key="runner", fix=exc.fix) from None
    return spec


def default_experiments_dir() -> Path:
    """The repository's ``experiments/`` folder (or the packaged copy in a wheel)."""
    here = Path(__file__).resolve().parent
    packaged = here.parent / "_assets" / "experiments"
    if packaged.is_dir():
        return packaged
    return here.parent.parent / "experiments"


def discover_experiments(source: str | os.PathLike[str] | Sequence[str | os.PathLike[str]]
                         | None = None, *, resolve_runner: bool = False
                         ) -> list[ExperimentSpec]:
    """Every experiment of a folder (its ``*.toml``, sorted by name) or of a list of files.

    ``None`` reads :func:`default_experiments_dir`. Names must be unique.
    """
    if source is None:
        source = default_experiments_dir()
    if isinstance(source, str | os.PathLike):
        src = Path(source)
        if src.is_dir():
            files = sorted(src.glob("*.toml"))
        elif src.is_file():
            files = [src]
        else:
            raise ConfigError("no such experiments folder or file", path=src,
                              key="experiments")
    else:
        files = [Path(p) for p in source]
    specs = [load_experiment(f, resolve_runner=resolve_runner) for f in files]
    seen: dict[str, Path | None] = {}
    for s in specs:
        if s.name in seen:
            raise ConfigError(f"name {s.name!r} is also used by {seen[s.name]}", path=s.path,
                              key="name")
        seen[s.name] = s.path
    return sorted(specs, key=lambda s: natural_key(s.name))


def natural_key(name: str) -> list[Any]:
    """``fig4_10`` after ``fig4_9``: digit runs compare as numbers."""
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name)]


def select(specs: Sequence[ExperimentSpec], only: str | Sequence[str] | None
           ) -> list[ExperimentSpec]:
    """The experiments named in ``only`` (``"a,b"`` or a list; None: all), in file order."""
    if only is None:
        return list(specs)
    names = [n.strip() for n in only.split(",")] if isinstance(only, str) else list(only)
    names = [n for n in names if n]
    if not names:
        raise ConfigError("no experiment named", key="only")
    known = {s.name for s in specs}
    missing = [n for n in names if n not in known]
    if missing:
        raise ConfigError(f"unknown experiment(s) {', '.join(missing)}", key="only",
                          fix=f"known: {', '.join(s.name for s in specs)}")
    return [s for s in specs if s.name in names]
