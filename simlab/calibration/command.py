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

import numpy as np

from simlab.base import validation
from simlab.base.actions import SIMLAB16, ActionSet, ActionSetOptions, parse_action_set
from simlab.base.errors import ConfigError
from simlab.base.options import command, option
from simlab.calibration.config import OBJECTIVES, CalibrationConfig, RealTable
from simlab.calibration.report import check_outputs, write_outputs
from simlab.calibration.space import ParameterSpace, load_space
from simlab.calibration.stages import CalibrationResult, calibrate, default_base


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
    from simlab.base.io import read_toml

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


def read_real_table(real: str | os.PathLike[str], n_states: int, aset: ActionSet | None,
                    real_hours: float | None) -> RealTable:
    """The real counts: a count file read in ``aset`` (default simlab's 16), or an
    ``mdp.npz`` of ``simlab estimate --counts``, which records its action set once: a
    different ``aset`` given beside it is refused, naming both."""
    from simlab.data.counts import check_action_width, load_counts

    if Path(real).suffix.lower() == ".npz":
        from simlab.data.mdp import load_mdp

        mdp = load_mdp(real)
        if mdp.counts is None:
            raise ConfigError("this MDP holds no counts to calibrate against", path=real,
                              fix="estimate it with simlab estimate --counts (it keeps them)")
        recorded = mdp.action_set or SIMLAB16
        if aset is not None and aset != recorded:
            raise ConfigError(f"the MDP records {recorded.describe()}, the options say "
                              f"{aset.describe()}", path=real, key="action_set",
                              fix="drop --n-actions/--convention/--speed: the MDP's record "
                              "is used")
        if mdp.n_states != n_states:
            raise ConfigError(f"the MDP has {mdp.n_states} states, the states file "
                              f"{n_states}", path=real, key="states",
                              fix="use the states file the real counts were numbered by")
        return RealTable(counts=np.asarray(mdp.counts, dtype=np.int64), action_set=recorded,
                         hours=real_hours, source=str(real))
    given = aset is not None and aset.n_actions == 16
    aset = SIMLAB16 if aset is None else aset
    table = load_counts(real, n_states=n_states, n_actions=aset.n_actions)
    check_action_width(table, given=given)
    return RealTable(counts=table.counts, action_set=aset, hours=real_hours, source=str(real))


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
        real: real counts (CSV, JSON or ISIR JSON; :func:`simlab.data.counts.load_counts`),
            or an ``mdp.npz`` of ``simlab estimate --counts`` (its recorded action set is
            used; a different ``action_set`` is refused).
        states: states file the real states are numbered by.
        arena: arena name or TOML path.
        out: output directory (see :mod:`simlab.calibration.report`).
        config: search options (:class:`CalibrationConfig`).
        action_set: meaning of the real actions (default simlab's 16, or the MDP's record).
        real_hours: duration of the real data (h); fits the decision latency when given.
        space: searched fields (TOML path or object); default
            :func:`~simlab.calibration.space.default_space` sized from the real table.
        primitives: ``[primitives]`` TOML to start from (default: the record's defaults,
            switched to the mode the real table's signature asks for).
        overwrite: replace outputs of an earlier ``simlab calibrate`` in ``out``.
    """
    from simlab.physics.inputs import load_arena_config, load_discretizer

    config = CalibrationConfig() if config is None else config
    check_outputs(out, overwrite=overwrite)
    disc = load_discretizer(states)
    rt = read_real_table(real, int(disc.n_states), action_set, real_hours)
    base = None if primitives is None else load_base(primitives, config.simulator)
    sp = None
    if space is not None:
        sp = space if isinstance(space, ParameterSpace) else load_space(space)
        try:
            sp.check_fields(base if base is not None else default_base(config.simulator))
        except ConfigError as exc:
            if isinstance(space, ParameterSpace):
                raise
            raise ConfigError(exc.problem, path=space, key=exc.key, fix=exc.fix) from None
    arena_cfg = load_arena_config(arena)
    result = calibrate(rt, arena_cfg, disc, space=sp, base=base, config=config)
    files = write_outputs(result, out, overwrite=overwrite)
    return CalibrateFiles(result=result, files=files)


@dataclass(frozen=True, kw_only=True)
class CalibrateConfig(ActionSetOptions):
    """Options of ``simlab calibrate`` / :func:`calibrate_command`: the files, the real
    table's action set (:class:`~simlab.base.actions.ActionSetOptions`; ``n_actions`` None =
    16) and the search options, which become a :class:`CalibrationConfig` (checked there,
    so their errors name ``calibration.<field>`` as they always did)."""

    COMMAND = "calibrate"
    ARGUMENTS = ("real", "states", "arena", "out")

    real: Any = option(help="real counts: CSV/JSON (s, a, s_next, count) or ISIR model JSON")
    states: Any = option(help="states file (JSON of `simlab discretize`) the real states use")
    arena: Any = option("table", "arena name or TOML")
    out: Path = option(help="output directory: primitives.toml, report.json/.md, figure")
    hours_per_candidate: float | None = option(
        None, "simulated hours of each screening walk (default: --screen-share of the real "
        "transitions)")
    screen_share: float = option(0.25, "screening walk size as a share of the real "
                                 "transitions")
    candidates: int = option(48, "candidates walked at the search's first rung, the "
                             "starting point included")
    confirm_top: int = option(4, "best candidates of the search's last rung re-simulated on "
                              "fresh seeds (the starting point too); the winner is picked "
                              "there, and those within sampling of it form the twin ensemble")
    sampler: str = option("tpe", "Optuna sampler proposing the candidates: TPE, CMA-ES "
                          "(needs the cmaes package), scrambled Sobol or random",
                          choices=("tpe", "cmaes", "qmc", "random"))
    batch: int = option(4, "candidates proposed at a time (the search does not depend on "
                        "--workers: same seed, same twin on any machine)")
    eta: int = option(3, "successive halving: the best 1/ETA of a rung walk ETA times more "
                      "at the next")
    rungs: int = option(2, "rungs of the search before the confirmation (1: no promotion)")
    signature_weight: float = option(
        0.02, "weight of the signature penalty (self-transition share, entropy per action, "
        "outcomes per region, each against its tolerance) in the signature objective")
    confirm_seeds: int = option(1, "fresh seeds of each confirmed candidate")
    confirm_hours: float | None = option(
        None, "simulated hours of each confirming walk (default: sized from the matched "
        "floor, printed in the report)")
    transfer_seeds: int = option(3, "twin seeds of the transfer report (0: none)")
    goal_states: Any | None = option(
        None, "goal states of the transfer report, e.g. 18,34 (default: every state)",
        metavar="LIST")
    start_states: Any | None = option(
        "all", "where the walks start: all (one walk per state, default), a list such as "
        "0,5,12, or none (the arena's start pose)", metavar="all|none|LIST")
    workers: int = option(2, "walks simulated in parallel processes")
    address: str | None = option(None, "Ray cluster address: simulate the walks as Ray "
                                 "tasks there (default: local processes)")
    real_hours: float | None = option(
        None, "duration of the real data in hours; fits the decision latency (default: "
        "unknown, latency kept)")
    space: Any | None = option(
        None, "TOML [parameters.NAME] low/high/scale (or choices) of the searched fields "
        "(default: mode, drive times, detector margin, localization and wheel noise, the "
        "speed of an 8-action robot; ranges sized from the real cells)")
    primitives: Any | None = option(
        None, "[primitives] TOML to start from (default: built-in defaults in the mode the "
        "real table's signature asks for)")
    simulator: str = option("physics", "physics or the physics-free kinematic dry run",
                            choices=("physics", "kinematic"))
    pose_source: str = option("truth", "pose source of the simulated walks")
    n_boot: int = option(200, "bootstrap resamples of the sampling floor")
    unvisited: str = option("max", "real pairs the simulation never tried: a full miss "
                            "(max, default) or left out and reported", choices=("report", "max"))
    objective: str = option(
        "signature", "minimised: the visit-weighted TV distance plus the robot's signature "
        "(self-transition share, entropy per action, outcomes per region), the distance in "
        "excess of its sampling floor plus the signature, that excess alone, the plain "
        "distance, or bits per real transition under the simulated T",
        choices=OBJECTIVES)
    confirm: bool = option(True, "re-simulate the best candidates on fresh seeds and pick "
                           "the winner there (--no-confirm skips it, and the transfer report)")
    reset_states: str = option(
        "auto", "real rows that are an episode reset, not moves: auto (recognised: every "
        "transition of the state jumps several cells), none, or ids such as 18; they leave "
        "the distance and the transfer", metavar="auto|none|LIST")
    policy_data: bool = option(
        False, "collect the policy data the transfer recommends with the calibrated "
        "primitives and score the policy planned on them (adds that walk's time)")
    untried: str = option(
        "stay", "transfer: a twin action the real robot never tried in that state: stay = "
        "it stays put there (never arrives); mask = choose the twin's policy among the tried "
        "ones", choices=("stay", "mask"))
    profile_step: float = option(
        0.0, "after the twins, move each searched field alone by this share of its range "
        "from the winner, a confirming walk each, and say which fields the real table tells "
        "(0: no profile; 0.25 measures it)")
    profile_pairs: bool = option(
        False, "with --profile-step, also move every two told fields together (both "
        "diagonals, up to 2 t (t - 1) more walks for t told fields), so fields that trade off "
        "are not excluded by a move of one alone")
    seed: int = option(0, "seed of walks and search")
    overwrite: bool = option(False, "replace the outputs of an earlier simlab calibrate")
    progress: bool = option(True, "progress bar (--no-progress hides it)")

    def validate(self) -> None:
        from simlab.physics.arena import check_arena_option

        check_arena_option(self.arena)
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
            workers=self.workers, seed=self.seed, sampler=self.sampler, batch=self.batch,
            eta=self.eta, rungs=self.rungs, signature_weight=self.signature_weight, simulator=self.simulator,
            pose_source=self.pose_source, n_boot=self.n_boot, unvisited=self.unvisited,
            objective=self.objective, confirm=self.confirm, progress=self.progress,
            screen_share=self.screen_share, confirm_hours=self.confirm_hours,
            confirm_top=self.confirm_top, confirm_seeds=self.confirm_seeds,
            transfer_seeds=self.transfer_seeds, address=self.address,
            start_states=None if str(self.start_states).strip().lower() == "none"
            else self.start_states,
            goal_states=validation.state_ids(self.goal_states, "goal_states"),
            reset_states=self.reset_states, policy_data=self.policy_data,
            untried=self.untried, profile_step=self.profile_step,
            profile_pairs=self.profile_pairs)

    def real_action_set(self) -> ActionSet | None:
        """What the real table's actions mean; None when no field of the group was given
        (simlab's 16, or the record of an ``mdp.npz``). ``speed`` is kept as given even for
        16 actions, where it changes nothing but the report's record (the command always
        did so; :meth:`make_action_set` would record "slow")."""
        if not self.action_set_given:
            return None
        n = 16 if self.n_actions is None else self.n_actions
        return parse_action_set(n, self.convention or "simlab", self.speed)



@command(CalibrateConfig)
def calibrate_command(cfg: CalibrateConfig) -> CalibrateFiles:
    """``simlab calibrate`` with its options as one :class:`CalibrateConfig` (or its
    fields as arguments): :func:`calibrate_files` with the config's search options and
    action set."""
    return calibrate_files(cfg.real, cfg.states, cfg.arena, cfg.out,
                           config=cfg.search_config(), action_set=cfg.real_action_set(),
                           real_hours=cfg.real_hours, space=cfg.space,
                           primitives=cfg.primitives, overwrite=cfg.overwrite)
