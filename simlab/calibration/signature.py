"""What a real count table says about the robot before any simulation: its *signature*.

Two numbers decide which primitives can reproduce a real table at all:

* the **self-transition share**, the fraction of real transitions with ``s' = s``. A robot
  that drives until its state changes (the ISIR TurtleBot of Chartouny et al. 2024, sec. 3)
  stays in place only when blocked or when its localization puts it back, about a quarter
  of the time; a robot whose moves are short against its cells stays most of the time;
* the **cell size** against the **move length**: the median distance from each state's
  centre to the nearest other centre, against the distance one primitive covers
  (``speed * drive_time`` in the thesis's fixed-time mode, section 3.2). A move shorter than
  half a cell cannot leave the cell from its centre.

:func:`real_signature` measures them; :func:`signature_base` picks the starting point of a
calibration from them, and :func:`reach_warnings` says, before any simulation, when the
searched space cannot reach the real table, and what to change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from simlab.base.actions import ActionSet
from simlab.calibration.space import HELD_UNTIL_STATE_CHANGE, ParameterSpace


@dataclass(frozen=True)
class Signature:
    """The signature of a real table (module docstring).

    Attributes:
        self_share: share of the real transitions with ``s' = s``.
        cell_size: median distance (m) from a state's centre to its nearest other centre.
        mean_entropy: visit-weighted mean next-state entropy of the visited pairs (bits).
        transitions: real transitions.
        pairs_visited: ``(s, a)`` pairs with at least one transition, of ``pairs``.
        states_visited: states with at least one transition from them, of ``states``.
    """

    self_share: float
    cell_size: float
    mean_entropy: float
    transitions: int
    pairs_visited: int
    pairs: int
    states_visited: int
    states: int

    def to_json(self) -> dict[str, Any]:
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                for k, v in self.__dict__.items()}


def cell_size(centres: ArrayLike) -> float:
    """Median distance (m) from each centre ``(S, 2)`` to its nearest other centre."""
    c = np.asarray(centres, dtype=np.float64)
    if len(c) < 2:
        return float("nan")
    from scipy.spatial import cKDTree

    d, _ = cKDTree(c).query(c, k=2)
    return float(np.median(d[:, 1]))


def real_signature(counts: ArrayLike, centres: ArrayLike) -> Signature:
    """The signature of ``counts`` ``(S, A, S)`` on states with centres ``(S, 2)``."""
    n = np.asarray(counts, dtype=np.int64)
    S, A, _ = n.shape
    total = int(n.sum())
    stay = int(np.einsum("sas->", n))
    n_sa = n.sum(axis=2)
    p = n / np.maximum(n_sa, 1)[:, :, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        h = -np.where(p > 0, p * np.log2(np.where(p > 0, p, 1.0)), 0.0).sum(axis=2)
    return Signature(
        self_share=stay / total if total else float("nan"),
        cell_size=cell_size(centres),
        mean_entropy=float((h * n_sa).sum() / total) if total else float("nan"),
        transitions=total,
        pairs_visited=int((n_sa > 0).sum()),
        pairs=S * A,
        states_visited=int((n_sa.sum(axis=1) > 0).sum()),
        states=S,
    )


def used_speed_field(action_set: ActionSet) -> tuple[str, ...]:
    """The primitive speed fields the real actions use (an 8-action robot has one)."""
    if action_set.n_actions == 8:
        return (f"{action_set.speed}_speed",)
    return ("slow_speed", "fast_speed")


#: A robot that leaves its cell on most moves: the real ISIR robot stays in 28 % of its
#: transitions (Chartouny et al. 2024's lab data); fixed-time moves shorter than half a cell
#: stay far more often.
SELF_SHARE_DRIVES_ON = 0.5


def drives_until_state_change(sig: Signature, params: Any, action_set: ActionSet) -> bool:
    """Whether the signature asks for the drive-until-state-change mode: the real robot
    leaves its cell in most moves while the record's longest fixed move is shorter than
    half a cell (so fixed moves from near a centre would mostly stay)."""
    if not math.isfinite(sig.cell_size) or not math.isfinite(sig.self_share):
        return False
    longest = max(getattr(params, f) for f in used_speed_field(action_set)) * params.drive_time
    return sig.self_share < SELF_SHARE_DRIVES_ON and longest < 0.5 * sig.cell_size


def signature_base(params: Any, sig: Signature, action_set: ActionSet) -> Any:
    """The starting point of a calibration: ``params`` switched to the
    drive-until-state-change mode when :func:`drives_until_state_change`, with a
    ``max_drive_time`` of two cells at the slowest used speed (long enough to leave any
    cell; the state change ends the move first) and the fields that space holds
    (:data:`~simlab.calibration.space.HELD_UNTIL_STATE_CHANGE`)."""
    if getattr(params, "mode", None) is None or not drives_until_state_change(
            sig, params, action_set):
        return params
    v = min(getattr(params, f) for f in used_speed_field(action_set))
    return replace(params, mode="until_state_change",
                   max_drive_time=float(min(max(2.0 * sig.cell_size / v, 1.0), 20.0)),
                   **HELD_UNTIL_STATE_CHANGE)


def _longest_fixed_move(space: ParameterSpace, base: Any, action_set: ActionSet) -> float:
    specs = {p.name: p for p in space.specs}
    speeds = []
    for f in used_speed_field(action_set):
        speeds.append(specs[f].high if f in specs else getattr(base, f))
    t = specs["drive_time"].high if "drive_time" in specs else base.drive_time
    return max(speeds) * t


def reach_warnings(sig: Signature, space: ParameterSpace, base: Any,
                   action_set: ActionSet) -> list[str]:
    """Why the space may not reach the real table, or the real table may not tell much,
    each with what to change (empty when nothing stands out). The mode check applies to
    physics records only (``mode`` is a field)."""
    out = []
    physics = getattr(base, "mode", None) is not None and math.isfinite(sig.cell_size)
    specs = {p.name: p for p in space.specs}
    modes = (specs["mode"].choices if "mode" in specs else (base.mode,)) if physics else ()
    longest = _longest_fixed_move(space, base, action_set) if physics else math.inf
    if (physics and "until_state_change" not in (modes or ())
            and sig.self_share < SELF_SHARE_DRIVES_ON and longest < 0.5 * sig.cell_size):
        out.append(
            f"the real robot leaves its state in {100 * (1 - sig.self_share):.0f} % of its "
            f"moves, but the searched primitives move at most {longest:.2f} m against cells "
            f"of {sig.cell_size:.2f} m and run in {', '.join(modes or ())} mode only: search "
            "the mode too ([parameters.mode] choices = [\"fixed\", \"until_state_change\"]) "
            "or widen drive_time and the speeds")
    if sig.states_visited < 0.5 * sig.states:
        out.append(f"the real data leave only {sig.states_visited} of {sig.states} states "
                   f"({sig.transitions} transitions): the twin is calibrated on a corner of "
                   "the lab; give more of the robot's data")
    if sig.pairs_visited < sig.pairs:
        share = sig.pairs_visited / sig.pairs
        if share < 0.5:
            out.append(f"the real table visits only {sig.pairs_visited} of {sig.pairs} (s, a) "
                       "pairs: the distance rests on few pairs; more real data would help")
    return out


def self_share_warning(real: float, sim: float, tolerance: float = 0.1) -> str | None:
    """A warning when the calibrated twin's self-transition share is off by more than
    ``tolerance`` from the real one, with the likely fix; None when within."""
    if not (math.isfinite(real) and math.isfinite(sim)) or abs(sim - real) <= tolerance:
        return None
    if sim > real:
        fix = ("moves too short or too often blocked: search the mode, widen max_drive_time "
               "or drive_time, lower detector_margin's range")
    else:
        fix = ("moves too long: shorten drive_time/max_drive_time, or add localization "
               "noise (pose_noise_xy)")
    return (f"the calibrated twin stays in its state in {100 * sim:.0f} % of its moves, the "
            f"real robot in {100 * real:.0f} %: {fix}")
