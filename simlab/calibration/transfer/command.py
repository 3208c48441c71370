"""``simlab transfer``: its options, its files and the command."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base import validation
from simlab.base.actions import ActionSetOptions
from simlab.base.errors import ConfigError
from simlab.base.options import command, option
from simlab.calibration.transfer.models import QTableTwin, TransferModel, load_twin
from simlab.calibration.transfer.render import plot_transfer, transfer_markdown
from simlab.calibration.transfer.score import (
    KIND,
    UNTRIED_RULES,
    TransferResult,
    columns_of,
    perfect_twin_line,
    transfer_report,
)

#: Files of ``simlab transfer`` in its ``--out`` directory.
FILES = ("transfer.json", "transfer.md", "transfer.png")


@dataclass(frozen=True, kw_only=True)
class TransferConfig(ActionSetOptions):
    """Options of ``simlab transfer`` / :func:`transfer_command`. The action-set group
    (``--n-actions/--convention/--speed``) describes a real **count file** only; an
    ``mdp.npz`` records its own."""

    COMMAND = "transfer"
    ARGUMENTS = ("real", "sim", "out")

    real: Path = option(help="the real robot's model: mdp.npz of `simlab estimate --counts`, "
                        "or a count file (CSV/JSON/ISIR) with --states and --n-actions")
    sim: tuple[Path, ...] = option(
        help="the twins, one per seed: mdp.npz of `simlab estimate` (its shortest-path "
        "policy is scored) or a `simlab train` directory / q_*.npz file (its greedy policy)",
        metavar="MDP_OR_QTABLES")
    out: Path = option(help="output directory: transfer.json, transfer.md, transfer.png")
    states: Path | None = option(
        None, "states file of the real data (S and centres of a count file; the map figure)")
    occupancy_map: Path | None = option(
        None, "map.yaml drawn under the states (needs --states)", flag="map")
    flip_y: bool = option(False, "flip the --map image vertically (stored bottom row first, "
                          "as some GMapping exports), so that it lies under the states")
    goal_states: Any | None = option(
        None, "one goal made of these state ids, e.g. 18,34 (default: the goals recorded in "
        "the real mdp.npz, else those of the twins' Q-tables)", parse=str)
    start_states: Any | None = option(
        None, "start states, e.g. 0,5,7 (default: every non-goal state the real robot left)",
        parse=str)
    weights: str = option("uniform", "mean over the start states: uniform, or weighted by "
                          "the real visits of each", choices=("uniform", "visits"))
    untried: str = option(
        "stay", "a twin action the real robot never tried in that state: stay = it stays "
        "put there (never arrives); mask = choose the twin's policy among the tried ones",
        choices=tuple(UNTRIED_RULES))
    reset_states: str = option(
        "auto", "real rows that are an episode reset, not moves: auto (recognised from the "
        "states' centres), none, or ids such as 18; they take the twins' own rows",
        metavar="auto|none|LIST")
    n_boot: int = option(200, "resamples of the perfect-twin floor and of the perfect twin "
                         "at each twin's data (0: none; needs the real counts)")
    seed: int = option(0, "seed of those resamples")
    plot: bool = option(True, "the figure transfer.png (--no-plot skips it)")
    overwrite: bool = option(False, "replace the outputs of an earlier `simlab transfer`")

    def validate(self) -> None:
        if not self.sim:
            raise ConfigError("no twin given", key="sim", fix="--sim MDP_OR_QTABLES ...")
        for key in ("goal_states", "start_states"):
            object.__setattr__(self, key, validation.state_ids(getattr(self, key), key))
        if self.occupancy_map is not None and self.states is None:
            raise ConfigError("the map figure needs the states file", key="map",
                              fix="add --states STATES.json")
        if self.flip_y and self.occupancy_map is None:
            raise ConfigError("--flip-y flips the --map image, and no map is given",
                              key="flip_y", fix="add --map MAP.yaml, or drop --flip-y")
        if self.action_set_given and Path(self.real).suffix == ".npz":
            raise ConfigError("--n-actions/--convention/--speed describe a count file; an "
                              "mdp.npz records its own action set", key="n_actions",
                              fix="drop them")
        self.make_action_set(16)
        validation.whole(self.n_boot, "n_boot", minimum=0)
        validation.whole(self.seed, "seed", minimum=0)


@dataclass(frozen=True)
class TransferFiles:
    """Result of :func:`transfer_command`: the report and the files written."""

    result: TransferResult
    files: dict[str, Path]


def _resolve(p: Path) -> Path:
    return p.expanduser().resolve()


def _check_outputs(cfg: TransferConfig) -> dict[str, Path]:
    """Refuse before any work: an output that is an input, an ``--out`` inside a Q-table
    directory, an existing output (without ``--overwrite``, or not one of ours)."""
    import json

    out = Path(cfg.out)
    paths = {name: out / name for name in FILES if cfg.plot or name != "transfer.png"}
    inputs = [Path(cfg.real), *cfg.sim, *(p for p in (cfg.states, cfg.occupancy_map)
                                          if p is not None)]
    ro = _resolve(out)
    for src in inputs:
        rs = _resolve(src)
        if rs.is_dir() and (ro == rs or rs in ro.parents):
            raise ConfigError("the output directory is inside an input directory",
                              path=out, key="out", fix="choose another --out")
        if any(_resolve(p) == rs for p in paths.values()):
            raise ConfigError("an output would replace this input", path=src, key="out",
                              fix="choose another --out")
    from simlab.base.io import ensure_new

    if out.exists() and not out.is_dir():
        raise ConfigError("the output directory is a file", path=out, key="out",
                          fix="choose another --out, or remove the file in the way")
    for p in paths.values():
        if p.is_dir():
            raise ConfigError("transfer output is a directory", path=p,
                              fix="choose another --out")
        ensure_new(p, overwrite=cfg.overwrite, what="transfer output")
    report = paths["transfer.json"]
    if cfg.overwrite and report.is_file():
        try:
            kind = json.loads(report.read_text(encoding="utf-8")).get("kind")
        except (ValueError, UnicodeDecodeError, AttributeError):
            kind = None
        if kind != KIND:
            raise ConfigError("not written by simlab transfer; --overwrite replaces only "
                              "its own outputs", path=report, fix="choose another --out")
    return paths


def _real_model(cfg: TransferConfig, n_states: int, disc: Any) -> TransferModel:
    from simlab.data.counts import check_action_width, load_counts
    from simlab.data.mdp import load_mdp

    real = Path(cfg.real)
    if real.suffix == ".npz":
        model = TransferModel.from_mdp(load_mdp(real), name=str(real))
        if disc is not None and model.n_states != disc.n_states:
            raise ConfigError(f"{model.n_states} states, the states file has "
                              f"{disc.n_states}", path=real, key="states")
        if disc is not None and model.centres is None:
            model = TransferModel(**{**model.__dict__,
                                     "centres": np.asarray(disc.centres, dtype=np.float64)})
        return model
    aset = cfg.make_action_set(16)
    table = load_counts(real, n_states=n_states, n_actions=aset.n_actions)
    check_action_width(table, given=cfg.n_actions is not None)
    centres = None if disc is None else disc.centres
    return TransferModel.from_counts(table.counts, name=str(real), action_set=aset,
                                     centres=centres)


def _goals(cfg: TransferConfig, real: TransferModel,
           twins: Sequence[TransferModel | QTableTwin]) -> dict[str, Any]:
    from simlab.data.goals import state_goal_name

    if cfg.goal_states is not None:
        return {state_goal_name(cfg.goal_states): np.array(cfg.goal_states)}
    if real.goals:
        return dict(real.goals)
    first = twins[0]
    if isinstance(first, QTableTwin):
        return {tab.name: tab.goal for tab in first.tables}
    if first.goals:
        return dict(first.goals)
    raise ConfigError("no goal: neither the real model nor the first twin records one",
                      path=cfg.real, key="goal_states", fix="give --goal-states, e.g. 18,34")


def _without_resets(cfg: TransferConfig, real: TransferModel,
                    twins: Sequence[TransferModel | QTableTwin]
                    ) -> tuple[TransferModel, tuple[int, ...]]:
    """The real model with its reset rows (:mod:`simlab.calibration.resets`) replaced by
    the model twins' own rows (their mean; their counts summed when every one has them),
    warned in one line; unchanged when there is none or no model twin to take rows from."""
    from simlab.base.errors import warn
    from simlab.calibration.resets import reset_warning, resolve_reset_states

    table = real.counts if real.counts is not None else (real.T > 0) * real.allowed[..., None]
    resets = resolve_reset_states(cfg.reset_states, table, real.centres)
    if not resets:
        return real, ()
    models = [t for t in twins if isinstance(t, TransferModel)]
    if not models:
        warn(f"state(s) {list(resets)}: the real rows are an episode reset, but the twins "
             "are Q-tables with no rows to put in their place: kept (give a twin's mdp.npz "
             "too, or --reset-states none to silence this)")
        return real, ()
    idx = list(resets)
    cols = [columns_of(t, real) for t in models]
    T_rows = np.mean([t.T[idx][:, c] for t, c in zip(models, cols, strict=True)], axis=0)
    counted = all(t.counts is not None for t in models)
    count_rows = sum(t.counts[idx][:, c] for t, c in zip(models, cols, strict=True)) \
        if counted else None
    warn(reset_warning(resets, table, real.centres, "the transfer: the twins' own rows "
                       "stand in for them"))
    return real.with_rows(resets, T_rows, count_rows), resets


@command(TransferConfig)
def transfer_command(cfg: TransferConfig) -> TransferFiles:
    """``simlab transfer``: score the twins' policies on the real model; write
    ``transfer.json`` (:meth:`TransferResult.to_json`), ``transfer.md`` and ``transfer.png``
    into ``out`` through one output transaction (nothing is written on any error)."""
    from simlab.base.io import atomic_write_json, atomic_write_text, output_transaction

    paths = _check_outputs(cfg)
    disc = grid = None
    if cfg.states is not None:
        from simlab.physics.inputs import load_discretizer

        disc = load_discretizer(cfg.states)
    if cfg.occupancy_map is not None:
        from discretize.mapio import read_map

        grid = read_map(cfg.occupancy_map, flip_y=cfg.flip_y)
    twins = [load_twin(p) for p in cfg.sim]
    n_states = disc.n_states if disc is not None else twins[0].n_states
    real = _real_model(cfg, n_states, disc)
    goals = _goals(cfg, real, twins)
    real, resets = _without_resets(cfg, real, twins)
    rng = np.random.default_rng(cfg.seed)
    try:
        result = transfer_report(real, twins, goals, cfg.start_states, weights=cfg.weights,
                                 untried=cfg.untried, n_boot=cfg.n_boot, rng=rng)
    except ConfigError as exc:
        if exc.path is not None or exc.key not in ("goal_states", "start_states"):
            raise
        raise ConfigError(exc.problem, path=cfg.real, key=exc.key, fix=exc.fix) from None
    result = dataclasses.replace(result, reset_states=resets, lines=tuple(
        perfect_twin_line(real, result, t.counts.sum(axis=2)[:, columns_of(t, real)],
                          n_boot=cfg.n_boot, rng=rng)
        if cfg.n_boot and real.counts is not None and isinstance(t, TransferModel)
        and t.counts is not None else None for t in twins))
    with output_transaction(cfg.out, paths.values(), overwrite=cfg.overwrite,
                            what="transfer output") as txn:
        atomic_write_json(txn.path(paths["transfer.json"]),
                          {**result.to_json(), "config": cfg.to_dict()})
        atomic_write_text(txn.path(paths["transfer.md"]), transfer_markdown(result, figure=cfg.plot))
        if cfg.plot:
            plot_transfer(result, txn.path(paths["transfer.png"]), grid=grid, disc=disc)
    return TransferFiles(result=result, files=paths)
