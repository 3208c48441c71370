"""``results.md``: the table of thesis claims, our numbers and PASS/FAIL, and the figures.

Pure rendering of the JSON entries the driver records (``results.json``); nothing here
runs an experiment.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from simlab.experiments.spec import FAIL, METRIC_OPS, NOT_CHECKED, PASS, format_number


def _cell(text: Any) -> str:
    """Text safe inside a Markdown table cell."""
    return str(text).replace("|", "\\|").replace("\n", " ")


def _seconds(s: float | None) -> str:
    if s is None or (isinstance(s, float) and math.isnan(s)):
        return "—"
    if s < 60:
        return f"{s:.1f} s"
    return f"{int(s // 60)} min {s % 60:02.0f} s"


def _status_word(status: str) -> str:
    return {PASS: "**PASS**", FAIL: "**FAIL**", NOT_CHECKED: "not checked (budget)"}.get(
        status, status)


def _counts(entries: Sequence[Mapping[str, Any]]) -> dict[str, int]:
    out = {"experiments": len(entries), "errors": 0, PASS: 0, FAIL: 0, NOT_CHECKED: 0}
    for e in entries:
        if e["status"] != "ok":
            out["errors"] += 1
        for c in e.get("checks", []):
            out[c["status"]] = out.get(c["status"], 0) + 1
    return out


def render_results(header: Mapping[str, Any], entries: Sequence[Mapping[str, Any]]) -> str:
    """The Markdown of ``results.md`` for the run ``header`` and its experiment entries."""
    n = _counts(entries)
    lines = [
        "# simlab reproduce — thesis results",
        "",
        f"simlab {header.get('simlab_version')} · written {header.get('written')} · "
        f"seed {header.get('seed')} · backend {header.get('backend')} · "
        f"total wall time of the last run {_seconds(header.get('wall_seconds'))}",
        "",
        f"**{n['experiments']} experiments** ({n['errors']} failed to run) · "
        f"**{n[PASS]} checks PASS, {n[FAIL]} FAIL**, {n[NOT_CHECKED]} not checked at their "
        "budget.",
        "",
        "Each row is one check of a thesis claim: *Thesis* is the statement it encodes, "
        "*Check* the test on our metric, *Ours* our value. Quick budgets are tiny and can "
        "only show some of the shapes; the full budget uses the thesis's trial counts.",
        "",
        "| Result | Budget | Thesis | Check | Ours | Holds |",
        "|---|---|---|---|---|---|",
    ]
    for e in entries:
        title = f"[{_cell(e['reference'])}: {_cell(e['title'])}](#{e['name']})"
        budget = e.get("budget", "—")
        if e["status"] != "ok":
            lines.append(f"| {title} | {budget} | {_cell(e['claim'])} | — | "
                         f"{_cell(e.get('error', 'error'))} | **ERROR** |")
            continue
        checks = e.get("checks", [])
        if not checks:
            lines.append(f"| {title} | {budget} | {_cell(e['claim'])} | (no checks) | "
                         f"see below | — |")
        for i, c in enumerate(checks):
            first = title if i == 0 else "″"
            ours = format_number(c["ours"]) if c["ours"] is not None else "—"
            if c.get("op") in METRIC_OPS and c["status"] != NOT_CHECKED:
                ours = _cell(c["detail"])  # our value and the other metric's bound
            lines.append(f"| {first} | {budget} | {_cell(c['thesis'])} | "
                         f"`{_cell(c['check'])}` | {ours} | {_status_word(c['status'])} |")
    lines += ["", "## Wall time per experiment", "",
              "| Experiment | Budget | Backend | Wall time | Status |", "|---|---|---|---|---|"]
    for e in entries:
        lines.append(f"| {e['name']} | {e.get('budget', '—')} | {e.get('backend', '—')} | "
                     f"{_seconds(e.get('wall_seconds'))} | {e['status']} |")
    for e in entries:
        lines += ["", f"<a id=\"{e['name']}\"></a>",
                  f"## {_cell(e['reference'])}: {_cell(e['title'])}", "",
                  f"*{e['claim']}*", "",
                  f"`{e['name']}` · runner `{e['runner']}` · budget {e.get('budget')} "
                  f"({_budget_text(e.get('budget_table', {}))}) · "
                  f"{_seconds(e.get('wall_seconds'))} · written {e.get('written', '—')}"]
        if e["status"] != "ok":
            lines += ["", f"**ERROR**: {e.get('error', '')} (traceback in "
                          f"[{e['name']}/error.txt]({e['name']}/error.txt))"]
            continue
        metrics = e.get("metrics", {})
        if metrics:
            lines += ["", "| Metric | Value |", "|---|---|"]
            lines += [f"| {_cell(k)} | {format_number(v) if v is not None else '—'} |"
                      for k, v in metrics.items()]
        for c in e.get("checks", []):
            if c["status"] == FAIL:
                lines += ["", f"FAIL: `{c['check']}` ({c['detail']}) — thesis: {c['thesis']}"]
        for note in e.get("notes", []):
            lines += ["", f"> {note}"]
        figures = e.get("figures", [])
        if figures:
            lines.append("")
            for f in figures:
                if str(f).lower().endswith((".png", ".gif", ".jpg", ".svg")):
                    lines.append(f"![{f}]({f})")
                else:
                    lines.append(f"- [{f}]({f})")
    return "\n".join(lines) + "\n"


def _budget_text(table: Mapping[str, Any]) -> str:
    return ", ".join(f"{k} {v}" for k, v in table.items()) or "—"
