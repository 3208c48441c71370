"""The real table's signature and what the calibration makes of it, on hand-made tables."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simlab.base.actions import SIMLAB16, parse_action_set
from simlab.calibration.signature import (
    reach_warnings,
    real_signature,
    self_share_warning,
    signature_base,
)
from simlab.calibration.space import ParameterSpace, ParamSpec, default_space
from simlab.physics.motion import PrimitiveParams

FAST8 = parse_action_set(8, "ccw-east", "fast")


def _lattice(spacing: float, n: int = 3) -> np.ndarray:
    g = np.arange(n) * spacing
    return np.array([(x, y) for y in g for x in g])


def test_signature_of_a_hand_made_table() -> None:
    counts = np.zeros((9, 8, 9), dtype=np.int64)
    counts[0, 0, 0] = 3   # 3 stays
    counts[0, 0, 1] = 1   # (0, 0): 3/4 stay, 1/4 move: H = 0.811 bits
    counts[4, 2, 7] = 4   # (4, 2): always to 7: H = 0
    sig = real_signature(counts, _lattice(0.7))
    assert sig.self_share == pytest.approx(3 / 8)
    assert sig.cell_size == pytest.approx(0.7)
    h = -(0.75 * math.log2(0.75) + 0.25 * math.log2(0.25))
    assert sig.mean_entropy == pytest.approx((4 * h + 4 * 0.0) / 8)
    assert (sig.pairs_visited, sig.pairs, sig.states_visited, sig.states) == (2, 72, 2, 9)
    assert sig.transitions == 8


def _table(self_share: float, S: int = 9) -> np.ndarray:
    counts = np.zeros((S, 8, S), dtype=np.int64)
    stay = round(100 * self_share)
    counts[0, 0, 0] = stay
    counts[0, 0, 1] = 100 - stay
    return counts


def test_the_start_drives_until_the_state_changes_on_large_cells_left_on_most_moves() -> None:
    base = PrimitiveParams()  # fixed mode, 0.22 m/s x 0.5 s = 0.11 m moves
    big = real_signature(_table(0.28), _lattice(0.7))
    start = signature_base(base, big, FAST8)
    assert start.mode == "until_state_change"
    # two cells at the robot's one speed
    assert start.max_drive_time == pytest.approx(2 * 0.7 / base.fast_speed)
    # what that mode's space does not search is held, neither left at the fixed-mode
    # record's values nor searched: 6 degrees of heading tolerance, wheel noise 0.03
    assert start.heading_tolerance == pytest.approx(math.radians(6.0))
    assert start.wheel_noise == pytest.approx(0.03)
    assert (base.heading_tolerance, base.wheel_noise) != (start.heading_tolerance,
                                                          start.wheel_noise)
    space = default_space(np.arange(8, 16), "physics", cell_size=0.7,
                          speed_fields=("fast_speed",), mode=start.mode)
    assert not {"heading_tolerance", "wheel_noise"} & set(space.names)
    # cells the fixed moves can leave, or a robot that mostly stays: the thesis primitive
    small = real_signature(_table(0.28), _lattice(0.15))
    assert signature_base(base, small, FAST8) == base
    stays = real_signature(_table(0.8), _lattice(0.7))
    assert signature_base(base, stays, FAST8) == base


def test_a_space_that_cannot_leave_the_cells_is_named_with_its_fix() -> None:
    sig = real_signature(_table(0.28), _lattice(0.7))
    fixed_only = ParameterSpace((ParamSpec("drive_time", 0.2, 1.0),))
    w = reach_warnings(sig, fixed_only, PrimitiveParams(), FAST8)
    assert any("0.22 m against cells of 0.70 m" in x and "[parameters.mode]" in x for x in w)
    full = default_space(FAST8.primitives(), "physics", cell_size=sig.cell_size,
                         speed_fields=("fast_speed",))
    assert not any("[parameters.mode]" in x for x in
                   reach_warnings(sig, full, PrimitiveParams(), FAST8))
    # long enough fixed moves reach the cells: no warning either
    long_moves = ParameterSpace((ParamSpec("drive_time", 0.2, 3.0),))
    assert not any("[parameters.mode]" in x for x in
                   reach_warnings(sig, long_moves, PrimitiveParams(), SIMLAB16))


def test_the_self_share_warning_points_the_right_way() -> None:
    assert self_share_warning(0.28, 0.33) is None
    high = self_share_warning(0.28, 0.78)
    assert high is not None and "78 %" in high and "28 %" in high and "too short" in high
    low = self_share_warning(0.60, 0.20)
    assert low is not None and "too long" in low
