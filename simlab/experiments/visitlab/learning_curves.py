"""``visitlab.curves``: learning curves of several training runs (thesis Figs. 4.1, 4.2,
4.4-4.6, poster Fig. 4)."""

from __future__ import annotations

import json
from typing import Any

from simlab.base.errors import ConfigError
from simlab.experiments.context import RunContext, RunResult
from simlab.experiments.registry import runner
from simlab.experiments.visitlab.metrics import (
    curve_details,
    curve_metrics,
    thresholds_param,
    windows_param,
)
from simlab.experiments.visitlab.runs import as_table, cache_note, get_runs, param_notes, parse_run


@runner("visitlab.curves")
def curves(params: dict[str, Any], budget: dict[str, Any], ctx: RunContext) -> RunResult:
    """Learning curves of the runs ``[[params.runs]]`` (module docstring).

    ``params.panels`` (optional): ``[{title = "...", runs = ["label", ...]}, ...]``
    (default: one panel with every run); ``params.title``; ``params.ylabel``;
    ``params.thresholds``, ``params.windows``: extra curve metrics. Metrics: the curve
    metrics of every run, plus ``trials`` and ``seeds``. Figure: ``curves.png``.
    """
    raw_runs = params.get("runs")
    if not isinstance(raw_runs, list) or not raw_runs:
        raise ConfigError("expected one or more [[params.runs]] tables", key="params.runs")
    specs = [parse_run(r, f"params.runs[{i}]", params, budget) for i, r in enumerate(raw_runs)]
    labels = [s.label for s in specs]
    if len(set(labels)) != len(labels):
        raise ConfigError(f"run labels must be unique, got {labels}", key="params.runs")
    thresholds, windows = thresholds_param(params), windows_param(params)
    runs = get_runs(ctx, specs)
    by_label = {r.spec.label: r for r in runs}
    metrics: dict[str, Any] = {}
    details: dict[str, Any] = {"curves": {}}
    for r in runs:
        metrics.update(curve_metrics(r.spec.label, r.returns, thresholds, windows))
        details["curves"][r.spec.label] = curve_details(r.spec.label, r.returns)
    metrics["seeds"] = specs[0].seeds
    panels_raw = params.get("panels") or [{"title": "", "runs": labels}]
    panels = []
    marks: list[list[float]] = []
    for i, p in enumerate(panels_raw):
        p = as_table(p, f"params.panels[{i}]")
        names = [str(x).replace("-", "_") for x in p.get("runs", [])]
        missing = [n for n in names if n not in by_label]
        if missing or not names:
            raise ConfigError(f"unknown run label(s) {missing or names}",
                              key=f"params.panels[{i}].runs", fix=f"labels: {', '.join(labels)}")
        curves_ = [(by_label[n].spec.legend or n, by_label[n].returns) for n in names]
        panels.append((str(p.get("title", "")), curves_))
        marks.append(sorted({s.takeover * s.trials for s in (by_label[n].spec for n in names)
                             if s.observer and s.takeover < 1.0}))
    from simlab.visitlab.figures import plot_curve_panels

    fig = plot_curve_panels(panels, ctx.out / "curves.png",
                            ylabel=str(params.get("ylabel", "reward per trial")),
                            title=f"{params.get('title', '')} ({specs[0].seeds} seeds)".strip(),
                            marks=marks)
    notes = [cache_note(runs), "Runs: " + "; ".join(
        f"{s.label} = {s.agent} on {s.task} ({s.variant}), {s.trials:,} trials"
        + (f", a Q-learner watching it takes over at {s.takeover:.0%}" if s.observer else "")
        + (f", {json.dumps(dict(s.overrides))}" if s.overrides else "")
        + (f", env {json.dumps(dict(s.env))}" if s.env else "") for s in specs) + "."]
    return RunResult(metrics=metrics, figures=[fig], notes=notes + param_notes(params),
                     details=details)


# --------------------------------------------------------------------------- Fig. 4.3
