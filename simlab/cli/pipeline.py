"""``simlab pipeline``: map -> states -> 10-hour walk -> empirical MDP -> training -> replay."""

from __future__ import annotations

import argparse

HELP = ("the physics half end to end: map, Voronoi states, random-walk dataset, empirical MDP, "
        "training on 9 goals, 3-hour closed-loop replay, report.md")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from simlab.orchestration.pipeline import PipelineConfig

    PipelineConfig.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from simlab.orchestration.pipeline import PipelineConfig, pipeline

    res = pipeline(PipelineConfig.from_args(args))
    print(f"done in {res.wall_seconds:.0f} s: {res.report}")
    return 0
