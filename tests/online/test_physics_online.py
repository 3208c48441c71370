"""Online learning in physics: the driver's transitions feed both experts; changes apply."""

from __future__ import annotations

import numpy as np
import pytest

from discretize.voronoi import Discretizer
from simlab.base.errors import ConfigError
from simlab.online import meta
from simlab.online.physics import PhysicsChange, run_physics_online
from simlab.physics.world import World


def _lattice() -> Discretizer:
    g = np.linspace(-0.6, 0.6, 5)
    return Discretizer(centres=np.array([(x, y) for y in g[::-1] for x in g]))


def _run(experts, criterion: str, n: int, changes=(), seed: int = 0):
    mf, mb = experts
    ag = meta.make_meta_agent(mf, mb, 25, 16, criterion=criterion)
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(3)]
    with World("table") as world:
        run = run_physics_online(ag, world, _lattice(), goal=(11, 12, 13),
                                 start_states=(6, 7, 8), decisions=n, changes=changes,
                                 env_rng=rngs[0], agent_rng=rngs[1], noise_rng=rngs[2])
        bodies = list(world.static_bodies)
    return ag, run, bodies


def test_transitions_rewards_and_the_passive_observer(experts) -> None:
    changes = (PhysicsChange(12, "goal", goal=(0,)), PhysicsChange(20, "box",
                                                                   box=(0.0, -0.3, 0.4, 0.05)))
    ag, run, bodies = _run(experts, "mb", 30, changes)
    log = run.log
    assert np.all(log.expert == meta.EXPERT_MB)
    assert list(log.phase[[0, 11, 12, 19, 20, 29]]) == [0, 0, 1, 1, 2, 2]
    goal = np.where(log.phase == 0, np.isin(log.s_next, (11, 12, 13)), log.s_next == 0)
    np.testing.assert_array_equal(log.reward > 0, goal)
    cont = np.flatnonzero(log.reward[:-1] == 0)
    np.testing.assert_array_equal(log.s[cont + 1], log.s_next[cont])  # no reward: go on
    assert np.all(np.isin(log.s[np.flatnonzero(log.reward[:-1] > 0) + 1], (6, 7, 8)))
    assert run.boxes and run.boxes[0] in bodies  # the box was added to the world
    assert run.robot_seconds > 0 and np.all(log.backups >= 0)
    # MF learned exactly by Q-learning on the transitions MB decided
    Q = np.full((25, 16), 1.0)
    for s, a, r, s2 in zip(log.s, log.a, log.reward, log.s_next, strict=True):
        Q[s, a] += 0.6 * (r + 0.9 * Q[s2].max() - Q[s, a])
    np.testing.assert_allclose(ag.mf.Q, Q, rtol=0, atol=1e-12)


def test_same_seed_same_run(experts) -> None:
    _, a, _ = _run(experts, "entropy_and_cost", 12, seed=3)
    _, b, _ = _run(experts, "entropy_and_cost", 12, seed=3)
    for col, x in a.log.columns().items():
        if col != "seconds":
            np.testing.assert_array_equal(x, b.log.columns()[col], err_msg=col)
    np.testing.assert_array_equal(a.blocked, b.blocked)


def test_bad_sizes_are_refused(experts) -> None:
    mf, mb = experts
    with World("table") as world:
        with pytest.raises(ConfigError, match="expected \\(25, 16\\)"):
            run_physics_online(meta.make_meta_agent(mf, mb, 10, 16), world, _lattice(),
                               goal=(1,), start_states=(0,), decisions=1,
                               env_rng=np.random.default_rng(0),
                               agent_rng=np.random.default_rng(0),
                               noise_rng=np.random.default_rng(0))
        with pytest.raises(ConfigError, match="goal"):
            run_physics_online(meta.make_meta_agent(mf, mb, 25, 16), world, _lattice(),
                               goal=(30,), start_states=(0,), decisions=1,
                               env_rng=np.random.default_rng(0),
                               agent_rng=np.random.default_rng(0),
                               noise_rng=np.random.default_rng(0))
