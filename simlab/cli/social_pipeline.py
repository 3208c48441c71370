"""``simlab social-pipeline``: the social task on the table, closed loop (issue 18)."""

from __future__ import annotations

import argparse

HELP = ("the social task in physics: train the grid social module, lead a simulated human "
        "through the table's goal areas closed loop vs a random policy; summary, plot, GIF")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from simlab.social.pipeline import SocialPipelineConfig

    SocialPipelineConfig.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from simlab.social.pipeline import SocialPipelineConfig, social_pipeline

    res = social_pipeline(SocialPipelineConfig.from_args(args))
    pooled = res.summary["pooled"]
    c, r = pooled["combined"], pooled["random"]
    ratio = res.summary["goal_rate_ratio"]
    print(f"combined: {c['goals']} goal areas reached with the human in {c['hours']:.2f} "
          f"simulated h = {c['goals_per_hour']:.1f} /h; random: {r['goals']} = "
          f"{r['goals_per_hour']:.1f} /h; ratio "
          + ("undefined (random reached none)" if ratio is None else f"{ratio:.1f}"))
    print("wrote " + ", ".join(str(p) for p in res.paths.values()))
    return 0
