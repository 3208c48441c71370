"""``simlab discretize``: place Voronoi states on a map, save them, draw them.

The discretizer itself (eroded free space, centres, numbering, ``state_of``) is
:mod:`discretize.voronoi`; the figure (thesis Fig. 3.5: map, cells, centres, visits) is
:mod:`discretize.plot`. This module composes them into the command: every input and
every output path is checked (exists?) before any file is written, and the outputs are
written atomically (:mod:`simlab.base.io`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from discretize.gridmap import OccupancyMap
from discretize.mapio import read_map
from discretize.plot import render_states_png, visits_from_dataset
from discretize.voronoi import DEFAULT_ROBOT_RADIUS, Discretizer, load_centres_txt
from simlab.base import validation
from simlab.base.errors import ConfigError
from simlab.base.io import atomic_write, ensure_new
from simlab.base.options import CommandConfig, command, option


@dataclass(frozen=True)
class DiscretizeResult:
    """What :func:`discretize_command` produced: the states, the states file, the figure
    (None: not drawn) and the visits per state that coloured it ((S,) int64, or None)."""

    discretizer: Discretizer
    out: Path
    png: Path | None
    visits: np.ndarray | None


@dataclass(frozen=True, kw_only=True)
class DiscretizeConfig(CommandConfig):
    """Options of ``simlab discretize`` / :func:`discretize_command`.

    ``states``, ``radius`` and ``centres`` are three ways to get the centres: at most one
    is given. ``map``, ``centres``, ``png`` and ``dataset`` keep the spelling they were
    given (the states file records the map's or the centres file's name as given).
    """

    COMMAND = "discretize"
    ARGUMENTS = ("map", "out", "states")

    map: Any = option(help="map_server map.yaml", metavar="YAML")
    out: Path = option(help="states file to write", metavar="JSON")
    states: int | None = option(None, "number of states (default 41)", metavar="N")
    radius: float | None = option(
        None, "cell-radius rule: N = eroded free area / (pi r^2) (thesis r_V = 0.09 m)",
        metavar="M")
    centres: Any | None = option(
        None, "use these centres (text file, one 'x y' or 'id x y theta' line per state, "
        "metres; ids number the states)", metavar="TXT")
    renumber: bool = option(
        False, "renumber --centres row-major from the top-left (default: file order)")
    robot_radius: float = option(
        DEFAULT_ROBOT_RADIUS, "erode free space by this radius in m (TurtleBot3 Burger)",
        metavar="M")
    all_components: bool = option(False, "keep every free region, not only the largest")
    flip_y: bool = option(
        False, "flip the map image vertically (images stored bottom row first; default off)")
    png: Any | None = option(None, "also draw the states figure", metavar="PNG")
    dataset: Any | None = option(
        None, "Parquet dataset (column s) to colour the figure by visits", metavar="DIR")
    overwrite: bool = option(False, "replace existing outputs")
    progress: bool = option(True, "progress bars (--no-progress hides them)")

    EXCLUSIVE = ("states", "radius", "centres")  # the three ways to get the centres

    def validate(self) -> None:
        for key in ("map", "centres", "png", "dataset"):
            validation.spelled_path(getattr(self, key), key)
        if self.centres is not None and (self.states is not None or self.radius is not None):
            raise ConfigError("give --centres or --states/--radius, not both", key="centres")
        if self.states is not None and self.radius is not None:
            raise ConfigError("give either a number of states or a cell radius, not both",
                              key="states")
        if self.states is not None:
            validation.whole(self.states, "states", minimum=1)
        if self.radius is not None:
            validation.positive(self.radius, "radius")
        validation.positive(self.robot_radius, "robot_radius", allow_zero=True)
        if self.dataset is not None and self.png is None:
            raise ConfigError("--dataset colours the figure; give --png too", key="dataset")


@command(DiscretizeConfig)
def discretize_command(cfg: DiscretizeConfig) -> DiscretizeResult:
    """``simlab discretize``: place states on a map and save them (and a figure).

    Takes a :class:`DiscretizeConfig` or its fields as arguments
    (``discretize_command("maps/table/map.yaml", "states/table.json", 41,
    progress=False)``). Writes the states file ``out`` (JSON, :meth:`Discretizer.save`)
    and, with ``png``, the Fig. 3.5-style figure, coloured by the visits per state of
    ``dataset`` when given.
    """
    out, png = _checked_outputs(cfg)
    grid = read_map(cfg.map, flip_y=cfg.flip_y)
    disc = _place_states(cfg, grid)
    visits = None
    figure = None
    if png is not None:
        if cfg.dataset is not None:
            visits = visits_from_dataset(cfg.dataset, disc.n_states)
        figure = render_states_png(grid, disc, visits=visits, robot_radius=cfg.robot_radius)
    disc.save(out, overwrite=cfg.overwrite)
    if png is not None and figure is not None:
        with atomic_write(png, "wb") as fh:
            fh.write(figure)
    return DiscretizeResult(discretizer=disc, out=out, png=png, visits=visits)


def _checked_outputs(cfg: DiscretizeConfig) -> tuple[Path, Path | None]:
    """``(states file, figure or None)``, each refused if it exists (unless
    ``overwrite``) or if the two are one file; checked before any work."""
    out = Path(cfg.out)
    png = None if cfg.png is None else Path(cfg.png)
    ensure_new(out, overwrite=cfg.overwrite, what="states file")
    if png is not None:
        ensure_new(png, overwrite=cfg.overwrite, what="figure")
        if png.resolve() == out.resolve():
            raise ConfigError("the figure and the states file would be the same file", path=out)
    return out, png


def _place_states(cfg: DiscretizeConfig, grid: OccupancyMap) -> Discretizer:
    """The discretizer of ``grid``: the centres file's centres (on the map, renumbered
    if asked), or centres placed on the eroded free space (:meth:`Discretizer.from_map`)."""
    if cfg.centres is not None:
        return Discretizer.from_centres(load_centres_txt(cfg.centres), grid=grid,
                                        renumber=cfg.renumber, source=cfg.centres)
    return Discretizer.from_map(
        grid, cfg.states, radius=cfg.radius, robot_radius=cfg.robot_radius,
        component="all" if cfg.all_components else "largest", progress=cfg.progress,
        source=cfg.map)
