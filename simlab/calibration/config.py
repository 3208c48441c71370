"""What a calibration is given: the real table (:class:`RealTable`) and the options
(:class:`CalibrationConfig`) of :func:`simlab.calibration.stages.calibrate`."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.base import validation
from simlab.base.actions import ActionSet
from simlab.base.errors import ConfigError


@dataclass(frozen=True)
class RealTable:
    """The real robot's counts and what is known about them.

    Attributes:
        counts: ``(S, A, S)`` counts, ``A = action_set.n_actions``.
        action_set: meaning of the real actions.
        hours: duration the counts cover (h), if known (gives transitions per hour).
        blocked: number of blocked transitions, if the data records it.
        source: where the counts came from (for the report).
        reset_states: states whose recorded rows are an episode reset, not moves
            (:mod:`~simlab.calibration.resets`); ``counts`` holds no row for them.
        reset_counts: the transitions of those rows that were left out.
    """

    counts: NDArray[np.int64]
    action_set: ActionSet
    hours: float | None = None
    blocked: int | None = None
    source: str = ""
    reset_states: tuple[int, ...] = ()
    reset_counts: int = 0

    def __post_init__(self) -> None:
        c = np.asarray(self.counts)
        if c.ndim != 3 or c.shape[0] != c.shape[2]:
            raise ConfigError(f"expected (S, A, S) counts, got shape {c.shape}", key="real")
        if c.shape[1] != self.action_set.n_actions:
            raise ConfigError(f"{c.shape[1]} actions in the counts, the action set has "
                              f"{self.action_set.n_actions}", key="real",
                              fix="give --n-actions matching the table")
        if c.sum() <= 0:
            raise ConfigError("the real table has no transition", key="real")
        if self.hours is not None and not (math.isfinite(self.hours) and self.hours > 0):
            raise ConfigError(f"must be > 0, got {self.hours}", key="real.hours")



@dataclass(frozen=True)
class CalibrationConfig:
    """Options of a calibration.

    Attributes:
        hours_per_candidate: simulated hours of each screening walk (> 0); None (default)
            sizes it from the real table: ``screen_share`` of its transitions.
        candidates: candidates walked at rung 0 of the search (>= 2), the starting point
            included. 48 by default: the successive halving promotes a third to rung 1 and
            the best ``confirm_top`` of those to the confirmation
            (:mod:`~simlab.calibration.search`).
        workers: walks simulated at once, one process each (1 = in this process). The
            search does not depend on it (its batches are ``batch`` candidates), so the same
            seed gives the same twin with any number of workers.
        batch: candidates asked of the sampler at a time (>= 1); the sampler learns from a
            batch's scores before the next.
        sampler: Optuna's sampler proposing the candidates: ``"tpe"`` (default), ``"cmaes"``
            (needs the ``cmaes`` package), ``"qmc"`` (scrambled Sobol, no learning) or
            ``"random"``.
        eta: promotion factor of the successive halving (>= 2): a third of a rung's
            candidates walk three times more at the next rung.
        rungs: rungs of the search before the confirmation (>= 1; 1 = no promotion, the
            confirmation takes the best rung-0 candidates).
        signature_weight: weight of the signature penalty of the ``signature`` objective
            (:mod:`~simlab.calibration.objective`; >= 0).
        seed: the search's seed: rung ``k``'s walks use ``seed + k`` (common to every
            candidate of the rung), the confirming walks the seeds after the rungs', the
            twin walks the ones after those.
        simulator: ``"physics"`` or ``"kinematic"`` (physics-free dry runs and tests).
        pose_source: pose source of the walks (``truth``, ``odometry``, ``mcl``); the
            localization error of a real robot's states is searched as ``pose_noise_xy``.
        n_boot: bootstrap resamples of the sampling floor.
        unvisited: real pairs the simulation never tried: ``"max"`` (default: a full miss,
            TV = 1, so covering less never pays) or ``"report"`` (left out of the mean and
            counted in the report).
        objective: what the search minimises: ``"signature"`` (default: the plain TV
            distance plus the penalty of the twin's signature against the robot's, its
            self-transition share, entropy per action and outcomes per region at the robot's
            own visits, :mod:`~simlab.calibration.objective`), ``"signature-excess"`` (the
            same penalty on ``excess``), ``"excess"`` (the visit-weighted TV
            distance minus what sampling alone gives if the candidate were the truth,
            :func:`~simlab.calibration.metrics.excess_distance`; it charges over-dispersed
            twins less), ``"tv"`` (the plain distance; with a few real visits per pair it
            favours too-certain simulators) or ``"loglik"`` (bits per real transition under
            the simulated T, :func:`~simlab.calibration.metrics.cross_entropy`). The report
            always gives the plain TV distance and the signature.
        confirm: re-simulate the best candidates on fresh seeds and pick the winner there.
        progress: tqdm bar over candidates.
        screen_share: screening walk size as a share of the real transitions (> 0; used
            when ``hours_per_candidate`` is None).
        confirm_hours: simulated hours of each confirming walk; None (default) sizes it
            from the matched floor (:func:`~simlab.calibration.budget.size_budgets`).
        confirm_top: candidates of the search's last rung confirmed (>= 1), besides the
            starting point; the confirmed candidates within sampling of the winner form the
            twin ensemble.
        confirm_seeds: fresh seeds each confirmed candidate walks (>= 1).
        transfer_seeds: twin seeds of the transfer report (0 = no transfer report); 3 by
            default: each is read against the perfect twin at its own data, so a few
            suffice, and each more one is another confirming-size walk (a seventh of
            calibrate's time on the ISIR lab).
        start_states: where the walks start: ``"all"`` (default: one walk per state),
            a list of states, or None (the arena's start pose).
        address: Ray cluster address: the walks run as Ray tasks there (default: local
            processes).
        goal_states: goal states of the transfer report (default: every state).
        reset_states: real rows that are an episode reset, not moves
            (:mod:`~simlab.calibration.resets`): ``"auto"`` (default: recognised from
            the state centres), ``"none"``, or state ids; they leave the distance and the
            transfer, with a warning.
        policy_data: after the transfer report, collect the policy data it recommends
            with the calibrated primitives (one walk from every state) and score the
            policy planned on them against the perfect-twin line at that data. It needs
            the transfer report it is sized from (``confirm`` and ``transfer_seeds`` > 0).
        untried: how the transfer scores a twin's action the real robot never tried:
            ``"stay"`` (default: the robot stays put there, as a policy that trusts the twin
            would find) or ``"mask"`` (the twin's policy is chosen among the pairs the real
            robot tried).
        profile_step: after the twins, move each searched field alone by this share of its
            range from the winner and walk the confirming size there, to say field by field
            whether the real table tells it (:mod:`~simlab.calibration.profile`; 0, the
            default, skips it: ``2 d`` more confirming walks for ``d`` fields).
        profile_pairs: with the profile, also move every two told numeric fields together
            (both diagonals, both ways: up to ``2 t (t - 1)`` more confirming walks for
            ``t`` told fields), so that a value one field's move excludes is allowed when a
            second field's move makes up for it (fields that trade off).
    """

    hours_per_candidate: float | None = None
    candidates: int = 48
    workers: int = 2
    batch: int = 4
    sampler: str = "tpe"
    eta: int = 3
    rungs: int = 2
    signature_weight: float = 0.02
    seed: int = 0
    simulator: str = "physics"
    pose_source: str = "truth"
    n_boot: int = 200
    unvisited: str = "max"
    objective: str = "signature"
    confirm: bool = True
    progress: bool = True
    screen_share: float = 0.25
    confirm_hours: float | None = None
    confirm_top: int = 4
    confirm_seeds: int = 1
    transfer_seeds: int = 3
    start_states: Any = "all"
    address: str | None = None
    goal_states: tuple[int, ...] | None = None
    reset_states: Any = "auto"
    policy_data: bool = False
    untried: str = "stay"
    profile_step: float = 0.0
    profile_pairs: bool = False

    def __post_init__(self) -> None:
        k = "calibration."
        for name in ("hours_per_candidate", "confirm_hours"):
            if getattr(self, name) is not None:
                validation.number(getattr(self, name), k + name, low=0.0, low_open=True,
                                  high=MAX_WALK_HOURS, fix="simulated hours of one walk; "
                                  "leave it out to size it from the real data")
        validation.number(self.screen_share, k + "screen_share", low=0.0, low_open=True,
                          high=MAX_SCREEN_SHARE, fix="a share of the real transitions, "
                          "0.25 by default")
        validation.whole(self.candidates, k + "candidates", minimum=2)
        validation.whole(self.workers, k + "workers", minimum=1)
        validation.whole(self.seed, k + "seed", minimum=0)
        validation.choice(self.simulator, ("physics", "kinematic"), k + "simulator")
        validation.whole(self.batch, k + "batch", minimum=1)
        validation.choice(self.sampler, SAMPLERS, k + "sampler")
        validation.whole(self.eta, k + "eta", minimum=2)
        validation.whole(self.rungs, k + "rungs", minimum=1)
        validation.number(self.signature_weight, k + "signature_weight", low=0.0)
        validation.whole(self.n_boot, k + "n_boot", minimum=1)
        validation.choice(self.unvisited, ("report", "max"), k + "unvisited")
        validation.choice(self.objective, OBJECTIVES, k + "objective")
        validation.whole(self.confirm_top, k + "confirm_top", minimum=1)
        validation.whole(self.confirm_seeds, k + "confirm_seeds", minimum=1)
        validation.whole(self.transfer_seeds, k + "transfer_seeds", minimum=0)
        validation.choice(self.untried, ("stay", "mask"), k + "untried")
        if self.policy_data and not (self.confirm and self.transfer_seeds > 0):
            why = "--no-confirm" if not self.confirm else "--transfer-seeds 0"
            raise ConfigError(f"--policy-data is sized from the transfer report, which {why} "
                              "leaves out: nothing would be collected", key=k + "policy_data",
                              fix="drop --policy-data, or keep the confirmation and at least "
                              "one transfer seed")
        validation.number(self.profile_step, k + "profile_step", low=0.0, high=1.0,
                          fix="a share of each field's searched range, e.g. 0.25 (0: no "
                          "profile)")
        if self.profile_step and not self.confirm:
            raise ConfigError("the profile moves each field from the confirmed winner, "
                              "which --no-confirm leaves out", key=k + "profile_step",
                              fix="drop --profile-step, or keep the confirmation")
        if self.profile_pairs and not self.profile_step:
            raise ConfigError("the pairs move the told fields of the profile, which "
                              "--profile-step 0 leaves out", key=k + "profile_pairs",
                              fix="add --profile-step 0.25, or drop --profile-pairs")
        if self.start_states is not None:
            from simlab.data.collect import parse_start_states

            parse_start_states(self.start_states, None)
        if self.goal_states is not None:
            object.__setattr__(self, "goal_states", tuple(
                validation.whole(g, k + "goal_states", minimum=0) for g in self.goal_states))



#: What the search may minimise (:class:`CalibrationConfig.objective`).
OBJECTIVES = ("signature", "signature-excess", "excess", "tv", "loglik")

#: Optuna samplers that may propose the candidates (:class:`CalibrationConfig.sampler`).
SAMPLERS = ("tpe", "cmaes", "qmc", "random")

#: Longest walk a calibration stage may be given (simulated hours): 1,000 h is ~1 million
#: transitions of a real robot's pace, days of wall time; more is a typo, not a budget.
MAX_WALK_HOURS = 1000.0

#: Largest screening walk as a share of the real transitions: the screening is meant to be
#: cheaper than the confirmation (1.5x the real transitions on a real lab's table).
MAX_SCREEN_SHARE = 10.0

