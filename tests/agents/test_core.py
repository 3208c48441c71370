"""The agent core: paper planning rules 1, 2, 7, valid-action masks and terminal states."""

from __future__ import annotations

import numpy as np
import pytest

from simlab.agents import core
from simlab.agents.agents import ModelBasedAgent, QLearningAgent, RMaxAgent
from simlab.agents.config import ModelBasedConfig, QLearningConfig, RMaxConfig
from simlab.agents.kernels import count_model_observe
from simlab.agents.registry import AGENTS, make_agent
from simlab.agents.sparse_model import CountModel
from simlab.base.errors import ConfigError
from simlab.training.harness import EpisodeTask, evaluate_q, run_episodes


def _params(**kw):
    return core.agent_params(ModelBasedConfig(**kw))


def test_untried_pairs_after_one_sweep_equal_gamma_mean_v():
    S, A, gamma = 4, 2, 0.9
    model = CountModel(S, A, 16)
    count_model_observe(model, 0, 0, 1.0, 1)  # the only tried pair
    Q = np.array([[0.0, 0.0], [2.0, 1.0], [0.5, 3.0], [1.0, 1.0]])
    V = Q.max(axis=1)  # 0, 2, 3, 1 -> mean 1.5
    p = _params(gamma=gamma, synchronous=True, untried_uniform=True, max_sweeps=1)
    core.plan(model, Q, p, core.NO_MASK, core.NO_TERMINAL)
    assert Q[0, 0] == pytest.approx(1.0 + gamma * V[1])
    untried = [(s, a) for s in range(S) for a in range(A) if (s, a) != (0, 0)]
    for s, a in untried:
        assert Q[s, a] == pytest.approx(gamma * V.mean())


def test_synchronous_vs_in_place_on_three_state_chain():
    # 2 -> 1 (r 0), 1 -> 0 (r 0), 0 -> 0 (r 1); one action, Q starts at 0, gamma 0.5.
    # The in-place sweep visits pairs by index: 0, 1, 2.
    gamma = 0.5
    qs = {}
    for sync in (True, False):
        m = CountModel(3, 1, 8)
        count_model_observe(m, 2, 0, 0.0, 1)
        count_model_observe(m, 1, 0, 0.0, 0)
        count_model_observe(m, 0, 0, 1.0, 0)
        Q = np.zeros((3, 1))
        core.plan(m, Q, _params(gamma=gamma, synchronous=sync, max_sweeps=1), core.NO_MASK,
                  core.NO_TERMINAL)
        qs[sync] = Q[:, 0]
    # Jacobi: each backup reads the previous sweep's zeros -> only the rewarded pair moves
    np.testing.assert_allclose(qs[True], [1.0, 0.0, 0.0])
    # Gauss-Seidel: Q0 = 1, then Q1 = 0.5 * 1, then Q2 = 0.5 * 0.5 within the same sweep
    np.testing.assert_allclose(qs[False], [1.0, 0.5, 0.25])


def test_untried_uniform_needs_synchronous():
    with pytest.raises(ConfigError, match="synchronous"):
        ModelBasedConfig(untried_uniform=True)


def test_rmax_freeze_stops_counting_at_m():
    for freeze, expected in ((True, 2), (False, 4)):
        agent = RMaxAgent(3, 2, RMaxConfig(m=2, freeze=freeze, plan_every=0),
                         np.random.default_rng(0))
        for s_next in (1, 1, 2, 2):
            agent.update(0, 0, 0.0, s_next)
        assert agent.model.n_sa[0, 0] == expected
        T, _ = agent.transition_matrix()
        assert T[0, 0, 1] == pytest.approx(1.0 if freeze else 0.5)


# --------------------------------------------------------------------------- masks
@pytest.mark.parametrize("method,eps", [(0, 0.0), (1, 0.5), (1, 1.0), (2, 0.0)])
def test_masked_selection_never_picks_an_invalid_action(method, eps):
    rng = np.random.default_rng(3)
    q = rng.normal(size=6)
    vrow = np.array([False, True, False, True, True, False])
    q[0] = 100.0  # the best action is invalid
    picks = {int(core.masked_select(q, vrow, method, eps, 0.5, rng)) for _ in range(500)}
    assert picks <= {1, 3, 4}
    if method == 1 and eps == 1.0:
        assert picks == {1, 3, 4}


@pytest.mark.parametrize("method", [0, 1, 2])
def test_all_true_mask_draws_like_no_mask(method):
    q = np.array([0.3, 0.3, 0.1, 0.3])
    r1, r2 = np.random.default_rng(7), np.random.default_rng(7)
    from simlab.agents.kernels import select_action

    a1 = [select_action(q, method, 0.3, 0.2, r1) for _ in range(300)]
    a2 = [core.masked_select(q, np.ones(4, bool), method, 0.3, 0.2, r2) for _ in range(300)]
    assert a1 == a2
    assert r1.random() == r2.random()


def test_state_without_valid_action_falls_back_to_all():
    rng = np.random.default_rng(0)
    picks = {int(core.masked_select(np.zeros(3), np.zeros(3, bool), 1, 1.0, 0.1, rng))
             for _ in range(200)}
    assert picks == {0, 1, 2}


def _chain(S=5):
    """Action 1 moves right, action 0 stays; reward on arriving in the last state."""
    T = np.zeros((S, 2, S))
    for s in range(S):
        T[s, 0, s] = 1.0
        T[s, 1, min(s + 1, S - 1)] = 1.0
    r = np.zeros(S)
    r[-1] = 1.0
    return T, r


@pytest.mark.parametrize("name", sorted(set(AGENTS) - {"sliding-window"}))
def test_no_agent_picks_an_invalid_action(name):
    T, r = _chain()
    valid = np.ones((5, 2), bool)
    valid[:, 0] = False  # "stay" forbidden everywhere
    agent = make_agent(name, 5, 2, np.random.default_rng(1))
    seen = []
    orig = agent.act
    agent.act = lambda s: seen.append(orig(s)) or seen[-1]
    run_episodes(agent, EpisodeTask(T, r, horizon=10, start=0, valid=valid), 20,
                 np.random.default_rng(2), fused_loop=False)
    assert seen and set(seen) == {1}


@pytest.mark.parametrize("name", sorted(AGENTS))
def test_fused_and_python_agree_with_mask_and_terminal(name):
    T, r = _chain()
    valid = np.ones((5, 2), bool)
    valid[2, 0] = False
    terminal = np.zeros(5, bool)
    terminal[-1] = True
    out = []
    for fused_loop in (True, False):
        agent = make_agent(name, 5, 2, np.random.default_rng(4))
        rewards = run_episodes(agent, EpisodeTask(T, r, horizon=12, valid=valid,
                                                  terminal=terminal),
                               30, np.random.default_rng(5), fused_loop=fused_loop)
        out.append((rewards, agent.Q.copy()))
    np.testing.assert_array_equal(out[0][0], out[1][0])
    np.testing.assert_array_equal(out[0][1], out[1][1])


def test_terminal_ends_the_episode_and_counts_its_reward():
    T, r = _chain()
    terminal = np.zeros(5, bool)
    terminal[-1] = True
    for cfg in (QLearningConfig(epsilon=0.1), ModelBasedConfig(plan_every=5)):
        cls = QLearningAgent if isinstance(cfg, QLearningConfig) else ModelBasedAgent
        agent = cls(5, 2, cfg, np.random.default_rng(0))
        rewards = run_episodes(agent, EpisodeTask(T, r, horizon=30, start=0, terminal=terminal),
                               200, np.random.default_rng(1))
        # without termination a greedy agent would collect up to 27 per episode
        assert rewards.max() == 1.0
        assert rewards[-50:].mean() > 0.9
        assert np.all(agent.Q[4] == 0.0) or isinstance(agent, QLearningAgent)


def test_all_true_mask_is_bit_identical_to_none():
    T, r = _chain()
    out = []
    for valid in (None, np.ones((5, 2), bool)):
        agent = make_agent("q-learning", 5, 2, np.random.default_rng(4))
        out.append(run_episodes(agent, EpisodeTask(T, r, horizon=12, valid=valid), 30,
                                np.random.default_rng(5)))
        out.append(agent.Q.copy())
    np.testing.assert_array_equal(out[0], out[2])
    np.testing.assert_array_equal(out[1], out[3])


def test_evaluate_q_with_terminal_and_mask():
    T, r = _chain()
    terminal = np.zeros(5, bool)
    terminal[-1] = True
    Q = np.zeros((1, 5, 2))
    Q[0, :, 1] = 1.0  # always move right
    ev = evaluate_q(EpisodeTask(T, r, horizon=10, start=0, terminal=terminal), Q, 0.9)
    assert ev.optimal_return == pytest.approx(1.0)  # reward once, then absorbed
    valid = np.ones((5, 2), bool)
    valid[:, 1] = False  # cannot move: nothing to earn
    ev = evaluate_q(EpisodeTask(T, r, horizon=10, start=0, terminal=terminal, valid=valid),
                    Q, 0.9)
    assert ev.greedy_returns[0] == pytest.approx(0.0)


def test_bad_mask_shape_is_a_config_error():
    with pytest.raises(ConfigError, match="valid"):
        QLearningAgent(3, 2, rng=np.random.default_rng(0), valid=np.ones((2, 2), bool))


def _learner_with_observer(takeover):
    S, A = 3, 2
    actor = core.agent_params(QLearningConfig(alpha=0.5, gamma=0.5, epsilon=0.0))
    watcher = core.agent_params(QLearningConfig(alpha=0.25, gamma=0.5, epsilon=0.0))
    obs = core.Observer(np.zeros((S, A)), watcher, takeover)
    return core.Learner(np.zeros((S, A)), core.NO_MODEL, actor, obs)


def test_learner_observer_learns_beside_the_actor_then_takes_over():
    lr = _learner_with_observer(takeover=2)
    t = core.learner_learn(lr, 0, 1, 1.0, 2, 1, core.NO_MASK, core.NO_TERMINAL, 7)
    # episode 1 < take-over 2: both learn (own alpha), the actor's clock advances
    assert t == 8
    assert lr.Q[0, 1] == 0.5 and lr.observer.Q[0, 1] == 0.25
    t = core.learner_learn(lr, 0, 1, 1.0, 2, 2, core.NO_MASK, core.NO_TERMINAL, t)
    # from the take-over on only the observer learns; the actor's clock stops
    assert t == 8
    assert lr.Q[0, 1] == 0.5 and lr.observer.Q[0, 1] == 0.25 + 0.25 * (1.0 - 0.25)
    # and the observer acts (greedy on its own Q) while the actor would pick otherwise
    lr.Q[1] = (1.0, 0.0)
    lr.observer.Q[1] = (0.0, 1.0)
    rng = np.random.default_rng(0)
    assert core.learner_act(lr, 1, 1, core.NO_MASK, rng) == 0
    assert core.learner_act(lr, 1, 2, core.NO_MASK, rng) == 1


def test_learner_without_observer_is_plain_act_and_learn():
    lr = _learner_with_observer(takeover=-1)._replace(
        observer=core.Observer(core.NO_OBSERVER_Q, core.agent_params(QLearningConfig()), 0))
    t = core.learner_learn(lr, 0, 1, 1.0, 2, 5, core.NO_MASK, core.NO_TERMINAL, 0)
    assert t == 1 and lr.Q[0, 1] == 0.5
    lr.Q[1] = (0.0, 3.0)
    assert core.learner_act(lr, 1, 5, core.NO_MASK, np.random.default_rng(0)) == 1
