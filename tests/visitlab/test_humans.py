"""Human parameters (SPEC B4): presets and validation."""

from __future__ import annotations

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.visitlab.humans import PRESETS, Human, human

# SPEC B4 table: s_H, F_H, P_H, L_H, O_H, r_H
SPEC_TABLE = {
    "easy": ((1, 0, 0), 0, 0, 0, 0, 0),
    "medium": ((0.5, 0.5, 0), 0.2, 0.5, 0.2, 0.3, 0.3),
    "hard": ((0, 0, 1), 0.5, 0.7, 0.5, 0.5, 0.5),
    "H1": ((1, 0, 0), 0, 0, 0, 0.1, 0.1),
    "H2": ((0, 0.5, 0.5), 0.05, 0, 0.05, 0.15, 0.05),
    "H3": ((0.33, 0.33, 0.34), 0.5, 0.5, 0.1, 0.3, 0.2),
}


@pytest.mark.parametrize("name", list(SPEC_TABLE))
def test_presets_match_the_spec_table(name):
    speeds, f, p, lose, o, r = SPEC_TABLE[name]
    h = PRESETS[name]
    assert h.speed_probs == pytest.approx(speeds)
    assert (h.fail_hello, h.pointing_need, h.lose_attention, h.orientation_change,
            h.random_move) == pytest.approx((f, p, lose, o, r))
    np.testing.assert_allclose(h.to_array(), [*speeds, f, p, lose, o, r])
    assert human(name.lower()) is h and human(name.upper()) is h


@pytest.mark.parametrize(("field", "value"), [
    ("fail_hello", 1.5),
    ("pointing_need", -0.1),
    ("lose_attention", "often"),
    ("orientation_change", 2),
    ("random_move", True),
])
def test_probability_fields_are_validated_by_name(field, value):
    with pytest.raises(ConfigError, match=field):
        Human(**{field: value})


@pytest.mark.parametrize("speeds", [(0.5, 0.4, 0.0), (1.2, -0.2, 0.0), (1.0, 0.0), "fast"])
def test_speed_probabilities_are_validated(speeds):
    with pytest.raises(ConfigError, match="speed_probs"):
        Human(speed_probs=speeds)


def test_human_is_frozen_and_copies_are_validated():
    h = PRESETS["medium"]
    with pytest.raises(AttributeError):
        h.fail_hello = 0.0  # type: ignore[misc]
    slow = h.with_(speed_probs=(1.0, 0.0, 0.0), name="medium-slow")
    assert slow.speed_probs == (1.0, 0.0, 0.0) and h.speed_probs == (0.5, 0.5, 0.0)
    with pytest.raises(ConfigError, match="pointing_need"):
        h.with_(pointing_need=3)
    with pytest.raises(ConfigError, match="human"):
        human("nobody")
