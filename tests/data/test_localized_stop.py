"""A robot whose states come from a noisy localization drives until its *localized* state
changes (physics walker, drive-until-state-change mode with pose noise)."""

from __future__ import annotations

import itertools

import numpy as np

from simlab.data.walkers import PhysicsWalker
from simlab.physics.inputs import load_arena_config, load_discretizer
from simlab.physics.motion import PrimitiveParams


def test_a_move_ends_when_its_reading_leaves_the_state(table_states_file) -> None:
    disc = load_discretizer(table_states_file)
    params = PrimitiveParams(mode="until_state_change", max_drive_time=3.0,
                             pose_noise_xy=0.05, decision_latency=1.0)
    walker = PhysicsWalker(load_arena_config("table"), params, "truth", {}, disc)
    run = walker.driver._execute
    reasons: list[str] = []

    def spy(*args, **kwargs):  # why each move ended
        res = run(*args, **kwargs)
        reasons.append(res.stop_reason)
        return res

    walker.driver._execute = spy
    rng = np.random.default_rng(4)
    walker.reset(None, np.random.default_rng(5))
    state = disc.state_of
    ends, moved, readings = [], 0, []
    try:
        for a in rng.integers(0, 16, size=60):
            out = walker.step(int(a), rng)
            readings.append((out.pose_before, out.pose_after))
            if reasons[-1] != "state_change":  # blocked, the detector mid-drive, time out
                continue
            moved += 1
            # the error of the end reading, held during the move
            offset = out.pose_after[:2] - out.truth_after[:2]
            start = state((out.truth_before[:2] + offset)[None])[0]
            end = state((out.truth_after[:2] + offset)[None])[0]
            ends.append(start != end)
    finally:
        walker.close()
    assert moved > 30
    # every move that ended on a state change left its *localized* state (with 5 cm of
    # error on ~0.2 m cells the true position often has not left its cell)
    assert all(ends)
    # the recorded end pose is that reading, and the next move starts from it
    for (_, after), (before_next, _) in itertools.pairwise(readings):
        np.testing.assert_array_equal(after, before_next)
    errors = np.array([r[1][:2] for r in readings])
    assert errors.std() > 0  # readings are noisy
