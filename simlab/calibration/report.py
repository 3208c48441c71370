"""Outputs of a calibration: the calibrated ``[primitives]`` TOML, JSON and markdown reports,
and a figure.

Files in the output directory (none is replaced without ``overwrite``; each is written to a
temporary sibling and renamed):

* ``primitives.toml`` — ``[primitives]``: every field of the calibrated record (the format
  ``collect/replay/pipeline --primitives FILE.toml`` read; other tables are ignored by them),
  then ``[calibration]``: the distance, floor and source, for people;
* ``report.json`` — everything, machine-readable;
* ``report.md`` — sim vs real side by side;
* ``calibration.png`` — distance of every candidate over the search (with the floor band)
  and the mean next-state entropy per action, sim vs real.
"""

from __future__ import annotations

import dataclasses
import io
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from simlab.calibration.search import CalibrationResult
from simlab.io import atomic_write, atomic_write_json, atomic_write_text, ensure_new

FILES = ("primitives.toml", "report.json", "report.md", "calibration.png")


def output_paths(out: str | os.PathLike[str]) -> dict[str, Path]:
    """``{file name: path}`` of the outputs in directory ``out``."""
    return {name: Path(out) / name for name in FILES}


def check_outputs(out: str | os.PathLike[str], *, overwrite: bool = False) -> dict[str, Path]:
    """Refuse (ConfigError) before any work if an output exists and not ``overwrite``."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        ensure_new(out, overwrite=False, what="output directory (a file is in the way)")
    paths = output_paths(out)
    for path in paths.values():
        ensure_new(path, overwrite=overwrite, what="calibration output")
    return paths


def _record(params: Any) -> dict[str, Any]:
    to_json = getattr(params, "to_json", None)
    return dict(to_json()) if callable(to_json) else dataclasses.asdict(params)


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int | float):
        return repr(float(v)) if isinstance(v, float) else str(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    raise TypeError(f"cannot write {v!r} to TOML")


def primitives_toml(result: CalibrationResult) -> str:
    """Text of ``primitives.toml`` (module docstring)."""
    lines = ["# Calibrated by `simlab calibrate` against " + (result.real.source or "a real table"),
             "[primitives]"]
    lines += [f"{k} = {_toml_value(v)}" for k, v in _record(result.params).items()
              if v is not None]
    lines += ["", "[calibration]",
              f"distance = {_toml_value(_num(result.final.distance))}",
              f"floor_median = {_toml_value(_num(result.floor.median))}",
              f"matched_floor_median = {_toml_value(_num(result.matched_floor.median))}",
              f"searched = [{', '.join(_toml_value(n) for n in result.space.names)}]",
              f"simulator = {_toml_value(result.config.simulator)}"]
    return "\n".join(lines) + "\n"


def _num(x: float) -> float:
    return float(x) if math.isfinite(x) else -1.0


def _fin(x: Any) -> Any:
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def report_json(result: CalibrationResult) -> dict[str, Any]:
    """The JSON report (plain types)."""
    cfg = dataclasses.asdict(result.config)
    return {
        "real": {"source": result.real.source, "action_set": result.real.action_set.to_json(),
                 **result.real_summary},
        "sim": {**result.sim_summary, "walk_rows": result.final.sim.walk_rows},
        "distance": result.final.tv.to_json(),
        "floor": result.floor.to_json(),
        "matched_floor": result.matched_floor.to_json(),
        "argmax_agreement": _fin(result.agreement),
        "params": _record(result.params),
        "base_params": _record(result.base),
        "decision_latency_fitted": result.latency_fitted,
        "space": result.space.to_json(),
        "config": cfg,
        "best_candidate": result.best,
        "candidates": [{"index": c.index, "stage": c.stage, "values": c.values,
                        "distance": _fin(c.distance), "rows": c.sim.rows,
                        "real_only_pairs": c.tv.real_only,
                        "wall_seconds": c.sim.wall_seconds} for c in result.candidates],
        "wall_seconds": result.wall_seconds,
        "notes": result.notes,
    }


def _cell(v: Any, fmt: str = "{:.3f}") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "n/a"
    return fmt.format(v) if isinstance(v, float) else str(v)


def report_markdown(result: CalibrationResult) -> str:
    """The markdown report: sim vs real side by side, then the search."""
    r, s = result.real_summary, result.sim_summary
    tv = result.final.tv
    rows = [
        ("states (visited)", f"{r['states']} ({r['states_visited']})",
         f"{s['states']} ({s['states_visited']})"),
        ("transitions", r["transitions"], s["transitions"]),
        ("hours (of these transitions)", _cell(r["hours"], "{:.2f}"),
         _cell(s["hours"], "{:.2f}")),
        ("transitions per hour", _cell(r["transitions_per_hour"], "{:.0f}"),
         _cell(s["transitions_per_hour"], "{:.0f}")),
        ("(s, a) pairs visited", r["pairs_visited"], s["pairs_visited"]),
        ("mean entropy per action (bits)", _cell(r["mean_entropy_bits"]),
         _cell(s["mean_entropy_bits"])),
        ("self-transition share", _cell(r["self_transition_share"]),
         _cell(s["self_transition_share"])),
        ("blocked rate", _cell(r["blocked_rate"]), _cell(s["blocked_rate"])),
    ]
    out = io.StringIO()
    out.write(f"# Calibration against {result.real.source or 'the real table'}\n\n")
    out.write(f"Real actions: {result.real.action_set.describe()}; simulator "
              f"`{result.config.simulator}`, {result.config.hours_per_candidate:g} h per "
              f"candidate, {len(result.candidates)} candidates, seed {result.config.seed}.\n\n")
    sim = result.final.sim
    out.write(f"The simulated walk draws all 16 primitives; the {sim.rows} of its {sim.walk_rows} "
              "transitions whose primitive is one of the real actions are compared.\n\n")
    out.write("| | real | sim (calibrated) |\n|---|---|---|\n")
    for name, a, b in rows:
        out.write(f"| {name} | {a} | {b} |\n")
    fl, mf = result.floor, result.matched_floor
    out.write(
        f"\n**Visit-weighted TV distance** {_cell(tv.distance)} against a bootstrap sampling "
        f"floor of {_cell(fl.median)} (95 %: {_cell(fl.low)}-{_cell(fl.high)}); matched floor "
        f"for this simulated budget {_cell(mf.median)} (95 %: {_cell(mf.low)}-"
        f"{_cell(mf.high)}).\n\n"
        f"Most likely next state agrees in {_cell(100 * result.agreement, '{:.0f}')} % of the "
        f"{tv.common} (s, a) pairs visited in both; {tv.real_only} real pairs never tried in "
        f"the simulation ({_cell(100 * tv.real_weight_uncovered, '{:.1f}')} % of the real "
        f"visits, rule `{tv.unvisited}`), {tv.sim_only} simulated pairs absent from the real "
        "table.\n\n")
    out.write("## Calibrated parameters\n\n| field | start | calibrated |\n|---|---|---|\n")
    base, new = _record(result.base), _record(result.params)
    changed = [*result.space.names, "decision_latency"] if result.latency_fitted \
        else list(result.space.names)
    for name in changed:
        out.write(f"| {name} | {_cell(float(base[name]), '{:.4g}')} | "
                  f"{_cell(float(new[name]), '{:.4g}')} |\n")
    out.write("\n" + ("Decision latency fitted to the real transitions per hour.\n"
                      if result.latency_fitted else
                      "Decision latency not fitted (real duration unknown).\n"))
    out.write("\n## Search\n\n| # | stage | " + " | ".join(result.space.names)
              + " | distance |\n|" + "---|" * (result.space.dim + 3) + "\n")
    for c in result.candidates:
        vals = " | ".join(f"{c.values[n]:.4g}" for n in result.space.names)
        mark = " **best**" if c.index == result.best else ""
        out.write(f"| {c.index} | {c.stage} | {vals} | {_cell(c.distance)}{mark} |\n")
    for note in result.notes:
        out.write(f"\n{note}.\n")
    out.write("\n![calibration](calibration.png)\n")
    return out.getvalue()


def plot_calibration(result: CalibrationResult, path: Path) -> None:
    """The figure: distance per candidate with the floor band; entropy per action."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 4))
    ax1, ax2 = fig.subplots(1, 2)
    idx = np.array([c.index for c in result.candidates])
    dist = np.array([c.distance for c in result.candidates])
    init = np.array([c.stage == "init" for c in result.candidates])
    ax1.axhspan(result.floor.low, result.floor.high, color="0.85", label="floor (95 %)")
    ax1.axhline(result.matched_floor.median, color="0.4", ls="--", label="matched floor")
    ax1.plot(idx[init], dist[init], "o", label="initial design")
    ax1.plot(idx[~init], dist[~init], "s", label="refinement")
    ax1.plot(idx, np.minimum.accumulate(dist), "-", color="k", lw=1, label="best so far")
    ax1.set_xlabel("candidate")
    ax1.set_ylabel("visit-weighted TV distance")
    ax1.legend(fontsize=7)
    a = np.arange(result.entropy_real.size)
    ax2.bar(a - 0.2, np.nan_to_num(result.entropy_real), 0.4, label="real")
    ax2.bar(a + 0.2, np.nan_to_num(result.entropy_sim), 0.4, label="sim (calibrated)")
    ax2.set_xticks(a)
    ax2.set_xlabel("action (real numbering)")
    ax2.set_ylabel("mean next-state entropy (bits)")
    ax2.legend(fontsize=7)
    fig.tight_layout()
    with atomic_write(path, "wb") as fh:
        fig.savefig(fh, format="png", dpi=110)


def write_outputs(result: CalibrationResult, out: str | os.PathLike[str], *,
                  overwrite: bool = False, plot: bool = True) -> dict[str, Path]:
    """Write the files of the module docstring into ``out``; returns them by name."""
    paths = check_outputs(out, overwrite=overwrite)
    Path(out).mkdir(parents=True, exist_ok=True)
    atomic_write_text(paths["primitives.toml"], primitives_toml(result))
    atomic_write_json(paths["report.json"], report_json(result))
    atomic_write_text(paths["report.md"], report_markdown(result))
    if plot:
        plot_calibration(result, paths["calibration.png"])
    else:
        del paths["calibration.png"]
    return paths
