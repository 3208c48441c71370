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

from simlab.actions import SIMLAB16, ActionSet
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
