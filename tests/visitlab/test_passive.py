"""The passive model-free observer (IMOL poster) and the optimal navigation values."""

from __future__ import annotations

import numpy as np
import pytest

from simlab.agents.kernels import q_learning_update
from simlab.agents.registry import make_agent
from simlab.base.errors import ConfigError
from simlab.visitlab.grid import gridworld
from simlab.visitlab.passive import nav_optimal_q, observer_run
from simlab.visitlab.training import (
    EnvSpec,
    loop_agent_config,
    make_env,
    run_seed,
    seed_generators,
)

NAV = {"start": "random", "goal": "random"}


@pytest.mark.parametrize("actor", ["rmax", "mb-egreedy"])
def test_observer_q_equals_a_q_learner_fed_the_actors_transitions(actor):
    trials = 30
    overrides = {"plan_every": 300}
    # the actor alone, and the same actor watched for the whole run
    cfg = loop_agent_config(actor, "nav", "thesis", overrides)
    alone = run_seed(EnvSpec("nav", kwargs=NAV), cfg, trials, seed_generators(6, 1)[0])
    watched = observer_run("nav", actor, trials, seed_generators(6, 1)[0],
                           takeover_fraction=1.0, actor_overrides=overrides, env_kwargs=NAV)
    np.testing.assert_array_equal(watched.returns, alone.returns)  # watching changes nothing
    np.testing.assert_array_equal(watched.q, alone.q)
    # replay the actor with simlab.agents' class on the Gymnasium env, recording transitions
    env = make_env("nav", **NAV)
    env_rng, agent_rng = seed_generators(6, 1)[0]
    env.np_random = env_rng
    learner = make_agent(actor, env.observation_space.n, env.action_space.n, agent_rng,
                         config=cfg)
    obs_cfg = loop_agent_config("q-learning", "nav", "thesis")
    q_ref = np.full((env.observation_space.n, env.action_space.n), obs_cfg.initial_value)
    returns = np.zeros(trials)
    for k in range(trials):
        s, _ = env.reset()
        truncated = False
        while not truncated:
            a = learner.act(int(s))
            s_next, r, _, truncated, _ = env.step(a)
            learner.update(int(s), a, float(r), int(s_next))
            q_learning_update(q_ref, int(s), a, float(r), int(s_next), obs_cfg.alpha,
                              obs_cfg.gamma)
            returns[k] += r
            s = s_next
    np.testing.assert_array_equal(returns, alone.returns)
    np.testing.assert_array_equal(watched.q_observer, q_ref)
    assert q_ref.any()


def test_observer_takes_over_at_half_of_the_run():
    trials = 40
    overrides = {"plan_every": 300}
    cfg = loop_agent_config("mb-egreedy", "nav", "thesis", overrides)
    half = run_seed(EnvSpec("nav", kwargs=NAV), cfg, trials // 2, seed_generators(2, 1)[0])
    full = run_seed(EnvSpec("nav", kwargs=NAV), cfg, trials, seed_generators(2, 1)[0])
    run = observer_run("nav", "mb-egreedy", trials, seed_generators(2, 1)[0],
                       takeover_fraction=0.5, actor_overrides=overrides, env_kwargs=NAV)
    # the first half is the actor's, the second the observer's
    np.testing.assert_array_equal(run.returns[:trials // 2], half.returns)
    assert not np.array_equal(run.returns, full.returns)
    # from the take-over on the actor no longer learns: its Q is the half-run's
    np.testing.assert_array_equal(run.q, half.q)
    assert not np.array_equal(run.q, full.q)


def test_observer_needs_a_model_based_actor():
    with pytest.raises(ConfigError) as e:
        observer_run("nav", "q-learning", 5, seed_generators(0, 1)[0])
    assert e.value.key == "actor"


def test_optimal_navigation_values_on_a_corridor():
    """2 x 12 open grid, rooms: columns 0-5 (label 0) and 6-11 (label 1); reward 1 per
    step ending in the goal room, gamma 0.9. Moves go up to 3 cells: from columns 3-11
    one move ends in room 1 (or stays in it), V* = 1 / (1 - 0.9) = 10; from columns 0-2
    two moves are needed, V* = 0.9 * 10 = 9."""
    lay = gridworld(2, 12, (1, 2))
    q = nav_optimal_q(lay, gamma=0.9)
    v = q[lay.n_cells:].max(axis=1).reshape(2, 12)  # goal label 1
    expected = np.where(np.arange(12) >= 3, 10.0, 9.0)
    np.testing.assert_allclose(v, np.tile(expected, (2, 1)), atol=1e-8)
    # STAY in the goal room is optimal there: 1 + 0.9 * 10
    assert q[lay.n_cells + lay.cell(0, 8), 24] == pytest.approx(10.0)
    # STAY outside earns nothing now: 0.9 * V*(same cell)
    assert q[lay.n_cells + lay.cell(0, 0), 24] == pytest.approx(0.9 * 9.0)
    with pytest.raises(ConfigError):
        nav_optimal_q(lay, gamma=1.0)
