"""The typed summary of a replay (what ``replay.json`` holds).

Callers read attributes (``summary.result.rate_per_hour``,
``summary.comparison.predicted_rate_per_hour``); :meth:`ReplaySummary.to_json` gives the
dict written to ``replay.json``, key for key and in the same order as before the
summary was typed. Nested records that other modules define (the prediction of
:mod:`simlab.replay.prediction`, the error summaries of
:mod:`simlab.localization.tracker`, the primitive parameters) stay plain dicts.
Callers read attributes (``summary.reward_rate_per_hour``, ``summary.result.rewards``);
:meth:`~ReplaySummary.to_json` is the document for files and for code that wants JSON.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.replay.loop import RunOutcome

__all__ = ["BaselineStats", "Comparison", "ReplaySummary", "RunStats", "Schedule",
           "comparison", "localization_summary", "run_stats"]


@dataclass(frozen=True)
class RunStats:
    """The numbers of one run (``result`` / ``random_baseline`` of replay.json).
    Times in robot seconds unless named otherwise; rates per robot hour."""

    transitions: int
    robot_seconds: float
    stepped_seconds: float
    rewards: int
    rate_per_hour: float
    reward_per_transition: float
    goals_reached: dict[str, int]
    rewards_true_state_agrees: int
    seconds_per_transition: float | None
    mean_primitive_seconds: float | None
    transitions_per_goal: float | None
    blocked: int
    blocked_retries: int
    escapes: int
    returns_to_start: int
    state_agrees_with_truth: float | None
    wall_seconds: float
    real_time_factor_robot: float | None
    real_time_factor_stepped: float | None

    def to_json(self) -> dict[str, Any]:
        return {f.name: _plain(getattr(self, f.name)) for f in dataclasses.fields(self)}


@dataclass(frozen=True)
class BaselineStats:
    """The random-policy baseline run: where it comes from, its length (h), its numbers."""

    source: str
    hours: float
    stats: RunStats

    @property
    def rate_per_hour(self) -> float:
        return self.stats.rate_per_hour

    def to_json(self) -> dict[str, Any]:
        return {"source": self.source, "hours": self.hours, **self.stats.to_json()}


@dataclass(frozen=True)
class Schedule:
    """Which parts ran in processes of their own."""

    baseline_process: bool
    mcl_process: bool

    def to_json(self) -> dict[str, Any]:
        return {"baseline_process": self.baseline_process, "mcl_process": self.mcl_process}


@dataclass(frozen=True)
class Comparison:
    """The measured rate against the random baseline and the MDP's prediction.

    The random group (``random_rate_per_hour``, ``ratio_to_random``) exists with a
    baseline run, the predicted group with a prediction for the replayed policy; a ratio
    is None when its denominator is 0. ``rewards_measured_over_expected_over_horizon``
    exists when the prediction has a horizon (``has_horizon``).
    """

    rate_per_hour: float
    random_rate_per_hour: float | None = None
    ratio_to_random: float | None = None
    predicted_rate_per_hour: float | None = None
    measured_over_predicted: float | None = None
    within_25_percent: bool | None = None
    reward_per_transition_measured_over_predicted: float | None = None
    has_horizon: bool = False
    rewards_measured_over_expected_over_horizon: float | None = None
    warning: str | None = None

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"rate_per_hour": self.rate_per_hour}
        if self.random_rate_per_hour is not None:
            out["random_rate_per_hour"] = self.random_rate_per_hour
            out["ratio_to_random"] = self.ratio_to_random
        if self.predicted_rate_per_hour is not None:
            for key in ("predicted_rate_per_hour", "measured_over_predicted",
                        "within_25_percent", "reward_per_transition_measured_over_predicted"):
                out[key] = getattr(self, key)
            if self.has_horizon:
                out["rewards_measured_over_expected_over_horizon"] = (
                    self.rewards_measured_over_expected_over_horizon)
            if self.warning is not None:
                out["warning"] = self.warning
        return out


@dataclass(frozen=True)
class ReplaySummary:
    """Everything ``replay.json`` records (fields in the file's key order).

    Inputs: ``arena`` (name), ``arena_sha256``, ``states`` / ``qtables`` / ``map`` records,
    ``mdp`` and ``dataset`` sources, ``goal_names``, ``goal_states`` (goal -> state ids),
    ``action_set`` (its JSON record), ``masked_pairs``; settings: ``policy`` ...
    ``primitive_params`` with their ``primitive_params_source`` and ``primitives_file`` (the
    ``--primitives`` TOML they were read from, None without one), ``physics`` (the rate
    stepped at, its solver iterations and where the rate came from), ``mcl_params``,
    ``schedule``; results: ``result`` (:class:`RunStats`),
    ``localization`` (error summaries per pose source), ``random_baseline``,
    ``prediction`` (per policy, :mod:`simlab.replay.prediction`), ``comparison``;
    ``files`` written (name -> path).
    """

    arena: str
    arena_sha256: str | None
    states: dict[str, Any]
    qtables: dict[str, Any] | None
    mdp: str | None
    dataset: str | None
    map: dict[str, Any]
    goal_names: tuple[str, ...]
    goal_states: dict[str, list[int]]
    action_set: dict[str, Any]
    masked_pairs: int | None
    policy: str
    pose_source: str
    seed: int
    hours: float
    return_to_start: bool
    retry_blocked: bool
    escape_radius: float
    epsilon: float
    primitive_params: dict[str, Any]
    primitive_params_source: str
    primitives_file: str | None
    physics: dict[str, Any]
    mcl_params: dict[str, Any] | None
    schedule: Schedule
    result: RunStats
    localization: dict[str, Any]
    random_baseline: BaselineStats | None
    prediction: dict[str, Any] | None
    comparison: Comparison
    files: dict[str, str]

    # -- headline numbers (also flat at the top of replay.json) ---------------------------

    @property
    def reward_rate_per_hour(self) -> float:
        return self.result.rate_per_hour

    @property
    def random_rate_per_hour(self) -> float | None:
        return self.comparison.random_rate_per_hour

    @property
    def predicted_rate_per_hour(self) -> float | None:
        return self.comparison.predicted_rate_per_hour

    @property
    def position_error_mean_m(self) -> float | None:
        """Mean position error (m) at decisions of a non-truth pose source (else None)."""
        if self.pose_source == "truth":
            return None
        return self.localization[self.pose_source]["at_decisions"].get("position_mean_m")

    # -- replay.json ------------------------------------------------------------------

    def to_json(self) -> dict[str, Any]:
        """The replay.json dict (same keys, values and order as the untyped summary)."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name in ("random_baseline", "prediction") and value is None:
                continue
            if f.name == "files":
                out.update(self._flat())
            out[f.name] = value.to_json() if hasattr(value, "to_json") else _plain(value)
        return out

    def _flat(self) -> dict[str, Any]:
        """The headline numbers, flat (what reports such as ``simlab pipeline``'s read)."""
        flat: dict[str, Any] = {"reward_rate_per_hour": self.result.rate_per_hour}
        for key in ("random_rate_per_hour", "predicted_rate_per_hour"):
            if getattr(self.comparison, key) is not None:
                flat[key] = getattr(self.comparison, key)
        if self.pose_source != "truth":
            flat["position_error_mean_m"] = self.position_error_mean_m
        return flat


def _plain(value: Any) -> Any:
    if isinstance(value, tuple):
        return list(value)
    return value


# --------------------------------------------------------------------------------------
# Builders
# --------------------------------------------------------------------------------------


def run_stats(run: RunOutcome, goal_names: tuple[str, ...]) -> RunStats:
    """The :class:`RunStats` of one run."""
    log = run.log
    hours = run.robot_seconds / 3600.0
    rewards = int(log.reward.sum())
    wall = run.wall_seconds
    return RunStats(
        transitions=log.n,
        robot_seconds=run.robot_seconds,
        stepped_seconds=run.stepped_seconds,
        rewards=rewards,
        rate_per_hour=rewards / hours if hours > 0 else 0.0,
        reward_per_transition=rewards / log.n if log.n else 0.0,
        goals_reached={g: int(log.reward[log.goal == i].sum())
                       for i, g in enumerate(goal_names)},
        rewards_true_state_agrees=int(((log.reward > 0) & (log.s_true_next == log.s_next)).sum()),
        seconds_per_transition=run.robot_seconds / log.n if log.n else None,
        mean_primitive_seconds=float(log.duration.mean()) if log.n else None,
        transitions_per_goal=log.n / rewards if rewards else None,
        blocked=int(log.blocked.sum()),
        blocked_retries=run.blocked_retries,
        escapes=run.escapes,
        returns_to_start=run.returns_to_start,
        state_agrees_with_truth=float((log.s_true_next == log.s_next).mean())
        if log.n else None,
        wall_seconds=wall,
        real_time_factor_robot=run.robot_seconds / wall if wall > 0 else None,
        real_time_factor_stepped=run.stepped_seconds / wall if wall > 0 else None,
    )


def _pose_errors(est: NDArray[np.float64], truth: NDArray[np.float64]
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    from simlab.localization.motion import wrap

    pos = np.hypot(*(est[:, :2] - truth[:, :2]).T) if len(est) else np.zeros(0)
    head = np.abs(wrap(est[:, 2] - truth[:, 2])) if len(est) else np.zeros(0)
    return pos, head


def localization_summary(run: RunOutcome) -> dict[str, Any]:
    """Pose errors of the odometry (always) and of the ``mcl`` filter (when it ran)."""
    from simlab.localization.tracker import error_summary

    log = run.log
    out: dict[str, Any] = {}
    pe, he = _pose_errors(log.odom_after, log.truth_after)
    out["odometry"] = {"at_decisions": error_summary(pe, he),
                       "final_position_error_m": float(pe[-1]) if pe.size else None}
    if run.mcl_log is not None:
        ml = run.mcl_log
        pe2, he2 = _pose_errors(log.est_after, log.truth_after)
        late = ml.t >= 60.0
        out["mcl"] = {
            "at_decisions": error_summary(pe2, he2),
            "updates": error_summary(ml.position_error, ml.heading_error),
            "updates_after_first_minute": error_summary(ml.position_error[late],
                                                        ml.heading_error[late]),
            "particles_injected": int(ml.injected.sum()),
        }
    return out


def comparison(result: RunStats, baseline: BaselineStats | None,
               pred: dict[str, Any] | None) -> Comparison:
    """The replayed policy's rate against the baseline and its prediction ``pred``."""
    rate = result.rate_per_hour
    kw: dict[str, Any] = {}
    if baseline is not None:
        b = baseline.rate_per_hour
        kw.update(random_rate_per_hour=b, ratio_to_random=rate / b if b else None)
    if pred is not None:
        p = pred["rate_per_hour"]
        q = pred["reward_per_transition"]
        e = pred.get("expected_rewards_over_horizon")
        kw.update(predicted_rate_per_hour=p, measured_over_predicted=rate / p if p else None,
                  within_25_percent=bool(p) and abs(rate / p - 1.0) <= 0.25,
                  reward_per_transition_measured_over_predicted=(
                      result.reward_per_transition / q if q else None),
                  has_horizon=e is not None,
                  rewards_measured_over_expected_over_horizon=(
                      result.rewards / e if e is not None and e > 0 else None))
        if pred["n_closed_classes"] > 1:
            kw["warning"] = (f"the MDP's chain has {pred['n_closed_classes']} closed classes "
                             "reachable from the start: its long-run rate depends on which "
                             "one the robot falls into (often states whose actions the "
                             "dataset never tried); collect more data")
    return Comparison(rate_per_hour=rate, **kw)
