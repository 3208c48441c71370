"""Summary, Parquet log, figures and markdown of ``simlab online`` (:mod:`simlab.online.command`).

Definitions (per arm, each a mean over runs, with the standard deviation beside it):

* ``reward`` — total reward over the run; ``reward_before`` / ``reward_after`` — before and
  from the change on (None without a change);
* ``backups`` / ``seconds`` — total planning cost of the deciding experts, and of the
  other expert at a state's first visit under ``plan_both_first`` (deterministic, wall
  clock); ``cost_vs_mb`` / ``seconds_vs_mb`` — divided by the ``mb`` arm's (None
  without an ``mb`` arm); the same before / after the change;
* ``mb_share`` — fraction of decisions planned by MB; ``mb_share_windows`` — per window of
  ``window`` decisions;
* ``recovery_decisions`` — decisions after the change until the reward rate of a window
  (mean over runs) first reaches 80 % of the rate over the last ``3 * window`` decisions
  before it (None: not within the run). ``rate_after_vs_before`` — reward rate after the
  change over the rate before (whole phases);
* ``restarts`` — runs that started again for want of a reward (``restart_after``): mean
  restarts per run and the runs concerned;
* ``chosen`` — for a change chosen by use, per run the alternative that happened and
  ``use_counts`` the decisions each counting state saw before the change.

The run-level ``protocol`` records the rules applied (:meth:`OnlineConfig.rules_summary`).
``decisions.parquet`` carries each column's ``unit`` and ``description`` in its Parquet
field metadata (and all of them as JSON under the schema key ``simlab.columns``), as the
datasets of ``simlab collect`` do.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base.io import atomic_write, atomic_write_bytes, atomic_write_json, atomic_write_text

__all__ = ["DECISION_DOCS", "MARKER", "decision_docs", "online_figures", "summarize",
           "window_centres", "write_outputs"]

#: ``summary.json``'s ``command`` value: what ``--overwrite`` recognises as its own.
MARKER = "simlab online"

#: Recovery threshold (fraction of the pre-change reward rate).
RECOVERY = 0.8

#: Unit and meaning of every column of ``decisions.parquet`` (``COST`` stands for the unit
#: of the cost the criterion reads: backups, or s with ``--cost seconds``).
DECISION_DOCS: dict[str, tuple[str, str]] = {
    "arm": ("1", "arm: the criterion (entropy_and_cost once per kappa, named _k<kappa>)"),
    "seed": ("1", "run index within the arm (runs of one index share their random streams)"),
    "t": ("1", "decision index within the run, from 0"),
    "s": ("1", "state of the decision"),
    "a": ("1", "action taken"),
    "s_next": ("1", "state after the action"),
    "expert": ("1", "expert whose plan gave the action: MF or MB"),
    "h_mf": ("1", "MF's normalised entropy read by the criterion, in [0, 1]"),
    "h_mb": ("1", "MB's normalised entropy read by the criterion, in [0, 1]"),
    "c_mf": ("COST", "MF's filtered planning cost at the state read by the criterion"),
    "c_mb": ("COST", "MB's filtered planning cost at the state read by the criterion"),
    "backups": ("backups", "Bellman backups of the plan(s) of this decision"),
    "seconds": ("s", "wall-clock time of the plan(s) of this decision"),
    "reward": ("1", "reward of the decision (on arriving in s_next)"),
    "phase": ("1", "task phase: 0 before the change, then the change (the alternative "
                   "chosen by use)"),
    # a run in physics (simlab online --arena)
    "blocked": ("1", "the obstacle detector stopped the primitive before it drove"),
    "duration": ("s", "simulated time of the decision: the primitive and the decision latency"),
    "x": ("m", "true x of the robot after the decision (map frame)"),
    "y": ("m", "true y of the robot after the decision (map frame)"),
    "undone": ("1", "moves taken back before this decision's because they crossed a passage "
                    "closed by removing its transitions"),
}


def decision_docs(cost: str) -> dict[str, tuple[str, str]]:
    """:data:`DECISION_DOCS` with the cost unit of ``cost`` (``backups`` or ``seconds``)."""
    unit = "s" if cost == "seconds" else "backups"
    return {k: (unit if u == "COST" else u, text) for k, (u, text) in DECISION_DOCS.items()}


def _ms(x: np.ndarray) -> dict[str, float]:
    return {"mean": float(np.mean(x)), "std": float(np.std(x))}


def windows(x: np.ndarray, w: int) -> np.ndarray:
    """(runs, n) -> (runs, ceil(n / w)) means per window."""
    runs, n = x.shape
    k = -(-n // w)
    pad = np.full((runs, k * w), np.nan)
    pad[:, :n] = x
    return np.nanmean(pad.reshape(runs, k, w), axis=2)


def window_centres(n: int, w: int) -> np.ndarray:
    """(ceil(n / w),) the middle of each window of :func:`windows` in decisions: the last,
    partial window is drawn at the middle of the decisions it holds, inside the run."""
    starts = np.arange(0, n, w, dtype=float)
    return (starts + np.minimum(starts + w, n)) / 2.0


def _stack(logs: list[dict[str, np.ndarray]], col: str) -> np.ndarray:
    return np.stack([lg[col] for lg in logs]).astype(np.float64)


def _recovery(reward: np.ndarray, at: int, w: int) -> int | None:
    mean = reward.mean(axis=0)
    lo = max(0, at - 3 * w)
    before = mean[lo:at].mean() if at > lo else 0.0
    if before <= 0:
        return None
    for end in range(at + w, mean.shape[0] + 1, max(1, w // 4)):
        if mean[end - w:end].mean() >= RECOVERY * before:
            return int(end - at)
    return None


def summarize(logs: dict[str, list[dict[str, np.ndarray]]], cfg: Any, task: Any, m: Any,
              mf_cfg: Any, mb_cfg: Any) -> dict[str, Any]:
    """The JSON-ready summary of every arm (module docstring)."""
    import simlab
    from simlab.agents.config import config_to_dict

    at = task.changes[0].at if task.changes else None
    arms: dict[str, Any] = {}
    totals: dict[str, dict[str, np.ndarray]] = {}
    for name, runs in logs.items():
        r = _stack(runs, "reward")
        b = _stack(runs, "backups")
        sec = _stack(runs, "seconds")
        e = _stack(runs, "expert")
        rec: dict[str, Any] = {
            "reward": _ms(r.sum(1)), "backups": _ms(b.sum(1)), "seconds": _ms(sec.sum(1)),
            "mb_share": float(e.mean()),
            "mb_share_windows": [round(float(x), 4) for x in windows(e, cfg.window).mean(0)],
        }
        totals[name] = {"b": b.sum(1), "s": sec.sum(1)}
        if at is not None:
            rec["reward_before"] = _ms(r[:, :at].sum(1))
            rec["reward_after"] = _ms(r[:, at:].sum(1))
            rec["mb_share_before"] = float(e[:, :at].mean())
            rec["mb_share_after"] = float(e[:, at:].mean())
            rate_b = r[:, :at].mean()
            rec["rate_after_vs_before"] = (float(r[:, at:].mean() / rate_b) if rate_b > 0
                                           else None)
            rec["recovery_decisions"] = _recovery(r, at, cfg.window)
            totals[name].update(bb=b[:, :at].sum(1), ba=b[:, at:].sum(1))
        arms[name] = rec
    if "mb" in totals:
        ref = totals["mb"]
        for name, rec in arms.items():
            t = totals[name]
            rec["cost_vs_mb"] = float(t["b"].mean() / ref["b"].mean())
            rec["seconds_vs_mb"] = float(t["s"].mean() / ref["s"].mean())
            rec["reward_vs_mb"] = (rec["reward"]["mean"] / arms["mb"]["reward"]["mean"]
                                   if arms["mb"]["reward"]["mean"] > 0 else None)
            if at is not None:
                rec["cost_vs_mb_before"] = float(t["bb"].mean() / ref["bb"].mean())
                rec["cost_vs_mb_after"] = float(t["ba"].mean() / ref["ba"].mean())
    for name, runs in logs.items():
        arms[name].update(_run_fields(runs, task))
    return {
        "command": MARKER,
        "simlab_version": simlab.__version__,
        "protocol": cfg.rules_summary(),
        "mdp": None if m.source is None else str(m.source),
        "states": m.n_states, "actions": m.n_actions,
        "task": task.as_dict(),
        "change": None if not task.changes else task.changes[0].describe(),
        "decisions": cfg.decisions, "seeds": cfg.seeds, "seed": cfg.seed,
        "cost": cfg.cost, "cost_alpha": cfg.cost_alpha, "prob_alpha": cfg.prob_alpha,
        "reward_ends": cfg.reward_ends, "state_reward": cfg.state_reward,
        "plan_both_first": cfg.plan_both_first, "window": cfg.window,
        "experts": {"mf": {"agent": cfg.mf, "config": config_to_dict(mf_cfg)},
                    "mb": {"agent": cfg.mb, "config": config_to_dict(mb_cfg)}},
        "arms": arms,
    }


def _alternatives(task: Any) -> list[str]:
    """Labels of the alternatives of the task's change chosen by use (empty: none)."""
    c = task.changes[-1] if task.changes else None
    if c is None or not c.use_states:
        return []
    if c.kind == "model":
        return list(c.names) or [f"model {k + 1}" for k in range(len(c.after))]
    return [f"{u}-{v}" for u, v in c.passages]


def _run_fields(runs: list[dict[str, np.ndarray]], task: Any) -> dict[str, Any]:
    """Per arm: restarts, and for a change chosen by use the alternative of each run."""
    restarts = [int(r.get("restarts", 0)) for r in runs]
    out: dict[str, Any] = {"restarts": {"mean": float(np.mean(restarts)),
                                        "runs": int(np.count_nonzero(restarts))}}
    labels = _alternatives(task)
    if labels:
        first = len(runs[0]["use_counts"]) - len(labels)  # the alternatives' first phase
        at = task.changes[-1].at
        out["chosen"] = [labels[int(r["phase"][at]) - first] for r in runs]
        out["use_counts"] = [dict(zip(labels, (int(x) for x in r["use_counts"][first:]),
                                      strict=True)) for r in runs]
    return out


def _markdown(summary: dict[str, Any]) -> str:
    lines = [f"# simlab online: {summary['seeds']} runs x {summary['decisions']} decisions",
             "", f"MDP: {summary['mdp'] or '(in memory)'} ({summary['states']} states, "
             f"{summary['actions']} actions); change: {summary['change'] or 'none'}; cost "
             f"measure deciding: {summary['cost']}.", "", _protocol_line(summary["protocol"]),
             ""]
    change = summary["change"] is not None
    head = "| arm | reward | cost vs MB | wall time vs MB | MB share |"
    sep = "|---|---|---|---|---|"
    if change:
        head += " reward before | reward after | recovery (decisions) |"
        sep += "---|---|---|"
    lines += [head, sep]

    def f(x: Any, spec: str = ".2f") -> str:
        return "-" if x is None else format(x, spec)

    for name, a in summary["arms"].items():
        row = (f"| {name} | {a['reward']['mean']:.1f} ± {a['reward']['std']:.1f} | "
               f"{f(a.get('cost_vs_mb'))} | {f(a.get('seconds_vs_mb'))} | "
               f"{a['mb_share']:.2f} |")
        if change:
            row += (f" {a['reward_before']['mean']:.1f} | {a['reward_after']['mean']:.1f} | "
                    f"{f(a['recovery_decisions'], 'd')} |")
        lines.append(row)
    for name, a in summary["arms"].items():
        if a["restarts"]["runs"]:
            lines.append(f"- {name}: {a['restarts']['runs']} run(s) restarted for want of a "
                         f"reward ({a['restarts']['mean']:.2f} restarts per run)")
        if "chosen" in a:
            tally = {c: a["chosen"].count(c) for c in dict.fromkeys(a["chosen"])}
            lines.append(f"- {name}: the more used of the alternatives happened: " + ", ".join(
                f"{c} in {k} run(s)" for c, k in tally.items()))
    lines += ["", "Costs are planning costs of the deciding expert, and of both experts at a "
              "state's first visit when both plan there (value-iteration backups; wall-clock "
              "seconds beside them), relative to MB deciding alone."]
    if "physics" in summary:
        lines += _physics_markdown(summary["physics"], change)
    return "\n".join(lines) + "\n"


def _physics_markdown(phys: dict[str, Any], change: bool) -> list[str]:
    lines = ["", "## In physics", "",
             "| arm | blocked primitives | before / after the change | simulated hours per "
             "run | decisions per wall second |", "|---|---|---|---|---|"]
    for name, a in phys["arms"].items():
        split = (f"{a['blocked_before']:.3f} / {a['blocked_after']:.3f}" if change else "-")
        lines.append(f"| {name} | {a['blocked']:.3f} | {split} | "
                     f"{a['robot_hours']['mean']:.2f} | {a['decisions_per_wall_second']:.0f} |")
    undone = {name: a["undone_after"] for name, a in phys["arms"].items()
              if a.get("undone_after")}
    if undone:
        lines.append("\nMoves taken back across a passage closed by removing its transitions, "
                     "per decision after the change: "
                     + ", ".join(f"{name} {u:.3f}" for name, u in undone.items()) + ".")
    for box in phys["boxes"]:
        x, y, sx, sy, yaw = box
        lines.append(f"\nBox added: centre ({x:.2f}, {y:.2f}) m, {sx:.2f} x {sy:.2f} m, yaw "
                     f"{np.degrees(yaw):.0f} degrees.")
    ens = phys.get("ensemble")
    if ens is not None:
        runs = ", ".join(f"run {i}: {m}" for i, m in enumerate(ens["run_members"]))
        lines.append(f"\nTwin ensemble of {ens['size']} members (0 is calibrate's winner); "
                     f"the member each run drove, in every arm: {runs}.")
    return lines


def _protocol_line(protocol: dict[str, Any]) -> str:
    rules = ", ".join(f"{k} {v}" for k, v in protocol["rules"].items())
    given = protocol["overridden"]
    return (f"Protocol: {protocol['name']} ({rules})"
            + (f"; given against it: {', '.join(given)}." if given else "."))


def online_figures(logs: dict[str, list[dict[str, np.ndarray]]], summary: dict[str, Any],
                   window: int) -> dict[str, Any]:
    """File name -> matplotlib Figure: cumulative reward, cumulative planning cost and the
    share of model-based decisions per window, per arm; x from 0 to the runs' length."""
    from matplotlib.figure import Figure

    at = summary["task"]["changes"][0]["at"] if summary["task"]["changes"] else None
    n = max(r["reward"].shape[0] for runs in logs.values() for r in runs)
    out = {}
    for fname, col, ylabel, cum in (
            ("cumulative_reward.png", "reward", "cumulative reward (sum of rewards)", True),
            ("cumulative_cost.png", "backups", "cumulative planning cost (backups)", True),
            ("mb_share.png", "expert", f"MB decisions (share, window {window})", False)):
        fig = Figure(figsize=(6.4, 4.2), layout="constrained")
        ax = fig.add_subplot()
        for name, runs in logs.items():
            x = _stack(runs, col)
            if cum:
                y = np.cumsum(x, axis=1)
                t = np.arange(1, y.shape[1] + 1)
                mean, std = y.mean(0), y.std(0)
                ax.plot(t, mean, label=name)
                # a cumulative sum is >= 0: the band of one std is clipped there
                ax.fill_between(t, np.maximum(mean - std, 0.0), mean + std, alpha=0.15)
            else:
                ax.plot(window_centres(x.shape[1], window), windows(x, window).mean(0),
                        marker="o", ms=3, label=name)
        if at is not None:
            ax.axvline(at, color="k", ls="--", lw=1, label="change")
        if col == "backups":
            ax.set_yscale("symlog")
        ax.set_xlabel("decision (count)")
        ax.set_xlim(0, n)
        ax.set_ylabel(ylabel)
        ax.legend(fontsize=7)
        out[fname] = fig
    return out


def _figures(logs: dict[str, list[dict[str, np.ndarray]]], summary: dict[str, Any],
             window: int) -> dict[str, bytes]:
    import matplotlib

    matplotlib.use("Agg")
    out = {}
    for fname, fig in online_figures(logs, summary, window).items():
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=90)
        out[fname] = buf.getvalue()
    return out


def write_outputs(txn: Any, finals: dict[str, Path], logs: dict[str, list[dict[str, np.ndarray]]],
                  summary: dict[str, Any], cfg: Any, *,
                  extra_figures: dict[str, bytes] | None = None,
                  run_fields: tuple[str, ...] = ()) -> None:
    """Write every output to its staged path of the transaction ``txn``; a run in physics
    adds its figures (``extra_figures``, PNG bytes by file name) and names the fields of its
    logs that are per run, not per decision (``run_fields``: not columns of
    ``decisions.parquet``)."""
    import json

    import pyarrow as pa
    import pyarrow.parquet as pq

    from simlab.online.loop import RUN_FIELDS

    cols: dict[str, list[np.ndarray]] = {}
    for name, runs in logs.items():
        for i, lg in enumerate(runs):
            n = lg["s"].shape[0]
            extra = {"arm": np.full(n, name, dtype=object), "seed": np.full(n, i, np.int32),
                     "t": np.arange(n, dtype=np.int32)}
            for k, val in {**extra, **lg}.items():
                if k in RUN_FIELDS or k in run_fields:
                    continue
                if k == "expert":
                    val = np.where(val == 1, "MB", "MF").astype(object)
                cols.setdefault(k, []).append(val)
    docs = decision_docs(cfg.cost)
    arrays = {k: pa.array(np.concatenate(v)) for k, v in cols.items()}
    fields = [pa.field(k, a.type).with_metadata(
        {b"unit": docs[k][0].encode(), b"description": docs[k][1].encode()} if k in docs else {})
        for k, a in arrays.items()]
    schema = pa.schema(fields, metadata={b"simlab.columns": json.dumps(
        {k: {"unit": u, "description": d} for k, (u, d) in docs.items() if k in arrays}
    ).encode()})
    table = pa.Table.from_arrays(list(arrays.values()), schema=schema)
    with atomic_write(txn.path(finals["decisions.parquet"]), "wb") as fh:
        pq.write_table(table, fh)
    if cfg.plots:
        for fname, data in {**_figures(logs, summary, cfg.window),
                            **(extra_figures or {})}.items():
            atomic_write_bytes(txn.path(finals[fname]), data)
    summary = {**summary, "files": {k: str(p) for k, p in finals.items()}}
    atomic_write_json(txn.path(finals["summary.json"]), summary)
    atomic_write_text(txn.path(finals["summary.md"]), _markdown(summary))


def owned_by_online(out: Path) -> bool:
    """True when ``out/summary.json`` was written by ``simlab online`` (its marker)."""
    import json

    try:
        return json.loads((Path(out) / "summary.json").read_text()).get("command") == MARKER
    except (OSError, ValueError, AttributeError):
        return False
