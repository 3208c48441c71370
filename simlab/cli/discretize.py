"""``simlab discretize``: Voronoi states on an occupancy map (thesis Fig. 3.5).

The options are the fields of :class:`discretize.voronoi.DiscretizeConfig`.
"""

from __future__ import annotations

import argparse
from typing import Any

HELP = "place Voronoi state centres on a map_server map and save them as JSON (and a figure)"


class _OneOf:
    """The parser as :meth:`DiscretizeConfig.add_arguments` sees it: the options of
    ``DiscretizeConfig.EXCLUSIVE`` go into one mutually exclusive group (argparse refuses
    ``--states 5 --radius 0.1`` as it always did), every other option to the parser."""

    def __init__(self, parser: argparse.ArgumentParser, dests: tuple[str, ...]) -> None:
        self._parser = parser
        self._group = parser.add_mutually_exclusive_group()
        self._dests = dests

    def add_argument(self, *names: str, **kwargs: Any) -> argparse.Action:
        target = self._group if kwargs.get("dest") in self._dests else self._parser
        return target.add_argument(*names, **kwargs)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from discretize.voronoi import DiscretizeConfig

    DiscretizeConfig.add_arguments(_OneOf(parser, DiscretizeConfig.EXCLUSIVE))  # type: ignore[arg-type]


def run(args: argparse.Namespace) -> int:
    from discretize.voronoi import DiscretizeConfig, discretize_command

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
