"""Simulated humans (thesis 2.1.2 and Table 4.1; Chartouny et al.
2024, humans H1-H3).

A :class:`Human` is a frozen, validated set of behaviour probabilities; the
kernels read it as a float64 array (:meth:`Human.to_array`). What each parameter
does is specified in :mod:`simlab.visitlab.dynamics`.

=============  ===============  =====  =====  =====  =====  =====
preset         speed_probs      F_H    P_H    L_H    O_H    r_H
=============  ===============  =====  =====  =====  =====  =====
easy (thesis)  (1, 0, 0)        0      0      0      0      0
medium         (.5, .5, 0)      .2     .5     .2     .3     .3
hard           (0, 0, 1)        .5     .7     .5     .5     .5
H1 (paper)     (1, 0, 0)        0      0      0      .1     .1
H2             (0, .5, .5)      .05    0      .05    .15    .05
H3             (.33, .33, .34)  .5     .5     .1     .3     .2
=============  ===============  =====  =====  =====  =====  =====
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from simlab.base.errors import ConfigError

# Indices into the human parameter array.
H_S1, H_S2, H_S3, H_FAIL, H_POINT, H_LOSE, H_TURN, H_MOVE = range(8)

_PROB_FIELDS = ("fail_hello", "pointing_need", "lose_attention", "orientation_change",
                "random_move")


@dataclass(frozen=True)
class Human:
    """Behaviour parameters of a simulated human.

    Attributes:
        speed_probs: probabilities of moving 1, 2 or 3 cells per step (s_H); sum to 1.
        fail_hello: F_H, probability that HELLO fails when the human sees the robot
            but does not look at it (percept level 3).
        pointing_need: P_H, probability that COME leaves the human waiting for
            POINTING (level 6) instead of following at once (level 7).
        lose_attention: L_H, per-step probability that an engaged human (level >= 5)
            loses attention.
        orientation_change: O_H, per-step probability that a human who is not engaged
            turns to a new random orientation.
        random_move: r_H, per-step probability that a human who is not engaged walks
            in a random direction.
        name: a label for plots and summaries.
    """

    speed_probs: tuple[float, float, float] = (1.0, 0.0, 0.0)
    fail_hello: float = 0.0
    pointing_need: float = 0.0
    lose_attention: float = 0.0
    orientation_change: float = 0.0
    random_move: float = 0.0
    name: str = "custom"

    def __post_init__(self) -> None:
        try:
            speeds = tuple(float(p) for p in self.speed_probs)
        except (TypeError, ValueError):
            raise ConfigError(f"expected three probabilities, got {self.speed_probs!r}",
                              key="speed_probs") from None
        if len(speeds) != 3 or any(not (0.0 <= p <= 1.0) for p in speeds):
            raise ConfigError(f"expected three probabilities in [0, 1], got {self.speed_probs!r}",
                              key="speed_probs")
        if not math.isclose(sum(speeds), 1.0, abs_tol=1e-9):
            raise ConfigError(f"must sum to 1, got {sum(speeds):g}", key="speed_probs")
        object.__setattr__(self, "speed_probs", speeds)
        for key in _PROB_FIELDS:
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int | float | np.floating):
                raise ConfigError(f"expected a probability, got {value!r}", key=key)
            if not 0.0 <= float(value) <= 1.0:
                raise ConfigError(f"expected a probability in [0, 1], got {value}", key=key)
            object.__setattr__(self, key, float(value))

    def to_array(self) -> np.ndarray:
        """float64 shape (8,): s1, s2, s3, F_H, P_H, L_H, O_H, r_H (kernel order)."""
        return np.array([*self.speed_probs, self.fail_hello, self.pointing_need,
                         self.lose_attention, self.orientation_change, self.random_move],
                        dtype=np.float64)

    def with_(self, **changes: object) -> Human:
        """A copy with some fields changed (validated again)."""
        return replace(self, **changes)


PRESETS: dict[str, Human] = {
    "easy": Human((1.0, 0.0, 0.0), 0.0, 0.0, 0.0, 0.0, 0.0, name="easy"),
    "medium": Human((0.5, 0.5, 0.0), 0.2, 0.5, 0.2, 0.3, 0.3, name="medium"),
    "hard": Human((0.0, 0.0, 1.0), 0.5, 0.7, 0.5, 0.5, 0.5, name="hard"),
    "H1": Human((1.0, 0.0, 0.0), 0.0, 0.0, 0.0, 0.1, 0.1, name="H1"),
    "H2": Human((0.0, 0.5, 0.5), 0.05, 0.0, 0.05, 0.15, 0.05, name="H2"),
    "H3": Human((0.33, 0.33, 0.34), 0.5, 0.5, 0.1, 0.3, 0.2, name="H3"),
}


def human(name: str | Human) -> Human:
    """A preset by name (``easy``, ``medium``, ``hard``, ``H1``, ``H2``, ``H3``;
    case-insensitive), or a :class:`Human` unchanged."""
    if isinstance(name, Human):
        return name
    for key, preset in PRESETS.items():
        if isinstance(name, str) and key.lower() == name.strip().lower():
            return preset
    raise ConfigError(f"unknown human {name!r}", key="human",
                      fix=f"use one of {', '.join(PRESETS)}")
