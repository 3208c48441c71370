"""Action sets: conventions, headings, permutations, metadata round trips."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simlab.base.actions import (
    HEADINGS,
    SIMLAB16,
    ActionSet,
    action_set_from_metadata,
    convention_permutation,
    parse_action_set,
)
from simlab.base.directions import Direction
from simlab.base.errors import ConfigError


def test_ccw_east_headings_turn_counter_clockwise_from_east():
    aset = parse_action_set(8, "ccw-east")
    assert aset.convention == "ccw-east"
    np.testing.assert_allclose(np.unwrap(aset.headings()), np.arange(8) * math.pi / 4,
                               atol=1e-12)


def test_simlab16_is_speed_times_eight_plus_direction():
    assert SIMLAB16.primitives().tolist() == list(range(16))
    assert SIMLAB16.direction(9) is Direction.DOWN and SIMLAB16.speed_index(9) == 1
    assert SIMLAB16.heading(0) == pytest.approx(math.pi / 2)
    assert np.array_equal(HEADINGS, [SIMLAB16.heading(d) for d in range(8)])


def test_eight_actions_use_the_named_speed():
    fast = parse_action_set(8, "simlab", speed="fast")
    assert fast.primitives().tolist() == list(range(8, 16))
    assert parse_action_set(8, "simlab").primitives().tolist() == list(range(8))


def test_permutation_moves_a_q_table_between_numberings():
    ccw, ours = parse_action_set(8, "ccw-east"), parse_action_set(8, "simlab")
    perm = ccw.permutation_to(ours)
    rng = np.random.default_rng(0)
    Q = rng.random((5, 8))
    Q_ours = np.empty_like(Q)
    Q_ours[:, perm] = Q
    # The argmax means the same heading in both numberings.
    for s in range(5):
        assert ccw.heading(int(Q[s].argmax())) == ours.heading(int(Q_ours[s].argmax()))
    # ccw-east 0 (East) is simlab RIGHT (3); 2 (North) is UP (0).
    assert perm[0] == Direction.RIGHT and perm[2] == Direction.UP


def test_permutation_between_different_sizes_is_refused():
    with pytest.raises(ConfigError, match="cannot map"):
        parse_action_set(8, "simlab").permutation_to(SIMLAB16)


def test_explicit_permutation_and_bad_specs():
    assert convention_permutation("3,5,0,4,2,6,1,7") == convention_permutation("ccw-east")
    assert parse_action_set(8, "1,0,2,3,4,5,6,7").convention == "custom"
    for bad in ("nosuch", "0,0,1,2,3,4,5,6", "0,1,2"):
        with pytest.raises(ConfigError):
            convention_permutation(bad)
    with pytest.raises(ConfigError, match="n_actions"):
        ActionSet(n_actions=12)
    with pytest.raises(ConfigError, match="speed"):
        ActionSet(n_actions=8, speed="medium")


def test_metadata_round_trip_and_defaults():
    aset = parse_action_set(8, "ccw-east", speed="fast")
    assert ActionSet.from_json(aset.to_json()) == aset
    meta = {"action_set": aset.to_json()}
    assert action_set_from_metadata(meta, 8, where="q.npz") == aset
    assert action_set_from_metadata({}, 16, where="q.npz") == SIMLAB16
    with pytest.raises(ConfigError, match="no action_set"):
        action_set_from_metadata({}, 8, where="q.npz")
    with pytest.raises(ConfigError, match="16"):
        action_set_from_metadata(meta, 16, where="q.npz")
