"""``simlab social-pipeline``: the social task on the table, closed loop (thesis 2.1.2, 3.1.1)."""

from __future__ import annotations

import argparse

HELP = ("the social task in physics: train the social module (grid, empirical MDP of a "
        "physics walk, or both), lead a simulated human through the table's goal areas "
        "closed loop vs a random policy; summary, plot, GIF")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from simlab.social.pipeline import SocialPipelineConfig

    SocialPipelineConfig.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from simlab.social.pipeline import SocialPipelineConfig, social_pipeline

    res = social_pipeline(SocialPipelineConfig.from_args(args))
    pooled = res.summary["pooled"]
    r = pooled["random"]
    ratio = res.summary["goal_rate_ratio"]
    learned = [p for p in ("combined", "empirical") if p in pooled]
    c = pooled[learned[0]]
    parts = [f"{learned[0]}: {c['goals']} goal areas reached with the human in "
             f"{c['hours']:.2f} simulated h = {c['goals_per_hour']:.1f} /h"]
    parts += [f"{p}: {pooled[p]['goals']} = {pooled[p]['goals_per_hour']:.1f} /h"
              for p in learned[1:]]
    parts.append(f"random: {r['goals']} = {r['goals_per_hour']:.1f} /h; ratio "
                 + ("undefined (random reached none)" if ratio is None else f"{ratio:.1f}"))
    print("; ".join(parts))
    predicted = res.summary["predicted_goals_per_hour"]
    if predicted:
        print("predicted by the empirical MDP (renewal model) / measured: " + "; ".join(
            f"{p} {v['goals_per_hour']:.1f} / {v['measured_goals_per_hour']:.1f} /h"
            for p, v in predicted.items()))
    print("wrote " + ", ".join(str(p) for p in res.paths.values()))
    return 0
