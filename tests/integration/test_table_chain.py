"""The physics chain on the table arena at the thesis's scale, checked against its findings.

One module-scoped run (about a minute of CPU): map -> 41 Voronoi states -> a 10-hour
random walk with 2 workers -> the empirical MDP. The tests then check the thesis's
results on it:

* issue 4 / thesis Fig. 4.8: at least 95 % of the (s, a) pairs visited, and the mean
  transition entropy of the fast actions above that of the slow ones;
* issue 5 / thesis Fig. 4.9: value-iteration softmax reaches at least 90 % of the optimal
  expected return within 2,000 episodes, for each of the 9 goals.
"""

from __future__ import annotations

import numpy as np
import pytest

from discretize.command import discretize_command
from simlab.data.collect import collect
from simlab.data.estimate import estimate
from simlab.orchestration.mapping import build_map

#: Every test shares the module's 10-hour physics chain (about a minute of CPU): the slow tier.
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def table_chain(tmp_path_factory):
    root = tmp_path_factory.mktemp("table_chain")
    run = build_map("table", minutes=10, seed=1, out=root / "map", progress=False)
    states = discretize_command(run.yaml_path, root / "states.json", states=41, progress=False)
    data = collect("table", root / "states.json", out=root / "dataset", hours=10.0, seed=1,
                   workers=2, progress=False)
    mdp = estimate(root / "dataset", root / "mdp" / "mdp.npz", plot=False)
    return {"root": root, "states": states.discretizer, "collect": data, "mdp": mdp}


def test_calibration_guard_decision_latency_gives_8448_transitions_in_10_hours(table_chain):
    """Calibration guard of ``PrimitiveParams.decision_latency = 3.02`` s
    (:mod:`simlab.physics.motion`), not a reproduced result.

    The latency was chosen so that a 10-hour walk gives about the thesis's 8,448
    transitions (36,000 s / (3.02 s idle + ~1.24 s mean primitive)); the count follows from
    it by construction. The guard fails when the primitives' durations drift (physics rate,
    speeds, braking, detector), which means the latency must be recalibrated, not that the
    thesis stops being reproduced.
    """
    data = table_chain["collect"]
    assert table_chain["states"].n_states == 41
    assert data.transitions == pytest.approx(8448, rel=0.05)


def test_ten_hour_walk_visits_95_percent_of_state_action_pairs(table_chain):
    coverage = table_chain["mdp"].summary["coverage"]
    assert coverage["fraction_visited"] >= 0.95


def test_fast_actions_have_higher_transition_entropy(table_chain):
    mdp = table_chain["mdp"]
    entropy = np.asarray(mdp.summary["entropy_bits"]["per_action"])
    slow, fast = entropy[:8].mean(), entropy[8:].mean()
    assert fast > slow
    assert mdp.summary["entropy_bits"]["fast_mean"] == pytest.approx(fast)
    # the empirical T is a distribution for every (s, a)
    np.testing.assert_allclose(mdp.mdp.T.sum(axis=2), 1.0)


def test_vi_softmax_reaches_90_percent_of_optimal_on_every_goal(table_chain):
    from simlab.training.train import train

    summary = train(table_chain["mdp"].npz, agent="vi-softmax", goals="all", episodes=2000,
                    runs=3, seed=0, out=None, progress=False)
    assert len(summary.goals) == 9
    for goal in summary.goals:
        assert goal.ratio is not None and goal.ratio >= 0.90, goal
