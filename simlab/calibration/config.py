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
        candidates: number of candidates screened (>= 2), the starting point included.
            28 by default: a robot that drives until its state changes searches 11 fields
            (a Sobol design of half the candidates and a refinement of the other half:
            about 1.3 points per field each).
        workers: walks simulated at once, one process each (1 = in this process).
            The refinement rounds have this many candidates, so the search is identical
            for the same (seed, workers), like ``collect``; the initial design is not
            affected.
        seed: the walks' seed (common to all candidates) and the optimiser's seed; the
            confirming and twin walks use ``seed + 1``, ``seed + 2``, ...
        simulator: ``"physics"`` or ``"kinematic"`` (physics-free dry runs and tests).
        pose_source: pose source of the walks (``truth``, ``odometry``, ``mcl``); the
            localization error of a real robot's states is searched as ``pose_noise_xy``.
        shrink: factor of the refinement step per round (0 < shrink <= 1).
        step: initial refinement step, in unit-cube coordinates (> 0).
        n_boot: bootstrap resamples of the sampling floor.
        unvisited: real pairs the simulation never tried: ``"max"`` (default: a full miss,
            TV = 1, so covering less never pays) or ``"report"`` (left out of the mean and
            counted in the report).
        objective: what the search minimises: ``"excess"`` (default: the visit-weighted
            TV distance minus what sampling alone gives if the candidate were the truth,
            :func:`~simlab.calibration.metrics.excess_distance`), ``"tv"`` (the plain
            distance; with a few real visits per pair it favours too-certain simulators:
            on a 36-state kinematic lattice with 365 and 1,167 real transitions, two seeds
            each, hidden drive time 0.8 s was found at 0.45-0.64 s by ``tv`` and at
            0.65-1.17 s by ``excess``: no longer biased low, but as spread) or ``"loglik"``
            (bits per real transition under the simulated T,
            :func:`~simlab.calibration.metrics.cross_entropy`). The report always gives the
            plain TV distance.
        confirm: re-simulate the best candidates on fresh seeds and pick the winner there.
        progress: tqdm bar over candidates.
        screen_share: screening walk size as a share of the real transitions (> 0; used
            when ``hours_per_candidate`` is None).
        confirm_hours: simulated hours of each confirming walk; None (default) sizes it
            from the matched floor (:func:`~simlab.calibration.budget.size_budgets`).
        confirm_top: screened candidates confirmed (>= 1), besides the starting point.
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
            policy planned on them against the perfect-twin line at that data.
    """

    hours_per_candidate: float | None = None
    candidates: int = 28
    workers: int = 2
    seed: int = 0
    simulator: str = "physics"
    pose_source: str = "truth"
    shrink: float = 0.6
    step: float = 0.15
    n_boot: int = 200
    unvisited: str = "max"
    objective: str = "excess"
    confirm: bool = True
    progress: bool = True
    screen_share: float = 0.25
    confirm_hours: float | None = None
    confirm_top: int = 2
    confirm_seeds: int = 1
    transfer_seeds: int = 3
    start_states: Any = "all"
    address: str | None = None
    goal_states: tuple[int, ...] | None = None
    reset_states: Any = "auto"
    policy_data: bool = False

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
        validation.number(self.shrink, k + "shrink", low=0.0, low_open=True, high=1.0)
        validation.positive(self.step, k + "step")
        validation.whole(self.n_boot, k + "n_boot", minimum=1)
        validation.choice(self.unvisited, ("report", "max"), k + "unvisited")
        validation.choice(self.objective, OBJECTIVES, k + "objective")
        validation.whole(self.confirm_top, k + "confirm_top", minimum=1)
        validation.whole(self.confirm_seeds, k + "confirm_seeds", minimum=1)
        validation.whole(self.transfer_seeds, k + "transfer_seeds", minimum=0)
        if self.start_states is not None:
            from simlab.data.collect import parse_start_states

            parse_start_states(self.start_states, None)
        if self.goal_states is not None:
            object.__setattr__(self, "goal_states", tuple(
                validation.whole(g, k + "goal_states", minimum=0) for g in self.goal_states))



#: What the search may minimise (:class:`CalibrationConfig.objective`).
OBJECTIVES = ("tv", "excess", "loglik")

#: Longest walk a calibration stage may be given (simulated hours): 1,000 h is ~1 million
#: transitions of a real robot's pace, days of wall time; more is a typo, not a budget.
MAX_WALK_HOURS = 1000.0

#: Largest screening walk as a share of the real transitions: the screening is meant to be
#: cheaper than the confirmation (1.5x the real transitions on a real lab's table).
MAX_SCREEN_SHARE = 10.0

