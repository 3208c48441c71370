"""``simlab calibrate`` as a Python function: files in, calibrated TOML and reports out.

Every input is read and checked (outputs absent unless ``overwrite``, states, real counts
against the states and the action set, parameter space against the parameter record, the
arena, the options) **before** any simulation, so bad input costs nothing and writes nothing.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from simlab.actions import SIMLAB16, ActionSet, ActionSetOptions, parse_action_set
from simlab.calibration.report import check_outputs, write_outputs
from simlab.calibration.search import (
    CalibrationConfig,
    CalibrationResult,
    RealTable,
    calibrate,
    default_base,
)
from simlab.calibration.space import ParameterSpace, default_space, load_space
from simlab.errors import ConfigError
from simlab.options import command, option


def load_base(path: str | os.PathLike[str] | None, simulator: str) -> Any:
    """Parameter record to start from: defaults, or the ``[primitives]`` table of a TOML file.

    Unknown fields are refused naming the file and the field; other tables are ignored
    (the format of ``collect --primitives``).
    """
    base = default_base(simulator)
    if path is None:
        return base
    if simulator == "physics":
        from simlab.physics.motion import PrimitiveParams

        return PrimitiveParams.from_toml(path)  # the format of collect --primitives
    from simlab.io import read_toml

    path = Path(path)
    table = read_toml(path, what="primitives file").get("primitives")
    if not isinstance(table, dict):
        raise ConfigError("no [primitives] table", path=path)
    names = {f.name for f in dataclasses.fields(base)}
    unknown = sorted(set(table) - names)
    if unknown:
        raise ConfigError(f"unknown field {unknown[0]!r}", path=path, key="primitives",
                          fix="fields: " + ", ".join(sorted(names)))
    try:
        return dataclasses.replace(base, **table)
    except (ConfigError, ValueError, TypeError) as exc:
        raise ConfigError(str(exc), path=path, key="primitives") from None


@dataclass(frozen=True)
class CalibrateFiles:
    """Result of :func:`calibrate_files`: the calibration and the files written."""

    result: CalibrationResult
    files: dict[str, Path]


def calibrate_files(
    real: str | os.PathLike[str],
    states: str | os.PathLike[str],
    arena: Any,
    out: str | os.PathLike[str],
    *,
    config: CalibrationConfig | None = None,
    action_set: ActionSet | None = None,
    real_hours: float | None = None,
    space: str | os.PathLike[str] | ParameterSpace | None = None,
    primitives: str | os.PathLike[str] | None = None,
    overwrite: bool = False,
) -> CalibrateFiles:
    """Calibrate against the count table ``real`` and write the outputs into ``out``.

    Args:
        real: real counts (CSV, JSON or ISIR JSON; :func:`simlab.data.counts.load_counts`).
        states: states file the real states are numbered by.
        arena: arena name or TOML path.
        out: output directory (see :mod:`simlab.calibration.report`).
        config: search options (:class:`CalibrationConfig`).
        action_set: meaning of the real actions (default simlab's 16).
        real_hours: duration of the real data (h); fits the decision latency when given.
        space: searched fields (TOML path or object); default
            :func:`~simlab.calibration.space.default_space`.
        primitives: ``[primitives]`` TOML to start from (default: the record's defaults).
        overwrite: replace existing outputs.
    """
    from simlab.data.counts import load_counts
    from simlab.physics.inputs import load_arena_config, load_discretizer

    config = CalibrationConfig() if config is None else config
    aset = SIMLAB16 if action_set is None else action_set
    check_outputs(out, overwrite=overwrite)
    disc = load_discretizer(states)
    table = load_counts(real, n_states=int(disc.n_states), n_actions=aset.n_actions)
    rt = RealTable(counts=table.counts, action_set=aset, hours=real_hours,
                   source=str(real))
    base = load_base(primitives, config.simulator)
    if space is None:
        sp = default_space(aset.primitives(), config.simulator)
    else:
        sp = space if isinstance(space, ParameterSpace) else load_space(space)
    sp.check_fields(base)
    arena_cfg = load_arena_config(arena)
    result = calibrate(rt, arena_cfg, disc, space=sp, base=base, config=config)
    return CalibrateFiles(result=result, files=write_outputs(result, out, overwrite=overwrite))


@dataclass(frozen=True, kw_only=True)
class CalibrateConfig(ActionSetOptions):
    """Options of ``simlab calibrate`` / :func:`calibrate_command`: the files, the real
    table's action set (:class:`~simlab.actions.ActionSetOptions`; ``n_actions`` None =
    16) and the search options, which become a :class:`CalibrationConfig` (checked there,
    so their errors name ``calibration.<field>`` as they always did)."""

    COMMAND = "calibrate"
    ARGUMENTS = ("real", "states", "arena", "out")

    real: Any = option(help="real counts: CSV/JSON (s, a, s_next, count) or ISIR model JSON")
    states: Any = option(help="states file (JSON of `simlab discretize`) the real states use")
    arena: Any = option("table", "arena name or TOML")
    out: Path = option(help="output directory: primitives.toml, report.json/.md, figure")
    hours_per_candidate: float = option(2.0, "simulated hours of each candidate's walk")
    candidates: int = option(16, "candidates evaluated, the starting point included")
    workers: int = option(2, "candidates simulated in parallel processes")
    real_hours: float | None = option(
        None, "duration of the real data in hours; fits the decision latency (default: "
        "unknown, latency kept)")
    space: Any | None = option(
        None, "TOML [parameters.NAME] low/high/scale of the searched fields (default: drive "
        "time, used speeds, detector margin)")
    primitives: Any | None = option(
        None, "[primitives] TOML to start from (default: built-in defaults)")
    simulator: str = option("physics", "physics or the physics-free kinematic dry run",
                            choices=("physics", "kinematic"))
    pose_source: str = option("truth", "pose source of the simulated walks")
    n_boot: int = option(200, "bootstrap resamples of the sampling floor")
    unvisited: str = option("report", "real pairs never simulated: report them or count "
                            "them as distance 1 (max)", choices=("report", "max"))
    objective: str = option(
        "excess", "minimised: the TV distance in excess of its sampling floor (unbiased with "
        "few real visits per pair), the plain visit-weighted TV distance, or bits per real "
        "transition under the simulated T", choices=("excess", "tv", "loglik"))
    confirm: bool = option(True, "re-simulate the winner on a fresh seed (--no-confirm "
                           "skips it)")
    seed: int = option(0, "seed of walks and search")
    overwrite: bool = option(False, "replace existing outputs")
    progress: bool = option(True, "progress bar (--no-progress hides it)")

    def validate(self) -> None:
        for key, kinds in (("real", str | os.PathLike), ("primitives", str | os.PathLike),
                           ("space", str | os.PathLike | ParameterSpace)):
            value = getattr(self, key)
            if value is not None and not isinstance(value, kinds):
                raise ConfigError(f"expected a path, got {value!r}", key=key)
        self.search_config()
        self.real_action_set()

    def search_config(self) -> CalibrationConfig:
        """The search options as the :class:`CalibrationConfig` Python callers use."""
        return CalibrationConfig(
            hours_per_candidate=self.hours_per_candidate, candidates=self.candidates,
            workers=self.workers, seed=self.seed, simulator=self.simulator,
            pose_source=self.pose_source, n_boot=self.n_boot, unvisited=self.unvisited,
            objective=self.objective, confirm=self.confirm, progress=self.progress)

    def real_action_set(self) -> ActionSet:
        """What the real table's actions mean. ``speed`` is kept as given even for 16
        actions, where it changes nothing but the report's record (the command always
        did so; :meth:`make_action_set` would record "slow")."""
        n = 16 if self.n_actions is None else self.n_actions
        return parse_action_set(n, self.convention, self.speed)


@command(CalibrateConfig)
def calibrate_command(cfg: CalibrateConfig) -> CalibrateFiles:
    """``simlab calibrate`` with its options as one :class:`CalibrateConfig` (or its
    fields as arguments): :func:`calibrate_files` with the config's search options and
    action set."""
    return calibrate_files(cfg.real, cfg.states, cfg.arena, cfg.out,
                           config=cfg.search_config(), action_set=cfg.real_action_set(),
                           real_hours=cfg.real_hours, space=cfg.space,
                           primitives=cfg.primitives, overwrite=cfg.overwrite)
