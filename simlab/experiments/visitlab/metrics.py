"""Metrics of the Visit-the-lab results: learning-curve metrics (package docstring),
the greedy-policy success of a navigation Q table, correlation."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from simlab.base.errors import ConfigError
from simlab.experiments.visitlab.runs import as_table


def curve_metrics(label: str, returns: np.ndarray, thresholds: Sequence[float] = (),
                  windows: Mapping[str, Sequence[float]] | None = None) -> dict[str, Any]:
    """The curve metrics of one run (module docstring), ``returns`` ``(seeds, trials)``."""
    from simlab.visitlab.curves import smooth_curve

    returns = np.asarray(returns, dtype=np.float64)
    n_trials = returns.shape[1]
    tail = max(1, n_trials // 10)
    per_seed = returns[:, -tail:].mean(axis=1)
    plateau = float(per_seed.mean())
    x, mean, std = smooth_curve(returns)
    out: dict[str, Any] = {
        f"{label}_plateau": plateau,
        f"{label}_std": float(std[-min(10, std.size):].mean()),
        f"{label}_seed_std": float(per_seed.std()),
    }
    hit = np.flatnonzero(mean >= 0.9 * plateau) if plateau > 0 else np.zeros(0, dtype=int)
    out[f"{label}_trials_to_90pct"] = int(x[hit[0]]) if hit.size else None
    for thr in thresholds:
        hit = np.flatnonzero(mean >= thr)
        out[f"{label}_trials_to_{fmt_number(thr)}"] = int(x[hit[0]]) if hit.size else None
    for name, (lo, hi) in (windows or {}).items():
        a = round(lo * n_trials)
        b = max(round(hi * n_trials), a + 1)
        out[f"{label}_{name}"] = float(returns[:, a:b].mean())
    return out


def fmt_number(x: float) -> str:
    return str(int(x)) if float(x) == int(x) else f"{x:g}"


def curve_details(label: str, returns: np.ndarray) -> dict[str, Any]:
    from simlab.visitlab.curves import smooth_curve

    x, mean, std = smooth_curve(returns)
    return {"x": x.tolist(), "mean": np.round(mean, 4).tolist(), "std": np.round(std, 4).tolist()}


def windows_param(params: Mapping[str, Any]) -> dict[str, tuple[float, float]]:
    raw = as_table(params.get("windows"), "params.windows")
    out = {}
    for name, v in raw.items():
        if not (isinstance(v, list) and len(v) == 2 and all(isinstance(x, int | float) for x in v)
                and 0 <= v[0] < v[1] <= 1):
            raise ConfigError(f"expected [lo, hi] with 0 <= lo < hi <= 1, got {v!r}",
                              key=f"params.windows.{name}")
        out[str(name)] = (float(v[0]), float(v[1]))
    return out


def thresholds_param(params: Mapping[str, Any]) -> list[float]:
    raw = params.get("thresholds", [])
    if not isinstance(raw, list) or not all(isinstance(x, int | float) and not isinstance(x, bool)
                                            for x in raw):
        raise ConfigError(f"expected a list of numbers, got {raw!r}", key="params.thresholds")
    return [float(x) for x in raw]


# --------------------------------------------------------------------------- visitlab.curves


def greedy_success(nxt: np.ndarray, labels: np.ndarray, q: np.ndarray, goal: int,
                   horizon: int) -> float:
    """Fraction of the cells outside room ``goal`` from which following ``argmax_a q``
    (first maximiser) reaches the room within ``horizon`` moves; ``q`` ``(n_cells, 25)``,
    ``nxt`` the layout's move table."""
    best = q.argmax(axis=1)
    cells = np.flatnonzero(labels != goal)
    pos = cells.copy()
    done = np.zeros(cells.size, dtype=bool)
    for _ in range(horizon):
        pos = nxt[pos, best[pos]]
        done |= labels[pos] == goal
    return float(done.mean()) if cells.size else 1.0


def pearson(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson correlation of two 1-D arrays of one length; NaN when one is constant."""
    if a.std() == 0 or b.std() == 0:
        return math.nan
    return float(np.corrcoef(a, b)[0, 1])


# --------------------------------------------------------------------------- modules
