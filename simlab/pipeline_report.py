"""``report.md`` of a pipeline run: the key numbers beside the thesis's, and every figure."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from simlab import __version__
from simlab.io import atomic_write_text


def _rel(path: Path, root: Path) -> str:
    return path.relative_to(root).as_posix()


def _fig(root: Path, path: Path, caption: str) -> str:
    if not path.exists():
        return f"*({caption}: not produced)*\n"
    return f"![{caption}]({_rel(path, root)})\n\n*{caption}*\n"


def write_report(p: Any, cfg: Any, state: dict[str, Any]) -> Path:
    """Write ``p.report`` from the stage numbers in ``state`` (see :mod:`simlab.pipeline`)."""
    st = state["stages"]
    m, s, d, mdp, tr, rp = (st.get(k, {}) for k in
                            ("map", "states", "dataset", "mdp", "train", "replay"))
    root = p.out
    lines = [
        f"# simlab pipeline report: arena `{cfg.arena}`",
        "",
        f"simlab {__version__}, seed {cfg.seed}. Every number below was measured in this run;",
        "the thesis column gives the result we reproduce (Amini 2023, ch. 3-4).",
        "",
        "## Key numbers",
        "",
        "| quantity | this run | thesis |",
        "|---|---|---|",
    ]
    row = lines.append
    if m:
        row(f"| map accuracy vs arena geometry (walls / free space) | {m['wall_correct']:.1%} / "
            f"{m['free_correct']:.1%} after {m['robot_minutes']:.0f} robot-min | GMapping, "
            "73.1 min exploration |")
    if s:
        row(f"| Markov states (Voronoi cells) | {s['states']} | 41 |")
    if d:
        row(f"| random-walk transitions | {d['transitions']:,} in {d['simulated_hours']:.1f} "
            f"simulated h ({d['collect_wall_seconds']:.0f} s wall, {cfg.workers} workers) | "
            "8,448 in about 10 h of robot time |")
    if mdp:
        row(f"| (s, a) pairs visited | {mdp['fraction_visited']:.1%} | - |")
        order = "fast > slow" if mdp["entropy_fast"] > mdp["entropy_slow"] else "fast <= slow"
        row(f"| mean transition entropy, slow / fast actions | {mdp['entropy_slow']:.2f} / "
            f"{mdp['entropy_fast']:.2f} bits ({order}) | fast actions higher (Fig. 4.8) |")
    if tr:
        r, g = tr.get("min_ratio_to_optimal"), tr.get("min_greedy_ratio")
        if r is not None:
            row(f"| {tr['agent']} after {cfg.episodes} episodes, worst of "
                f"{len(tr['goals'])} goals: on-policy / greedy return vs optimal | {r:.0%} / "
                f"{g:.0%} | a good policy after about 2,000 episodes (Fig. 4.9) |")
    if rp:
        if "reward_rate_per_hour" in rp:
            rate, rnd = rp["reward_rate_per_hour"], rp.get("random_rate_per_hour")
            pred = rp.get("predicted_rate_per_hour")
            row(f"| replay: goals reached per hour (learned / random) | {rate:.1f} / "
                f"{rnd:.1f} ({rate / rnd:.1f}x) | cumulative reward grows linearly (Fig. 4.10) |"
                if rnd else f"| replay: goals reached per hour | {rate:.1f} | - |")
            if pred:
                row(f"| replay vs MDP-predicted rate | {rate:.1f} vs {pred:.1f} "
                    f"({rate / pred - 1:+.0%}: the sim-to-model gap) | - |")
        if "position_error_mean_m" in rp:
            row(f"| localization ({cfg.pose_source}) mean position error | "
                f"{rp['position_error_mean_m'] * 100:.1f} cm | AMCL on the GMapping map |")
    lines += ["", "## Figures", ""]
    lines.append(_fig(root, p.states_png, "Occupancy map and Voronoi states (thesis Fig. 3.5)"))
    lines.append(_fig(root, p.visits_png, "Visits per state in the random walk (log10)"))
    lines.append(_fig(root, p.mdp.with_name("mdp_entropy.png"),
                      "Mean transition entropy per action (thesis Fig. 4.8)"))
    lines.append(_fig(root, p.qtables / "curves.png",
                      "Learning curves on the empirical MDP, per goal (thesis Fig. 4.9)"))
    lines.append(_fig(root, p.qtables / "heatmaps.png",
                      "max_a Q and argmax arrows per goal (thesis Fig. 4.3)"))
    lines.append(_fig(root, p.replay / "cumulative_reward.png",
                      "Cumulative reward over the replay (thesis Fig. 4.10)"))
    lines.append(_fig(root, p.replay / "replay.gif",
                      "Top-down replay: map, values of the current goal, robot, trail (Fig. 4.11)"))
    lines += ["", "## Stage timings", "", "| stage | wall time (s) |", "|---|---|"]
    total = 0.0
    for name, numbers in st.items():
        total += numbers.get("wall_seconds", 0.0)
        lines.append(f"| {name} | {numbers.get('wall_seconds', 0.0):.1f} |")
    lines.append(f"| **total** | **{total:.1f}** |")
    lines += ["", "Settings: " + ", ".join(f"{k}={v}" for k, v in state["config"].items()), ""]
    atomic_write_text(p.report, "\n".join(lines))
    return p.report
