"""Outputs of a calibration: the calibrated ``[primitives]`` TOML, JSON and markdown reports,
and a figure.

Files in the output directory (none is replaced without ``overwrite``; each is written to a
temporary sibling and renamed):

* ``primitives.toml`` — ``[primitives]``: every field of the calibrated record (the format
  ``collect/replay/pipeline --primitives FILE.toml`` read; other tables are ignored by them),
  then ``[calibration]``: the distance, floor and source, for people; then, when the twin
  ensemble has two members or more, ``[[ensemble]]``: one full record per member, the
  winner first, each after a comment naming its candidate and distance, every member with
  the winner's decision latency (it does not change T); ``collect`` and ``online --arena``
  with ``--ensemble`` draw from them
  (:meth:`simlab.physics.motion.PrimitiveParams.ensemble_from_toml` reads them). Without
  confirmation, or with the winner alone within sampling, there is no ``[[ensemble]]``;
* ``report.json`` — everything, machine-readable;
* ``report.md`` — sim vs real side by side;
* ``calibration.png`` — distance of every candidate over the search (with the floor band)
  and the mean next-state entropy per action, sim vs real;
* ``transfer.png`` — with twin seeds: the transfer of twin policies to the real model
  (:mod:`simlab.calibration.transfer`) for the goal where the twins do worst;
* ``pairs.png`` — when the twin contradicts the robot beyond sampling somewhere
  (:mod:`simlab.calibration.contradictions`): those (s, a) pairs drawn on the arena;
* ``told_space.toml`` — with a profile (``--profile-step``) that finds a field the real
  table does not tell: the space of the told fields alone (the ``--space`` format of
  :mod:`simlab.calibration.space`). ``calibrate --primitives primitives.toml --space
  told_space.toml`` then searches only what the data tell, the others held at this twin's
  values, instead of leaving them to the search's luck.

All of them are written in one output transaction (:func:`simlab.base.io.output_transaction`):
a failed or killed run leaves the previous outputs as they were, and ``overwrite``
replaces only these names.
"""

from __future__ import annotations

import dataclasses
import io
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base.actions import ActionSet
from simlab.base.errors import ConfigError
from simlab.base.io import (
    atomic_write,
    atomic_write_json,
    atomic_write_text,
    ensure_new,
    output_transaction,
)
from simlab.calibration.metrics import Floor
from simlab.calibration.policies import policy_need
from simlab.calibration.stages import CalibrationResult
from simlab.calibration.walks import action_set_options

FILES = ("primitives.toml", "report.json", "report.md", "calibration.png", "transfer.png",
         "pairs.png", "told_space.toml")

#: First line of ``told_space.toml``: what ``--overwrite`` recognises as calibrate's own.
TOLD_TITLE = "# The fields the real table tells"

#: ``kind`` of ``report.json``: what ``--overwrite`` recognises as calibrate's own.
KIND = "simlab-calibrate"


def output_paths(out: str | os.PathLike[str]) -> dict[str, Path]:
    """``{file name: path}`` of the outputs in directory ``out``."""
    return {name: Path(out) / name for name in FILES}


def _report_is_ours(path: Path) -> bool:
    """``report.json`` written by ``simlab calibrate``: its ``kind`` (reports written before
    it existed: the distance, floors, parameters and space calibrate always wrote)."""
    import json

    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError):
        return False
    if not isinstance(doc, dict):
        return False
    return doc.get("kind") == KIND or ("kind" not in doc and {
        "distance", "floor", "matched_floor", "params", "space", "candidates"} <= set(doc))


def _is_ours(path: Path, report_ours: bool) -> bool:
    """Whether an existing output ``path`` is one calibrate wrote: ``primitives.toml`` by its
    ``[calibration]`` table, ``report.md`` by its title, the figures beside a report of ours."""
    name = path.name
    if name == "report.json":
        return report_ours
    try:
        if name == "primitives.toml":
            import tomllib

            table = tomllib.loads(path.read_text(encoding="utf-8")).get("calibration")
            return isinstance(table, dict) and {"searched", "simulator"} <= set(table)
        if name in ("report.md", "told_space.toml"):
            title = "# Calibration against" if name == "report.md" else TOLD_TITLE
            with path.open(encoding="utf-8") as fh:
                return fh.readline().startswith(title)
        with path.open("rb") as fh:
            return report_ours and fh.read(8) == b"\x89PNG\r\n\x1a\n"
    except (OSError, ValueError, UnicodeDecodeError):
        return False


def check_outputs(out: str | os.PathLike[str], *, overwrite: bool = False) -> dict[str, Path]:
    """Refuse (ConfigError) before any work: an output directory that is a file, an
    existing output without ``overwrite``, and with it any output an earlier ``simlab
    calibrate`` did not write (a ``primitives.toml`` written by hand is never replaced)."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ConfigError("the output directory is a file", path=out, key="out",
                          fix="choose another --out, or move the file out of the way")
    paths = output_paths(out)
    for path in paths.values():
        if path.is_dir():
            raise ConfigError("calibration output is a directory", path=path, key="out",
                              fix="choose another --out")
        ensure_new(path, overwrite=overwrite, what="calibration output")
    if overwrite:
        report_ours = _report_is_ours(paths["report.json"])
        for path in paths.values():
            if path.exists() and not _is_ours(path, report_ours):
                raise ConfigError("not written by simlab calibrate; --overwrite replaces "
                                  "only calibrate's own outputs", path=path, key="overwrite",
                                  fix="choose another --out, or move the file away")
    return paths


def param_record(params: Any) -> dict[str, Any]:
    """A parameter record's fields as plain values (its ``to_json`` when it has one)."""
    to_json = getattr(params, "to_json", None)
    return dict(to_json()) if callable(to_json) else dataclasses.asdict(params)


def toml_value(v: Any) -> str:
    """``v`` written as a TOML value."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int | float):
        return repr(float(v)) if isinstance(v, float) else str(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    raise TypeError(f"cannot write {v!r} to TOML")


def record_lines(params: Any) -> list[str]:
    """``name = value`` lines of a parameter record's set fields (a TOML table's body)."""
    return [f"{k} = {toml_value(v)}" for k, v in param_record(params).items() if v is not None]


def ensemble_tables(members: list[tuple[str, Any]]) -> list[str]:
    """``[[ensemble]]`` tables, one per ``(comment, params)``, each after a blank line and
    its ``# comment``."""
    lines: list[str] = []
    for comment, params in members:
        lines += ["", f"# {comment}", "[[ensemble]]", *record_lines(params)]
    return lines


def primitives_toml(result: CalibrationResult) -> str:
    """Text of ``primitives.toml`` (module docstring)."""
    lines = ["# Calibrated by `simlab calibrate` against " + (result.real.source or "a real table"),
             "[primitives]"]
    lines += record_lines(result.params)
    lines += ["", "[calibration]",
              f"distance = {toml_value(_num(result.final.distance))}",
              f"floor_median = {toml_value(_num(result.floor.median))}",
              f"matched_floor_median = {toml_value(_num(result.matched_floor.median))}",
              *([] if result.perfect_floor is None else [
                  "perfect_twin_floor_median = "
                  f"{toml_value(_num(result.perfect_floor.median))}"]),
              f"searched = [{', '.join(toml_value(n) for n in result.space.names)}]",
              f"simulator = {toml_value(result.config.simulator)}"]
    # An ensemble of the winner alone adds nothing to [primitives]: written only with two
    # members or more, so that `--ensemble` on a file without it says so plainly.
    if len(result.ensemble) >= 2:
        from simlab.calibration.search import params_at

        lines += ["", "# The twin ensemble (`collect` / `online --arena` with --ensemble): the "
                  "confirmed candidates", "# within sampling of the winner, the winner first; "
                  "each with the winner's decision latency"]
        # latency does not change T: every member gets the winner's (fitted) one
        lines += ensemble_tables([
            (f"member {k}: candidate #{c.index}, distance {_num(c.distance):.6f}"
             f"{' (the winner)' if k == 0 else ''}",
             dataclasses.replace(params_at(result.space, result.base, c.unit),
                                 decision_latency=result.params.decision_latency))
            for k, c in enumerate(result.ensemble)])
    return "\n".join(lines) + "\n"


def _num(x: float) -> float:
    return float(x) if math.isfinite(x) else -1.0


def _fin(x: Any) -> Any:
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def fresh_twins(result: CalibrationResult) -> list[Any]:
    """The twin walks of the winner on seeds it was not chosen on (its confirming walks, the
    best of the confirmed candidates there, read low by their luck)."""
    chosen = {c.seed for c in result.confirmed if c.index == result.best}
    return [t for t in result.twins if t.seed not in chosen]


def level_json(result: CalibrationResult) -> dict[str, Any]:
    """The winner's distance as a multiple of the distance a twin equal to the robot would
    show (``perfect_twin``, the perfect-twin floor) and of the plug-in matched floor
    (``matched``, which reads low: the same twin reads higher against it); ``fresh``: the
    mean distance of :func:`fresh_twins` and its multiple of the perfect-twin floor (None
    without such walks)."""
    d = result.final.distance
    pf = result.perfect_floor

    def over(x: float, f: Floor | None) -> float | None:
        return None if f is None or not f.median > 0 else _fin(x / f.median)

    fresh = fresh_twins(result)
    mean = float(np.mean([t.distance for t in fresh])) if fresh else math.nan
    return {"perfect_twin": over(d, pf), "matched": over(d, result.matched_floor),
            "fresh": None if not fresh else {"walks": len(fresh), "distance": _fin(mean),
                                             "perfect_twin": over(mean, pf)}}


def report_json(result: CalibrationResult) -> dict[str, Any]:
    """The JSON report (plain types)."""
    cfg = dataclasses.asdict(result.config)
    return {
        "kind": KIND,
        "real": {"source": result.real.source, "action_set": result.real.action_set.to_json(),
                 **result.real_summary},
        "sim": {**result.sim_summary, "walk_rows": result.final.sim.walk_rows},
        "distance": result.final.tv.to_json(),
        "floor": result.floor.to_json(),
        "matched_floor": result.matched_floor.to_json(),
        "perfect_twin_floor": None if result.perfect_floor is None
        else result.perfect_floor.to_json(),
        "level": level_json(result),
        "argmax_agreement": _fin(result.agreement),
        "params": param_record(result.params),
        "base_params": param_record(result.base),
        "decision_latency_fitted": result.latency_fitted,
        "space": result.space.to_json(),
        "config": cfg,
        "best_candidate": result.best,
        "candidates": [{"index": c.index, "stage": c.stage, "values": c.values,
                        "distance": _fin(c.distance), "score": _fin(c.score),
                        "rows": c.sim.rows, "real_only_pairs": c.tv.real_only,
                        "wall_seconds": c.sim.wall_seconds} for c in result.candidates],
        "signature_gap": None if result.final.gap is None else result.final.gap.to_json(),
        "search": search_json(result),
        "ensemble": ensemble_json(result),
        "profile": None if result.profile is None else result.profile.to_json(),
        "wall_seconds": result.wall_seconds,
        "notes": result.notes,
        "warnings": result.warnings,
        "screen_best_candidate": result.screen_best,
        "coverage": coverage(result),
        "signature": None if result.signature is None else result.signature.to_json(),
        "budgets": None if result.budgets is None else result.budgets.to_json(),
        "confirmed": [{"index": c.index, "seed": c.seed, "distance": _fin(c.distance),
                       "score": _fin(c.score), "rows": c.sim.rows,
                       "signature_gap": None if c.gap is None else c.gap.to_json()}
                      for c in result.confirmed],
        "reset_states": {"states": list(result.real.reset_states),
                         "transitions_left_out": result.real.reset_counts},
        "regions": result.regions,
        "contradictions": None if result.contradictions is None
        else result.contradictions.to_json(),
        "transfer": None if result.transfer is None else {
            "overview": transfer_overview(result.transfer),
            "headline": transfer_headline(result),
            "data_curve": [{k: _fin(v) for k, v in row.items()}
                           for row in result.transfer_curve],
            "data_need": policy_data(result),
            **_lines_json(result.twin_transfer),
            **result.transfer.to_json()},
    }


def search_json(result: CalibrationResult) -> dict[str, Any] | None:
    """The search's rungs (each candidate's pooled score there), its picks and the share of
    the rung-0 score each field explains."""
    found = result.search
    if found is None:
        return None
    rungs = [{"rung": k + 1, "walk": {"hours": size[0], "transitions": size[1]},
              "candidates": [{"index": c.index, "score": _fin(c.score),
                              "distance": _fin(c.distance), "rows": c.sim.rows} for c in rung]}
             for k, (rung, size) in enumerate(zip([found.candidates, *found.rungs],
                                                  found.sizes, strict=True))]
    return {"sampler": result.config.sampler, "eta": result.config.eta, "rungs": rungs,
            "picks": found.picks, "importance": found.importance}


#: Share of the first rung's score variance a field must explain to count as told by the
#: data (:func:`ensemble_spread`): with the 9 fields of the ISIR lab's search, a field of
#: average weight explains 11 %.
TOLD_SHARE = 0.05


def ensemble_spread(result: CalibrationResult) -> list[dict[str, Any]]:
    """Per searched field: the ensemble's values (lowest, highest), that span as a share
    of the searched range (unit-cube width), the share of the search's score the field
    explains, and ``told``: whether the data pin it down. With a profile
    (:mod:`~simlab.calibration.profile`) that is its measured verdict; without, a guess:
    the field must explain at least
    :data:`TOLD_SHARE` of the score's variance over the first rung (PED-ANOVA); the
    members' span alone cannot say it, as the sampler gathers the confirmed candidates
    near one another whatever the data tell. Without importances (too few candidates),
    members within a quarter of the range count as told."""
    members = result.ensemble
    imp = result.search.importance if result.search is not None else {}
    measured = {} if result.profile is None else result.profile.verdicts()
    allowed = {} if result.profile is None else {f.name: (f.allowed, f.open)
                                                 for f in result.profile.fields}
    rows = []
    for k, spec in enumerate(result.space.specs):
        units = np.array([c.unit[k] for c in members]) if members else np.zeros(0)
        vals = [c.values[spec.name] for c in members]
        width = float(units.max() - units.min()) if units.size else math.nan
        share = imp.get(spec.name)
        told = bool(share >= TOLD_SHARE) if share is not None else bool(
            units.size and width <= 0.25)
        if measured.get(spec.name) is not None:
            told = bool(measured[spec.name])
        row: dict[str, Any] = {"field": spec.name, "span_of_range": _fin(width),
                               "importance": share, "told": told}
        if allowed.get(spec.name, (None,))[0] is not None:
            row["allowed"] = list(allowed[spec.name][0])
            row["allowed_open"] = list(allowed[spec.name][1])
        if spec.categorical:
            row["values"] = sorted(set(vals))
        else:
            row["low"] = min(vals) if vals else None
            row["high"] = max(vals) if vals else None
        rows.append(row)
    return rows


def ensemble_json(result: CalibrationResult) -> dict[str, Any]:
    """The twin ensemble: its members (the winner first) and the spread field by field."""
    return {"members": [{"index": c.index, "distance": _fin(c.distance),
                         "score": _fin(c.score), "values": c.values}
                        for c in result.ensemble],
            "spread": ensemble_spread(result)}


def _lines_json(twin: Any) -> dict[str, Any]:
    """The perfect-twin lines and the collected policy data of the transfer stage."""
    if twin is None:
        return {}
    policy = None
    if twin.policy is not None:
        policy = {k: (v.to_json() if k == "line" else
                      {g: _fin(r) for g, r in v.items()} if k == "goal_ratios" else _fin(v))
                  for k, v in twin.policy.items()}
    ens = None if twin.ensemble is None else {k: _fin(v) for k, v in twin.ensemble.items()}
    return {"ensemble_against_winner": ens,
            "perfect_twin_line": None if twin.line is None else twin.line.to_json(),
            "perfect_twin_at_need": None if twin.line_at_need is None
            else twin.line_at_need.to_json(),
            "policy_data": policy, "goals_left_out": twin.left_out,
            "masked_ratios": None if twin.masked is None else [_fin(r) for r in twin.masked]}


def transfer_headline(result: CalibrationResult) -> str:
    """The transfer in one line: the twins' policies against a perfect twin at the same
    data, and at the recommended policy data (the fit, and the collected data when
    ``policy_data``)."""
    twin = result.twin_transfer
    if twin is None or twin.report is None:
        return "no transfer"
    ratios = twin.report.overall_ratios()
    fin = ratios[np.isfinite(ratios)]
    n = int(np.mean([t.sim.counts.sum() for t in result.twins]))
    if fin.size == ratios.size:
        mine = f"take {fin.mean():.3f} x the real optimum's steps"
    elif fin.size:
        mine = (f": {fin.size} of {ratios.size} seeds take {fin.mean():.3f} x the real "
                f"optimum's steps, {ratios.size - fin.size} never arrive"
                + (" (--untried mask plans among the pairs the real robot tried)"
                   if twin.untried == "stay" else ""))
    else:
        mine = f"never arrive for any of {ratios.size} seeds"
    text = (f"twin policies ({len(ratios)} twins of {n:,} transitions) {mine}, a perfect "
            f"twin at the same data {_ratio(twin.line)}"
            f"{_gap(fin.mean() if fin.size == ratios.size else math.inf, twin.line)}")
    if twin.need is not None:
        fit = twin.need["limit"] + twin.need["c"] / twin.need["transitions"]
        how = ("measured (more data do not help)" if twin.need["flat"] else
               "(the smallest size measured: the fit asks fewer) the fit gives"
               if twin.need["below_measured"] else "the fit gives")
        text += (f"; at the recommended {twin.need['transitions']:,.0f} transitions {how} "
                 f"{fit:.3f}, a perfect twin {_ratio(twin.line_at_need)}"
                 f"{_gap(fit, twin.line_at_need)}")
    if twin.policy is not None:
        text += (f"; the policy of {twin.policy['transitions']:,} collected transitions "
                 f"{_cell(twin.policy['ratio'])}, a perfect twin {_ratio(twin.policy['line'])}"
                 f"{_gap(twin.policy['ratio'], twin.policy['line'])}")
    return text


def _ratio(line: Any) -> str:
    return "n/a" if line is None else _steps_ratio(line.median)


def _gap(value: float, line: Any) -> str:
    """`` (+x.x %)``: ``value`` over the line's median, when both are finite."""
    if line is None or not (math.isfinite(value) and math.isfinite(line.median)):
        return ""
    return f" ({100 * (value / line.median - 1):+.1f} %)"


def coverage(result: CalibrationResult) -> dict[str, Any]:
    """How much of the real data the calibrated twin's walk covers: real (s, a) pairs
    tried, the share of the real transitions on them, and the states reached."""
    tv = result.final.tv
    n_real = result.real.counts.sum(axis=2)
    n_sim = result.final.sim.counts
    reached = (n_sim.sum(axis=(1, 2)) > 0) | (n_sim.sum(axis=(0, 1)) > 0)
    return {"real_pairs": int((n_real > 0).sum()), "real_pairs_tried": tv.common,
            "real_weight_tried": _fin(1.0 - tv.real_weight_uncovered),
            "states_reached": int(reached.sum()), "states": int(reached.size)}


def transfer_overview(transfer: Any) -> dict[str, Any]:
    """One figure per twin over every goal: the ratio of the twin policy's expected steps
    to the real optimum, summed over the goals (a random start and a random goal), the
    worst goal's ratio and the goals never reached; then the mean and worst over twins."""
    twins = []
    opt = np.array([g.optimum_mean for g in transfer.goals])
    ok = np.isfinite(opt) & (opt > 0)
    overall = transfer.overall_ratios()
    for k, name in enumerate(transfer.twin_names):
        steps = np.array([g.twins[k].mean_steps for g in transfer.goals])
        ratios = np.where(ok, steps / np.where(ok, opt, 1.0), np.nan)
        never = int(np.sum(ok & ~np.isfinite(steps)))
        total = float(overall[k])
        worst_i = int(np.nanargmax(ratios)) if np.isfinite(ratios).any() or never else -1
        twins.append({"twin": name, "ratio": _fin(total),
                      "worst_goal": transfer.goals[worst_i].name if worst_i >= 0 else None,
                      "worst_goal_ratio": _fin(float(ratios[worst_i])) if worst_i >= 0
                      else None, "goals_never": never})
    r = np.array([t["ratio"] if t["ratio"] is not None else math.inf for t in twins])
    floors = [g.floor.median for g in transfer.goals
              if g.floor is not None and math.isfinite(g.floor.median)]
    return {"goals": len(transfer.goals), "twins": twins,
            "mean_ratio": _fin(float(r.mean())) if r.size else None,
            "worst_ratio": _fin(float(r.max())) if r.size else None,
            "perfect_twin_ratio": _fin(float(np.mean(floors))) if floors else None}


def _cell(v: Any, fmt: str = "{:.3f}") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "n/a"
    return fmt.format(v) if isinstance(v, float) else str(v)


def report_markdown(result: CalibrationResult) -> str:
    """The markdown report: sim vs real side by side, then the search."""
    out = io.StringIO()
    out.write(f"# Calibration against {result.real.source or 'the real table'}\n\n")
    _intro(out, result)
    out.write("| | real | sim (calibrated) |\n|---|---|---|\n")
    for name, a, b in _side_by_side(result):
        out.write(f"| {name} | {a} | {b} |\n")
    _distance(out, result)
    out.write(signature_section(result))
    out.write(region_table(result.regions))
    out.write(contradictions_section(result))
    out.write(_budget_section(result))
    out.write(_transfer_section(result))
    _parameters(out, result)
    out.write(ensemble_section(result))
    _search_table(out, result)
    out.write("\n![calibration](calibration.png)\n")
    return out.getvalue()


def _side_by_side(result: CalibrationResult) -> list[tuple[str, Any, Any]]:
    """(row name, real, sim) of the signature table, coverage last."""
    r, s = result.real_summary, result.sim_summary
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
    cov = coverage(result)
    tried_share = _cell(100 * (cov["real_weight_tried"] or 0.0), "{:.1f}")
    rows.append(("real (s, a) pairs tried by the twin", cov["real_pairs"],
                 f"{cov['real_pairs_tried']} ({tried_share} % of the real transitions)"))
    rows.append(("states reached", r["states_visited"], f"{cov['states_reached']}"))
    return rows


def _intro(out: io.StringIO, result: CalibrationResult) -> None:
    """Warnings, the walks' actions and starts, and the real signature."""
    cfg = result.config
    for w in result.warnings:
        out.write(f"> **Warning:** {w}.\n\n")
    starts = cfg.start_states
    where = ("every state's centre (one walk each)" if str(starts).lower() == "all" else
             "the arena's start pose" if starts is None else f"states {starts}")
    out.write(f"Real actions: {result.real.action_set.describe()}; the simulated walks draw "
              f"the same actions' primitives uniformly, starting from {where}. Simulator "
              f"`{cfg.simulator}`, pose source `{cfg.pose_source}`, {len(result.candidates)} "
              f"candidates screened, seed {cfg.seed}.\n\n")
    if result.real.reset_states:
        out.write(f"Reset rows: state(s) {list(result.real.reset_states)} "
                  f"({result.real.reset_counts} real transitions) are an episode reset, not "
                  "moves; they are left out of the distance, and in the transfer those states "
                  "take the twins' own rows.\n\n")
    sig = result.signature
    if sig is not None:
        out.write(f"Real signature: {100 * sig.self_share:.0f} % of the transitions stay in "
                  f"their state; cells of {sig.cell_size:.2f} m (median distance to the "
                  f"nearest other centre); the calibration starts in `{result.base.mode}` "
                  "mode.\n\n" if hasattr(result.base, "mode") else
                  f"Real signature: {100 * sig.self_share:.0f} % of the transitions stay in "
                  f"their state; cells of {sig.cell_size:.2f} m.\n\n")


def _distance(out: io.StringIO, result: CalibrationResult) -> None:
    """The distance against its floors, agreement and coverage in words."""
    tv = result.final.tv
    fl, mf = result.floor, result.matched_floor
    out.write(
        f"\n**Visit-weighted TV distance** {_cell(tv.distance)} against a bootstrap sampling "
        f"floor of {_cell(fl.median)} (95 %: {_cell(fl.low)}-{_cell(fl.high)}); matched floor "
        f"for this simulated budget {_cell(mf.median)} (95 %: {_cell(mf.low)}-"
        f"{_cell(mf.high)}).{_level_sentence(result)}\n\n"
        f"Most likely next state agrees in {_cell(100 * result.agreement, '{:.0f}')} % of the "
        f"{tv.common} (s, a) pairs visited in both; {tv.real_only} real pairs never tried in "
        f"the simulation ({_cell(100 * tv.real_weight_uncovered, '{:.1f}')} % of the real "
        f"visits, rule `{tv.unvisited}`), {tv.sim_only} simulated pairs absent from the real "
        "table.\n\n")


def _level_sentence(result: CalibrationResult) -> str:
    pf, lv = result.perfect_floor, level_json(result)
    if pf is None or lv["perfect_twin"] is None:
        return ""
    return (f" A twin equal to the robot, walked as long, would lie {_cell(pf.median)} from "
            f"the real table (95 %: {_cell(pf.low)}-{_cell(pf.high)}; the matched floor "
            "drawn from coverage-adjusted shares, since the real rows' own shares lack the "
            "rare next states a few visits miss): **this twin is "
            f"{lv['perfect_twin']:.2f}x that distance** ({_cell(lv['matched'], '{:.2f}')}x "
            "the plug-in matched floor)." + _fresh_sentence(lv["fresh"]))


def _fresh_sentence(fresh: dict[str, Any] | None) -> str:
    if not fresh or fresh["perfect_twin"] is None:
        return ""
    walks = "walk" if fresh["walks"] == 1 else f"{fresh['walks']} walks"
    return (f" On the winner's fresh twin {walks} (seeds it was not chosen on) the distance "
            f"is {_cell(fresh['distance'])}, {fresh['perfect_twin']:.2f}x: the confirming "
            "walk is the best of the confirmed candidates there, and reads low by its luck.")


def region_table(regions: list[dict[str, Any]]) -> str:
    """The signature per region (:mod:`~simlab.calibration.regions`), real / twin side by
    side, and each region's share of the distance: where a twin still differs."""
    if not regions:
        return ""
    out = io.StringIO()
    out.write("## Where the twin differs: the signature by region\n\nEach real (s, a) pair "
              "is in a region by the free floor along its heading from the state's centre: "
              "**wall** (an obstacle within one cell ahead), **corridor** (obstacles within "
              "one cell on both sides), **open** (the rest). Shares of the region's "
              "transitions, real / twin; an outcome is ahead, to a side or behind by the "
              "bearing of its state's centre.\n\n| region | real pairs | real transitions | "
              "TV | stay | ahead | side | behind | entropy (bits) |\n"
              "|---|---|---|---|---|---|---|---|---|\n")
    for row in regions:
        r, t = row["real"], row["sim"]
        cells = " | ".join(f"{_cell(r[k], '{:.2f}')} / {_cell(t[k], '{:.2f}')}"
                           for k in ("stay", "ahead", "side", "behind", "entropy"))
        out.write(f"| {row['region']} | {r['pairs']} | {r['transitions']} | "
                  f"{_cell(row['tv'])} | {cells} |\n")
    out.write("\n")
    return out.getvalue()


#: Listed pairs shown in report.md (all of them are in report.json).
PAIRS_SHOWN = 25


def contradictions_section(result: CalibrationResult) -> str:
    """The real pairs the twin contradicts beyond sampling
    (:mod:`~simlab.calibration.contradictions`), most certain first, and the map figure."""
    from simlab.calibration.contradictions import direction

    c = result.contradictions
    if c is None:
        return ""
    walks = (f"the winner's {len(result.twins)} twin walks pooled" if result.twins else
             "the winner's confirming walks pooled")
    out = io.StringIO()
    out.write("## Where the twin contradicts the robot\n\n"
              f"Each real (s, a) pair tested on its own: are the robot's next states and the "
              f"twin's ({walks}) two samples of one distribution (a permutation test of "
              f"their total-variation distance, {c.resamples:,} relabellings)? The pairs are "
              f"read together by Benjamini-Hochberg. **In this run {c.summary()}.** "
              f"{c.untested} real pairs have fewer than two transitions "
              "on a side and are not tested")
    out.write(f" ({c.twin_untried} of them never tried by the twin).\n\n" if c.twin_untried
              else ".\n\n")
    if c.raw > 2 * c.expected and len(c.pairs) < c.raw / 2:
        out.write(f"Far more pairs pass the raw test ({c.raw}) than chance gives "
                  f"({c.expected:.0f}), and fewer than half of them are listed: the twin "
                  "differs from the robot a little almost everywhere, beside the places "
                  "listed.\n\n")
    if not c.pairs:
        return out.getvalue()
    heads = result.real.action_set.headings()
    out.write("A pair that the winners of several calibrate seeds all contradict "
              "(`simlab calibrate-pool` tests each winner's walks and names them) is wrong "
              "whatever the fields: check the map and the arena there first.\n\n"
              "| state | action (heading) | region | real / twin transitions | "
              "stays, real / twin | most likely next, real | twin | TV | q |\n"
              "|---|---|---|---|---|---|---|---|---|\n")
    for r in c.pairs[:PAIRS_SHOWN]:
        deg = math.degrees(heads[r["action"]]) % 360
        out.write(f"| {r['state']} | {r['action']} ({deg:.0f} deg) | {r['region'] or '-'} | "
                  f"{r['real']} / {r['twin']} | {r['stay_real']:.2f} / {r['stay_twin']:.2f} "
                  f"({direction(r)}) | {r['next_real']} ({r['share_real']:.2f}) | "
                  f"{r['next_twin']} ({r['share_twin']:.2f}) | {r['tv']:.2f} | "
                  f"{r['q']:.3g} |\n")
    if len(c.pairs) > PAIRS_SHOWN:
        out.write(f"\n{len(c.pairs) - PAIRS_SHOWN} more in report.json "
                  "(`contradictions.pairs`).\n")
    out.write("\n![pairs](pairs.png)\n\n")
    return out.getvalue()


def plot_contradictions(result: CalibrationResult, path: Path) -> None:
    """The listed pairs on the arena: an arrow along each pair's heading from its state's
    centre, coloured by how the twin differs (stays more, stays less, moves elsewhere)."""
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    from simlab.calibration.contradictions import direction

    c = result.contradictions
    centres = np.asarray(result.centres, dtype=float)
    x0, y0, x1, y1 = (result.arena.bounds if result.arena is not None else
                      (*centres.min(axis=0) - 0.5, *centres.max(axis=0) + 0.5))
    aspect = (y1 - y0) / max(x1 - x0, 1e-9)
    fig = Figure(figsize=(9.0, max(3.0, 9.0 * aspect + 0.8)), layout="constrained")
    ax = fig.subplots()
    if result.arena is not None:
        from simlab.physics.render import draw_arena_on

        draw_arena_on(ax, result.arena)
    ax.plot(*centres.T, "o", ms=3, color="0.45")
    for i, (x, y) in enumerate(centres):
        ax.annotate(str(i), (x, y), xytext=(2, 2), textcoords="offset points", fontsize=6,
                    color="0.3")
    colours = {"stays more": "tab:red", "stays less": "tab:blue",
               "moves elsewhere": "tab:purple"}
    heads = result.real.action_set.headings()
    cell = result.signature.cell_size if result.signature is not None else float("nan")
    length = 0.45 * cell if math.isfinite(cell) else 0.05 * max(x1 - x0, y1 - y0)
    for r in c.pairs:
        h = heads[r["action"]]
        x, y = centres[r["state"]]
        ax.annotate("", (x + length * math.cos(h), y + length * math.sin(h)), (x, y),
                    arrowprops={"arrowstyle": "-|>", "color": colours[direction(r)],
                                "lw": 1.2 + 2.0 * min(1.0, r["real"] / 40)})
    ax.legend(handles=[Line2D([], [], color=v, lw=2, label=f"the twin {k}")
                       for k, v in colours.items()], fontsize=7, loc="upper right",
              framealpha=0.85)
    ax.set_title(f"{len(c.pairs)} (s, a) pairs where the twin contradicts the robot (FDR "
                 f"{100 * c.alpha:.0f} %; arrow width: real transitions)", fontsize=9)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal")
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    with atomic_write(path, "wb") as fh:
        fig.savefig(fh, format="png", dpi=100)


def _parameters(out: io.StringIO, result: CalibrationResult) -> None:
    """The searched fields, start against calibrated."""
    out.write("## Calibrated parameters\n\n| field | start | calibrated |\n|---|---|---|\n")
    base, new = param_record(result.base), param_record(result.params)
    changed = [*result.space.names, "decision_latency"] if result.latency_fitted \
        else list(result.space.names)
    for name in changed:
        out.write(f"| {name} | {_value(base[name])} | {_value(new[name])} |\n")
    out.write("\n" + ("Decision latency fitted to the real transitions per hour.\n"
                      if result.latency_fitted else
                      "Decision latency not fitted (real duration unknown).\n"))


def signature_section(result: CalibrationResult) -> str:
    """The twin's signature against the robot's at the robot's visits, with tolerances."""
    from simlab.calibration.objective import TOLERANCES

    gap = result.final.gap
    if gap is None:
        return ""
    ok = gap.within()
    rows = [("self-transition share", gap.self_share_real, gap.self_share,
             TOLERANCES["self_share"], ok.get("self_share")),
            ("entropy per action (bits, at matched draws)", gap.entropy_real, gap.entropy,
             TOLERANCES["entropy"], ok.get("entropy")),
            ("outcomes per region (TV)", 0.0, gap.regions, TOLERANCES["regions"],
             ok.get("regions"))]
    out = io.StringIO()
    out.write("\n## Signature at the robot's visits\n\nThe twin's moves on the pairs the "
              "robot tried, weighted by the robot's visits; the search's objective charges "
              "each gap by its square over its tolerance:\n\n| | robot | twin | tolerance | within |\n"
              "|---|---|---|---|---|\n")
    for name, real, twin, tol, within in rows:
        mark = "n/a" if within is None else ("yes" if within else "**no**")
        out.write(f"| {name} | {_cell(real)} | {_cell(twin)} | {tol:g} | {mark} |\n")
    out.write("\n")
    return out.getvalue()


def ensemble_section(result: CalibrationResult) -> str:
    """The twin ensemble and how sure the twin is, field by field."""
    if not result.ensemble:
        return ""
    out = io.StringIO()
    ids = ", ".join(f"#{c.index}" for c in result.ensemble)
    out.write(f"\n## How sure the twin is\n\nTwin ensemble: {ids} (the confirmed candidates "
              "within sampling of the winner: no more than the matched floor's 95 % "
              "half-width above its distance). Their values field by field, the span as a "
              "share of the searched range, and the share of the search's score the field "
              "explains (PED-ANOVA over the first rung). " + (
                  "Whether the data tell a field is the profile's measurement (below); a "
                  "field *not told* has the winner's value, not a measured one"
                  if result.profile is not None else
                  "A field that explains under 5 % of it is guessed *not told* by the data "
                  "(a guess from noisy screening walks: `--profile-step 0.25` measures it)")
              + ":\n\n| field | ensemble values | span of range | "
              "explains | told by the data |\n|---|---|---|---|---|\n")
    for row in ensemble_spread(result):
        vals = (", ".join(row["values"]) if "values" in row else
                f"{_value(row['low'])} - {_value(row['high'])}")
        share = "n/a" if row["importance"] is None else f"{100 * row['importance']:.0f} %"
        out.write(f"| {row['field']} | {vals} | {_cell(row['span_of_range'], '{:.2f}')} | "
                  f"{share} | {'yes' if row['told'] else '**not told**'} |\n")
    twin = result.twin_transfer
    ens = None if twin is None else twin.ensemble
    if ens is not None:
        verdict = ("transfers better than" if ens["better"] else "does not transfer better "
                   "than")
        out.write(f"\nPlanned on the walks of {ens['members']} ensemble members pooled "
                  f"({ens['transitions']:,} transitions), a policy takes "
                  f"{_steps_ratio(ens['ensemble_ratio'])} x the real optimum's steps; on as "
                  f"many of the winner's own walks ({ens['winner_transitions']:,}), "
                  f"{_steps_ratio(ens['winner_ratio'])}: the ensemble {verdict} the single "
                  "twin here.\n")
    out.write("\n")
    out.write(profile_section(result))
    return out.getvalue()


def profile_section(result: CalibrationResult) -> str:
    """What the table can tell: each field moved alone from the winner (the profile)."""
    prof = result.profile
    if prof is None:
        return ""
    out = io.StringIO()
    sigma = "unknown (one walk of the winner)" if not math.isfinite(prof.sigma) else (
        f"{prof.sigma:.4f}")
    out.write(f"### What the real table can tell\n\nEach searched field moved alone by "
              f"{prof.step:g} of its searched range from the winner, each point a walk of "
              f"{prof.transitions:,} transitions on the winner's seed {prof.seed} (its "
              f"distance there {prof.distance:.4f}, score {prof.score:.4f}): the change of "
              f"distance and of score, against the score's spread from walk to walk "
              f"({sigma}{_dof_text(prof)}). A field is told when a move changes the score by "
              f"more than {prof.band:.2f} times that spread (the 95 % half-width of a "
              "difference of two walks, the spread estimated: Student's t). A move that "
              "raised the score by more excludes the values past it, unless another "
              "confirmed candidate within the band on this seed lies past it; the last column is what is left, the spread the "
              "data allow (a side no move bounds is open: nothing was measured past the "
              "searched range). " + (
                  "The told fields were then moved in pairs too (both diagonals, the same "
                  "step, the same seed): a value is excluded only when every point that put "
                  "the field there raised the score beyond the band, so where a second "
                  "field makes up for a move the value is allowed (the column of pairs "
                  "names the points that freed one)" if prof.pairs else
                  "Each field moves with the others at the winner's values, so where two "
                  "fields trade off the data allow more than its column says (the other "
                  "could make up for it; `--profile-pairs` measures it)")
              + ":\n\n| field | winner | moved to: distance / score change | told "
              + ("| freed by a pair " if prof.pairs else "")
              + "| values the data allow |\n|---|---|---|---|" + "---|" * (1 + prof.pairs)
              + "\n")
    limit = prof.limit
    for f in prof.fields:
        moved = "; ".join(f"{_value(m.value)}: {m.distance_change:+.4f} / "
                          f"{m.score_change:+.4f}" for m in f.alone) or "n/a"
        told = "n/a" if f.told is None else ("yes" if f.told else "**not told**")
        freed = ""
        if prof.pairs:
            out_alone = f.excluded_alone(limit)
            freed = "| " + ("; ".join(
                f"{_value(m.value)} with {m.partner} {_value(m.partner_value)}: "
                f"{m.score_change:+.4f}" for m in f.moves
                if m.partner is not None and m.value in out_alone and m.score_change <= limit)
                or "none") + " "
        out.write(f"| {f.name} | {_value(f.value)} | {moved} | {told} {freed}| "
                  f"{_allowed(f.allowed, f.open)} |\n")
    refuted = _refuted(prof, result.space)
    if refuted:
        out.write("\nFreed by a confirmed candidate within the band on this seed (every field "
                  "at its own value): " + "; ".join(refuted) + ". The score does not keep "
                  "worsening past that move, so nothing measured bounds that side.\n")
    ties = prof.ties()
    if ties:
        out.write("\nTied by the data: " + "; ".join(f"{a} with {b}" for a, b in ties)
                  + ". A move of either alone is beyond sampling, one of both together is "
                  "not: the table tells a combination of the two, not each, and the winner's "
                  "values are one point of that combination. Fix one of a tied pair "
                  "(`--space` without it, from what you know of the robot) to read the other "
                  "from the data.\n")
    if told_space_toml(result) is not None:
        out.write("\nThe fields not told are this twin's values, not the robot's: "
                  "`told_space.toml` holds the space of the told ones, so `simlab calibrate "
                  "... --primitives primitives.toml --space told_space.toml` searches only "
                  "those, the others held here.\n")
    out.write("\nThis statement reads the basin of this winner: a value it excludes is worse "
              "near the winner, not everywhere, and another `--seed` can land in another basin "
              "as good (on a lab whose robot is known, `benchmarks/calibrate_twin.py --lab "
              "synthetic`, most single seeds exclude one of the robot's values). Calibrate "
              "with several seeds and read them together: `simlab calibrate-pool --runs DIR "
              "DIR ...` states what the data allow across the basins within sampling of the "
              "best.\n")
    out.write("\n")
    return out.getvalue()


def _dof_text(prof: Any) -> str:
    """``, from N walks`` when the profile kept how many walks its spread came from."""
    return "" if prof.dof is None else f", from {prof.dof + 1} walks of the winner"


def _refuted(prof: Any, space: Any) -> list[str]:
    """``field below/above V (a confirmed candidate at X: +score)`` for each move whose bound
    a confirmed candidate refutes (:func:`~simlab.calibration.profile.bounding`)."""
    from simlab.calibration.profile import excluding, refuting

    if not math.isfinite(prof.limit):
        return []
    limit, out = prof.limit, []
    for spec, f in zip(space.specs, prof.fields, strict=True):
        for m in excluding(list(f.moves), limit):
            good = refuting(spec, f.value, m, list(f.moves), limit)
            if good is None:
                continue
            side = "" if spec.categorical else (" below" if m.value < f.value else " above")
            out.append(f"{f.name}{side} {_value(m.value)} (a confirmed candidate at "
                       f"{_value(good.value)}: {good.score_change:+.4f})")
    return out


def _allowed(allowed: tuple[Any, ...] | None,
             open_: tuple[bool, bool] = (False, False)) -> str:
    """A profile's allowed values as the report writes them, a side the data leave open
    (the searched range's end) said so."""
    if allowed is None:
        return "n/a"
    if allowed and isinstance(allowed[0], str):
        return ", ".join(allowed)
    low, high = _value(allowed[0]), _value(allowed[1])
    if open_[0] and open_[1]:
        return f"{low} - {high} (no bound from the data: the searched range)"
    if open_[0]:
        return f"at most {high} (open below the searched {low})"
    if open_[1]:
        return f"at least {low} (open above the searched {high})"
    return f"{low} - {high}"


def told_space_toml(result: CalibrationResult) -> str | None:
    """The ``--space`` file of the fields the profile finds told, or None without a profile,
    when every field is told, or when none is (nothing left to search)."""
    prof = result.profile
    if prof is None:
        return None
    verdicts = prof.verdicts()
    told = [p for p in result.space.specs if verdicts.get(p.name) is True]
    untold = [p.name for p in result.space.specs if verdicts.get(p.name) is not True]
    if not told or not untold:
        return None
    out = io.StringIO()
    out.write(f"{TOLD_TITLE} (simlab calibrate --profile-step {prof.step:g}): a move of\n"
              f"# {prof.step:g} of its range from the winner changed the score by more than "
              f"{prof.band:.2f} times its\n# walk-to-walk spread ({prof.sigma:.4f}). Not told, "
              f"and held by a calibration that reads\n# this file: {', '.join(untold)}.\n"
              "#   simlab calibrate ... --primitives primitives.toml --space told_space.toml\n"
              "# starts from this twin and searches only the fields below.\n")
    for p in told:
        out.write(f"\n[parameters.{p.name}]\n")
        if p.categorical:
            assert p.choices is not None
            out.write(f"choices = [{', '.join(toml_value(c) for c in p.choices)}]\n")
        else:
            out.write(f"low = {toml_value(float(p.low))}\nhigh = {toml_value(float(p.high))}"
                      f"\nscale = {toml_value(p.scale)}\n")
    return out.getvalue()


def _search_table(out: io.StringIO, result: CalibrationResult) -> None:
    """Every candidate, the winner and the screening's best marked, then the notes."""
    out.write("\n## Search\n\n| # | stage | " + " | ".join(result.space.names)
              + " | distance |\n|" + "---|" * (result.space.dim + 3) + "\n")
    for c in result.candidates:
        vals = " | ".join(_value(c.values[n]) for n in result.space.names)
        mark = " **winner**" if c.index == result.best else (
            " (screening best)" if c.index == result.screen_best else "")
        out.write(f"| {c.index} | {c.stage} | {vals} | {_cell(c.distance)}{mark} |\n")
    for note in result.notes:
        out.write(f"\n{note}.\n")


def _value(v: Any) -> str:
    return v if isinstance(v, str) else _cell(float(v), "{:.4g}")


def _budget_section(result: CalibrationResult) -> str:
    b = result.budgets
    if b is None:
        return ""
    out = io.StringIO()
    out.write("## Budgets\n\n")
    screen = (f"{b.screen_hours:g} simulated hours" if b.screen_hours is not None else
              f"{b.screen_transitions} transitions")
    confirm = (f"{b.confirm_hours:g} simulated hours" if b.confirm_hours is not None else
               f"{b.confirm_transitions} transitions ({b.multiple:g} x the real ones)")
    out.write(f"Screening walks: {screen}; confirming and twin walks: {confirm}. A perfect "
              "simulator run for a multiple of the real transitions would still lie at the "
              "matched floor from the real table (bootstrap floor of the real table itself "
              f"{_cell(result.floor.median)}):\n\n| x real transitions | matched floor |\n"
              "|---|---|\n")
    for m, f in b.table:
        out.write(f"| {m:g} | {_cell(f)} |\n")
    if result.confirmed:
        out.write(f"\n{len(result.confirmed)} confirming walks:\n\n| candidate | seed | "
                  "distance | score |\n|---|---|---|---|\n")
        for c in result.confirmed:
            mark = " **winner**" if c.index == result.best else ""
            out.write(f"| {c.index}{mark} | {c.seed} | {_cell(c.distance)} | "
                      f"{_cell(c.score)} |\n")
    out.write("\n")
    return out.getvalue()


def _transfer_section(result: CalibrationResult) -> str:
    if result.transfer is None:
        return ""
    ov = transfer_overview(result.transfer)
    out = io.StringIO()
    out.write(f"## Transfer to the real robot\n\n**{transfer_headline(result)}.**\n\n"
              "A policy planned on each twin seed (its shortest-path policy to the goal) is "
              f"scored on the real model: expected decisions to reach each of {ov['goals']} "
              "goal states from every other state, against the real optimum (1.000 = "
              "optimal). The optimum of a model estimated from a few thousand real "
              "transitions is biased low, and a policy is only as good as the data it is "
              "planned on, so each score is read against a **perfect twin** (the real model "
              "itself, walked for the same data and scored the same way, by resampling).\n\n")
    _goal_table(out, result)
    out.write("| twin | steps / real optimum | worst goal | its ratio | goals never reached |"
              "\n|---|---|---|---|---|\n")
    for t in ov["twins"]:
        ratio = "never" if t["ratio"] is None else f"{t['ratio']:.3f}"
        worst = "never" if t["worst_goal_ratio"] is None else f"{t['worst_goal_ratio']:.3f}"
        out.write(f"| {t['twin']} | {ratio} | {t['worst_goal']} | {worst} | "
                  f"{t['goals_never']} |\n")
    out.write(f"\nOver the twins: mean ratio {_cell(ov['mean_ratio'])}, worst "
              f"{_cell(ov['worst_ratio'])}; a perfect twin of unlimited data scores about "
              f"{_cell(ov['perfect_twin_ratio'])} (the bias of the real optimum alone). The "
              "figure shows the goal where the twins do worst.\n\n"
              "![transfer](transfer.png)\n\n")
    if len(result.transfer_curve) > 1:
        _curve_table(out, result)
    return out.getvalue()


def _goal_table(out: io.StringIO, result: CalibrationResult) -> None:
    """Per goal: the twins' mean ratio against the perfect twin at the same data, and at
    the recommended data (with the collected policy data's score when there is one)."""
    twin = result.twin_transfer
    if twin is None or twin.line is None:
        return
    at_need = None if twin.line_at_need is None else twin.line_at_need.goal_medians
    policy = twin.policy
    out.write("| goal | twins (mean) | perfect twin, same data | gap | perfect twin, "
              "recommended data |" + (" policy data | gap |" if policy else "") + "\n|"
              + "---|" * (7 if policy else 5) + "\n")
    for k, g in enumerate(result.transfer.goals):
        r = np.array([t.ratio for t in g.twins])
        mean = float(r.mean()) if np.isfinite(r).all() else math.inf
        line = float(twin.line.goal_medians[k])
        row = (f"| {g.name} | {_steps_ratio(mean)} | {_cell(line)} | {_pct(mean, line)} | "
               f"{_cell(None if at_need is None else float(at_need[k]))} |")
        if policy:
            pr = policy["goal_ratios"][g.name]
            pl = float(policy["line"].goal_medians[k])
            row += f" {_steps_ratio(pr)} | {_pct(pr, pl)} |"
        out.write(row + "\n")
    out.write("\n")


def _steps_ratio(x: float) -> str:
    return "never" if math.isinf(x) else _cell(x)


def _pct(value: float, line: float) -> str:
    if not (math.isfinite(value) and math.isfinite(line) and line > 0):
        return "n/a"
    return f"{100 * (value / line - 1):+.1f} %"


def _curve_table(out: io.StringIO, result: CalibrationResult) -> None:
    """The data curve with the perfect twin at each size, the fitted policy data and its
    collect command."""
    out.write("A twin's policy is as good as the data it is planned on. The same twin "
              "walks pooled into fewer, larger twins (same score), beside a perfect twin of "
              "the same data:\n\n| walks per twin | twins | transitions per twin | steps / "
              "real optimum (mean) | worst | perfect twin |\n|---|---|---|---|---|---|\n")
    for row in result.transfer_curve:
        mean, worst, line = (_steps_ratio(row[k]) if row.get(k) is not None else "n/a"
                             for k in ("mean_ratio", "worst_ratio", "perfect_ratio"))
        out.write(f"| {row['walks']} | {row['pools']} | {row['transitions']} | {mean} | "
                  f"{worst} | {line} |\n")
    need = policy_data(result)
    if need is None:
        out.write("\nCollect at least the transitions of the row that reaches the "
                  "perfect-twin score before training the policy you take to the robot "
                  "(`simlab collect --hours` with the calibrated primitives).\n\n")
        return
    hours = ("" if need["hours"] is None else
             f" (about {need['hours']:.0f} h of robot time at the real rate)")
    if need["flat"]:
        out.write(f"\nThe score does not fall with more data: the twins' policies are limited "
                  f"by the twin, not its data (about {need['limit']:.3f}); **"
                  f"{need['transitions']:,.0f} twin transitions**{hours}, the largest pool, "
                  "are the policy data recommended")
    else:
        out.write(f"\nFitted to these rows, ratio = {need['limit']:.3f} + {need['c']:.0f} / "
                  f"transitions: a twin of unlimited data would score about "
                  f"{need['limit']:.3f}, and ")
        if need["below_measured"]:
            out.write(f"the smallest size measured, **{need['transitions']:,.0f} twin "
                      f"transitions**{hours}, is already within {need['tolerance']} of it (the "
                      f"fit's {need['fit_transitions']:,.0f} lie below every size measured, "
                      "where neither the fit nor the perfect twin's line was seen)")
        else:
            out.write(f"**{need['transitions']:,.0f} twin transitions**{hours} bring a policy "
                      f"within {need['tolerance']} of it")
    out.write(". Collect that much with the calibrated primitives before training the "
              f"policy you take to the robot: `{collect_line(result.real.action_set, need)}` "
              "(or `simlab calibrate --policy-data` collects and scores it).\n\n")


def policy_data(result: CalibrationResult) -> dict[str, Any] | None:
    """:func:`~simlab.calibration.policies.policy_need` of the transfer's data curve, with
    the robot hours of those transitions at the real table's rate (None when unknown)."""
    need = policy_need(result.transfer_curve)
    if need is None:
        return None
    n_real = int(result.real.counts.sum())
    hours = None if result.real.hours is None else need["transitions"] * result.real.hours / n_real
    return {**need, "transitions": round(need["transitions"]), "hours": _fin(hours)}


def collect_line(action_set: ActionSet, need: dict[str, Any]) -> str:
    """The ``simlab collect`` command of the policy data (:func:`policy_data`): the
    calibrated primitives, the real ``action_set``, every state a start, ``--hours`` (whole
    hours, rounded up) or, when the real duration is unknown, ``--transitions``."""
    flags = "".join(f" --{k.replace('_', '-')} {v}"
                    for k, v in action_set_options(action_set).items())
    size = (f"--hours {math.ceil(need['hours'])}" if need["hours"] is not None else
            f"--transitions {need['transitions']}")
    return (f"simlab collect --arena ARENA --states STATES --primitives primitives.toml"
            f"{flags} --start-states all {size} --out DIR")


def worst_goal(transfer: Any) -> Any:
    """The transfer result restricted to the goal whose twins do worst (mean ratio)."""

    def badness(g: Any) -> float:
        r = [t.ratio for t in g.twins]
        return math.inf if any(not math.isfinite(x) for x in r) else float(np.mean(r))

    g = max(transfer.goals, key=badness)
    return dataclasses.replace(transfer, goals=(g,))


def plot_calibration(result: CalibrationResult, path: Path) -> None:
    """The figure: distance per candidate with the floor band; entropy per action."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 4))
    ax1, ax2 = fig.subplots(1, 2)
    idx = np.array([c.index for c in result.candidates])
    dist = np.array([c.distance for c in result.candidates])
    conf = result.confirmed
    ax1.axhspan(result.floor.low, result.floor.high, color="0.85", label="floor (95 %)")
    ax1.axhline(result.matched_floor.median, color="0.4", ls="--", label="matched floor")
    if result.perfect_floor is not None:
        ax1.axhline(result.perfect_floor.median, color="tab:green", ls=":",
                    label="a twin equal to the robot")
    ax1.plot(idx, dist, "o", ms=4, label="rung 1 (every candidate)")
    for k, rung in enumerate(result.search.rungs if result.search is not None else []):
        ax1.plot([c.index for c in rung], [c.distance for c in rung], "s", mfc="none",
                 label=f"rung {k + 2} (walks pooled)")
    ax1.plot(idx, np.minimum.accumulate(dist), "-", color="k", lw=1, label="best so far")
    if conf:
        ax1.plot([c.index for c in conf], [c.distance for c in conf], "x", color="tab:red",
                 label="confirming walks (fresh seeds)")
    ax1.set_xlabel("candidate (order proposed)")
    ax1.set_ylabel("visit-weighted TV distance (0-1)")
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
    """Write the files of the module docstring into ``out`` in one output transaction;
    returns them by name. The figures draw the arena the twin walked (``result.arena``)
    under the states."""
    paths = check_outputs(out, overwrite=overwrite)
    if not plot:
        del paths["calibration.png"]
    if result.transfer is None or not plot:
        del paths["transfer.png"]
    if result.contradictions is None or not result.contradictions.pairs or not plot:
        del paths["pairs.png"]
    told = told_space_toml(result)
    if told is None:
        del paths["told_space.toml"]
    with output_transaction(out, paths.values(), overwrite=overwrite,
                            what="calibration output") as txn:
        atomic_write_text(txn.path(paths["primitives.toml"]), primitives_toml(result))
        atomic_write_json(txn.path(paths["report.json"]), report_json(result))
        atomic_write_text(txn.path(paths["report.md"]), report_markdown(result))
        if told is not None:
            atomic_write_text(txn.path(paths["told_space.toml"]), told)
        if "calibration.png" in paths:
            plot_calibration(result, txn.path(paths["calibration.png"]))
        if "pairs.png" in paths:
            plot_contradictions(result, txn.path(paths["pairs.png"]))
        if "transfer.png" in paths:
            from simlab.calibration.transfer import plot_transfer

            plot_transfer(worst_goal(result.transfer), txn.path(paths["transfer.png"]),
                          arena=result.arena)
    return paths
