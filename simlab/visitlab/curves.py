"""Learning curves of Visit-the-lab training: the record of one agent's runs and the
numbers and smoothing every report and figure reads from it.

:class:`TrainResult` is what :func:`simlab.visitlab.training.train` returns and
:mod:`simlab.visitlab.results` saves; :func:`smooth_curve` is thesis Fig. 4.1's
smoothing (windows of ``n_trials / 100`` trials, mean and within-window std over all
seeds); :func:`summarize_curve` the plateau and the trials to reach 90 % of it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["TrainResult", "smooth_curve", "summarize_curve"]


@dataclass
class TrainResult:
    """Learning curves of one agent on one task configuration, over several seeds.

    Attributes:
        label: short name for legends (agent, and human for the social task).
        returns: reward per trial, float64 ``(n_seeds, n_trials)``.
        q: final Q table of each seed, float64 ``(n_seeds, n_states, n_actions)``.
        config: task, agent, env and seed settings (JSON-serialisable).
        wall_time_s: wall-clock seconds of training (all seeds), in seconds.
    """

    label: str
    returns: np.ndarray
    q: np.ndarray
    config: dict[str, Any] = field(default_factory=dict)
    wall_time_s: float = 0.0

    @property
    def n_trials(self) -> int:
        return int(self.returns.shape[1])

    def summary(self) -> dict[str, Any]:
        """Plateau (mean of the last 10 % of trials) and when the curve gets there."""
        return summarize_curve(self.returns) | {"label": self.label,
                                                "wall_time_s": round(self.wall_time_s, 2)}


def summarize_curve(returns: np.ndarray) -> dict[str, Any]:
    """Numbers for a report from ``returns`` ``(n_seeds, n_trials)``.

    ``plateau``: mean reward per trial over the last 10 % of trials (mean over seeds;
    ``plateau_std``: std across seeds). ``trials_to_90pct``: first trial at which the
    seed-averaged curve, smoothed over ``n_trials / 100`` trials, reaches 90 % of the
    plateau (None if it never does or the plateau is 0). ``first_bins``: smoothed
    values of the first 10 bins.
    """
    returns = np.asarray(returns, dtype=np.float64)
    n_seeds, n_trials = returns.shape
    tail = max(1, n_trials // 10)
    per_seed = returns[:, -tail:].mean(axis=1)
    plateau = float(per_seed.mean())
    x, mean, _ = smooth_curve(returns)
    reach = None
    if plateau > 0:
        hits = np.flatnonzero(mean >= 0.9 * plateau)
        reach = int(x[hits[0]]) if hits.size else None
    return {
        "n_seeds": int(n_seeds),
        "n_trials": int(n_trials),
        "plateau": round(plateau, 3),
        "plateau_std": round(float(per_seed.std()), 3),
        "trials_to_90pct": reach,
        "first_bins": [round(float(v), 2) for v in mean[:10]],
    }


def smooth_curve(returns: np.ndarray, n_points: int = 100) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Thesis Fig. 4.1 smoothing: ``n_points`` bins of ``n_trials / n_points`` trials.

    Returns ``(x, mean, std)``: x = last trial index (1-based) of each bin; mean and
    std over all seeds and all trials of the bin (std shows the within-window
    variability, as in the thesis).
    """
    returns = np.asarray(returns, dtype=np.float64)
    n_seeds, n_trials = returns.shape
    n_points = max(1, min(n_points, n_trials))
    window = n_trials // n_points
    used = window * n_points
    binned = returns[:, :used].reshape(n_seeds, n_points, window)
    mean = binned.mean(axis=(0, 2))
    std = binned.std(axis=(0, 2))
    x = (np.arange(n_points) + 1) * window
    return x, mean, std
