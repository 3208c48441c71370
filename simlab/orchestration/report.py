"""``report.md`` of a pipeline run: the key numbers beside the thesis's, and every figure."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from simlab import __version__
from simlab.base.io import atomic_write_text


def train_ratios(record: dict[str, Any]) -> tuple[float | None, float | None]:
    """Worst goal's (on-policy, greedy) return over the optimal, from a train record
    (the ``summary`` of the ``train`` stage: ``{"goals": {goal: {"ratio", ...}}}``).
    It lives here, not in the pipeline, so that the report never imports the pipeline."""
    goals = record.get("goals", {}).values()
    ratios = [g["ratio"] for g in goals if g.get("ratio") is not None]
    greedy = [g["greedy_ratio"] for g in goals if g.get("greedy_ratio") is not None]
    return (min(ratios) if ratios else None, min(greedy) if greedy else None)


def _fig(out: Path, rel: str, caption: str) -> str:
    if not (out / rel).exists():
        return f"*({caption}: not produced)*\n"
    return f"![{caption}]({rel})\n\n*{caption}*\n"


#: The figures of the report, in order: (path under the run's folder, caption).
FIGURES = (
    ("states/states.png", "Occupancy map and Voronoi states (thesis Fig. 3.5)"),
    ("figures/states_visits.png", "Visits per state in the random walk (log10)"),
    ("mdp/mdp_entropy.png", "Mean transition entropy per action (thesis Fig. 4.8)"),
    ("qtables/curves.png", "Learning curves on the empirical MDP, per goal (thesis Fig. 4.9)"),
    ("qtables/heatmaps.png", "max_a Q and argmax arrows per goal (thesis Fig. 4.3)"),
    ("replay/cumulative_reward.png", "Cumulative reward over the replay (thesis Fig. 4.10)"),
    ("replay/replay.gif",
     "Top-down replay: map, values of the current goal, robot, trail (Fig. 4.11)"),
)


def write_report(out: Path, s: Any, seed: int, state: dict[str, Any]) -> Path:
    """Write ``out/report.md`` from the stage records in ``state`` (see
    :mod:`simlab.orchestration.pipeline`); ``s`` are the run's
    :class:`~simlab.orchestration.stages.PhysicsSettings`."""
    st = state["stages"]
    lines = [
        f"# simlab pipeline report: arena `{s.arena}`",
        "",
        f"simlab {__version__}, seed {seed}. Every number below was measured in this run;",
        "the thesis column gives the result we reproduce (Amini 2023, ch. 3-4).",
        "",
        "## Key numbers",
        "",
        "| quantity | this run | thesis |",
        "|---|---|---|",
        *_key_rows(s, st),
    ]
    lines += ["", "## Figures", ""]
    lines += [_fig(out, rel, caption) for rel, caption in FIGURES]
    lines += ["", "## Stages", "",
              "| stage | folder | this run | wall time (s) |", "|---|---|---|---|"]
    for name, rec in st.items():
        how = "built" if rec.get("built") else "reused"
        lines.append(f"| {name} | `{rec['folder']}/` | {how} | {rec.get('wall_seconds', 0):.1f} |")
    lines += ["", f"Settings (seed {seed}): "
              + ", ".join(f"{k}={v}" for k, v in state["settings"].items()), ""]
    report = out / "report.md"
    atomic_write_text(report, "\n".join(lines))
    return report


def _key_rows(s: Any, st: dict[str, Any]) -> list[str]:
    """The rows of the key-numbers table (this run against the thesis) for the stages
    ``st`` that ran; ``s`` are the run's settings."""
    m, d, mdp, tr, rp = (st.get(k, {}) for k in ("map", "dataset", "mdp", "train", "replay"))
    n_states = st.get("states", {}).get("n_states")
    rows: list[str] = []
    row = rows.append
    if m:
        row(f"| map accuracy vs arena geometry (walls / free space) | {m['wall_correct']:.1%} / "
            f"{m['free_correct']:.1%} after {s.map_minutes:g} robot-min | GMapping, 73.1 min "
            "exploration |")
    if n_states:
        row(f"| Markov states (Voronoi cells) | {n_states} | 41 |")
    if d:
        row(f"| random-walk transitions | {d['transitions']:,} in {d['simulated_hours']:.1f} "
            f"simulated h ({d['collect_wall_seconds']:.0f} s wall, {s.workers} workers) | "
            "8,448 in about 10 h of robot time |")
    if mdp:
        row(f"| (s, a) pairs visited | {mdp['fraction_visited']:.1%} | - |")
        order = "fast > slow" if mdp["entropy_fast"] > mdp["entropy_slow"] else "fast <= slow"
        row(f"| mean transition entropy, slow / fast actions | {mdp['entropy_slow']:.2f} / "
            f"{mdp['entropy_fast']:.2f} bits ({order}) | fast actions higher (Fig. 4.8) |")
    if tr:
        worst, greedy = train_ratios(tr)
        if worst is not None and greedy is not None:
            row(f"| {s.agent} after {s.episodes} episodes, worst of {len(tr['goals'])} goals: "
                f"on-policy / greedy return vs optimal | {worst:.0%} / {greedy:.0%} | a good "
                "policy after about 2,000 episodes (Fig. 4.9) |")
    rate, rnd = rp.get("reward_rate_per_hour"), rp.get("random_rate_per_hour")
    pred = rp.get("predicted_rate_per_hour")
    if rate is not None and rnd:
        row(f"| replay: goals reached per hour (learned / random) | {rate:.1f} / {rnd:.1f} "
            f"({rate / rnd:.1f}x) | cumulative reward grows linearly (Fig. 4.10) |")
    if rate is not None and pred:
        row(f"| replay vs MDP-predicted rate | {rate:.1f} vs {pred:.1f} "
            f"({rate / pred - 1:+.0%}: the sim-to-model gap) | - |")
    if rp.get("position_error_mean_m") is not None:
        row(f"| localization ({s.pose_source}) mean position error | "
            f"{rp['position_error_mean_m'] * 100:.1f} cm | AMCL on the GMapping map |")
    return rows
