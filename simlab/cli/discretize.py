"""``simlab discretize``: Voronoi states on an occupancy map (thesis Fig. 3.5).

The options are the fields of :class:`discretize.command.DiscretizeConfig`.
"""

from __future__ import annotations

import argparse

HELP = "place Voronoi state centres on a map_server map and save them as JSON (and a figure)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from discretize.command import DiscretizeConfig

    DiscretizeConfig.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from discretize.command import DiscretizeConfig, discretize_command

    result = discretize_command(DiscretizeConfig.from_args(args))
    disc = result.discretizer
    line = f"{disc.n_states} states ({disc.method}) -> {result.out}"
    if result.png is not None:
        line += f", figure {result.png}"
    print(line)
    print(f"content hash {disc.content_hash()[:16]}, map hash {(disc.map_hash or '-')[:16]}")
    if result.visits is not None:
        unvisited = int((result.visits == 0).sum())
        print(f"visits: {int(result.visits.sum())} total, {unvisited} states unvisited")
    return 0
