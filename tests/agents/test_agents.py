"""Agent classes: learning results, exploration, non-stationarity, configs, registry."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from simlab.agents import (
    AGENTS,
    ModelBasedAgent,
    ModelBasedConfig,
    PassiveObserverAgent,
    QLearningAgent,
    QLearningConfig,
    RMaxAgent,
    RMaxConfig,
    Selection,
    SlidingWindowAgent,
    SlidingWindowConfig,
    agent_config,
    make_agent,
    value_iteration,
)
from simlab.agents import kernels as K
from simlab.base.errors import ConfigError


def small_stochastic_mdp():
    rng = np.random.default_rng(42)
    S, A = 4, 2
    P = rng.dirichlet(np.ones(S), size=(S, A))
    R = rng.uniform(-1, 1, size=(S, A))
    return P, R


@njit(cache=True)
def _q_learning_uniform(P, R, gamma, steps, rng):
    S, A = R.shape
    Q = np.zeros((S, A))
    n = np.zeros((S, A))
    cdf = np.empty_like(P)
    for s in range(S):
        for a in range(A):
            cdf[s, a] = np.cumsum(P[s, a])
    s = 0
    for _ in range(steps):
        a = rng.integers(0, A)
        s2 = K.sample_from_cdf(cdf[s, a], rng)
        n[s, a] += 1
        # Robbins-Monro step sizes: sum alpha = inf, sum alpha^2 < inf
        K.q_learning_update(Q, s, a, R[s, a], s2, 1.0 / n[s, a] ** 0.7, gamma)
        s = s2
    return Q


def test_q_learning_kernel_converges_to_value_iteration():
    P, R = small_stochastic_mdp()
    Q_star, _, _ = value_iteration(P, R, 0.8)
    Q = _q_learning_uniform(P, R, 0.8, 1_000_000, np.random.default_rng(0))
    # |Q*| is up to ~5 here; 1e6 uniform steps bring every entry within 0.05
    assert np.max(np.abs(Q - Q_star)) < 0.05


def test_q_learning_agent_approaches_value_iteration():
    P, R = small_stochastic_mdp()
    gamma = 0.8
    Q_star, _, _ = value_iteration(P, R, gamma)
    rng = np.random.default_rng(1)
    cfg = QLearningConfig(gamma=gamma, alpha=0.02, epsilon=1.0, q_init=0.0)
    agent = QLearningAgent(4, 2, cfg, rng)
    cdf = np.cumsum(P, axis=2)
    errors = []
    s = 0
    for t in range(60_000):
        a = agent.act(s)
        s2 = int(K.sample_from_cdf(cdf[s, a], rng))
        agent.update(s, a, R[s, a], s2)
        s = s2
        if t in (1_000, 59_999):
            errors.append(np.max(np.abs(agent.Q - Q_star)))
    assert errors[1] < 0.25 < errors[0]  # it got there, and it was not there early
    np.testing.assert_array_equal(agent.Q.argmax(1), Q_star.argmax(1))


# --------------------------------------------------------------------------- R-max
def combination_lock(n: int, n_actions: int, seed: int):
    """Chain of ``n`` states; in states 0..n-2 one secret correct action moves forward
    and any other resets to state 0. Arriving in the last state pays 1; from there
    every action returns to state 0 (so the best return is 1 every n steps)."""
    correct = np.random.default_rng(seed).integers(0, n_actions, n)

    def step(s, a):
        if s == n - 1 or a != correct[s]:
            return 0, 0.0
        return s + 1, float(s + 1 == n - 1)

    return correct, step


def steps_to_optimal_policy(agent, correct, step, max_steps):
    """Steps until ``argmax Q`` is the unique correct action in states 0..n-2
    (the greedy policy then earns the optimal return; in the last state all
    actions are equivalent)."""
    n = len(correct) - 1
    rows = np.arange(n)
    s = 0
    for t in range(max_steps):
        a = agent.act(s)
        s2, r = step(s, a)
        agent.update(s, a, r, s2)
        s = s2
        Q = agent.Q[:n]
        others = Q.copy()
        others[rows, correct[:n]] = -np.inf
        if np.all(Q[rows, correct[:n]] > others.max(1)):
            return t + 1
    return max_steps


def test_rmax_solves_a_combination_lock_far_faster_than_epsilon_greedy():
    n, A, cap = 10, 2, 30_000
    classic = RMaxConfig(m=1, replan_when_known=True, plan_every=0, max_sweeps=50)
    rmax_steps, paper_steps, egreedy_steps, q_steps = [], [], [], []
    for seed in range(10):
        correct, step = combination_lock(n, A, seed)
        for cfg, out in ((classic, rmax_steps), (RMaxConfig(m=1), paper_steps)):
            agent = RMaxAgent(n, A, cfg, np.random.default_rng(seed))
            out.append(steps_to_optimal_policy(agent, correct, step, cap))
        # undirected exploration: zero-initialised values, epsilon-greedy
        mb = ModelBasedAgent(n, A, ModelBasedConfig(q_init=0.0), np.random.default_rng(seed))
        egreedy_steps.append(steps_to_optimal_policy(mb, correct, step, cap))
        ql = QLearningAgent(n, A, QLearningConfig(q_init=0.0), np.random.default_rng(seed))
        q_steps.append(steps_to_optimal_policy(ql, correct, step, cap))
    # R-max tries each of the 20 pairs once, walking back after every reset: on the
    # order of n^2 / 2 steps (measured: classic 55-65, paper settings 71-113).
    # Undirected exploration first needs the 9 correct actions in a row by chance,
    # about 2^n steps (measured: 750-5,500).
    assert max(rmax_steps) <= 100
    assert max(paper_steps) <= 150
    for rmax in (rmax_steps, paper_steps):
        assert np.mean(egreedy_steps) >= 10 * np.mean(rmax)
        assert np.mean(q_steps) >= 10 * np.mean(rmax)
    assert min(egreedy_steps) >= 500


def test_rmax_values_stay_optimistic_until_m_visits():
    agent = RMaxAgent(3, 2, RMaxConfig(m=3, gamma=0.5), np.random.default_rng(0))
    assert np.all(agent.Q == 2.0)  # r_max / (1 - gamma)
    for _ in range(2):
        agent.update(0, 1, 0.0, 1)
    assert agent.Q[0, 1] == 2.0 and not agent.known()[0, 1]
    agent.update(0, 1, 0.0, 1)  # third visit: known, value 0 + 0.5 * max Q[1] = 1
    assert agent.known()[0, 1]
    assert agent.Q[0, 1] == pytest.approx(1.0)


# --------------------------------------------------------------------------- non-stationarity
def _bandit_with_switch(agent, steps, switch):
    """One state, two actions: action 0 pays 1 before ``switch`` and 0 after;
    action 1 always pays 0.5. Returns the actions taken."""
    actions = np.empty(steps, dtype=int)
    for t in range(steps):
        a = agent.act(0)
        r = (1.0 if t < switch else 0.0) if a == 0 else 0.5
        agent.update(0, a, r, 0)
        actions[t] = a
    return actions


def test_sliding_window_model_adapts_to_a_change_the_count_model_averages_away():
    common = dict(gamma=0.5, selection="epsilon-greedy", epsilon=0.1, plan_every=0)
    win_cfg = SlidingWindowConfig(window=10, **common)
    cnt_cfg = ModelBasedConfig(**common)
    after_win, after_cnt = [], []
    for seed in range(5):
        w = _bandit_with_switch(
            SlidingWindowAgent(1, 2, win_cfg, np.random.default_rng(seed)), 1400, 1000
        )
        c = _bandit_with_switch(
            ModelBasedAgent(1, 2, cnt_cfg, np.random.default_rng(seed)), 1400, 1000
        )
        after_win.append(np.mean(w[1100:] == 1))
        after_cnt.append(np.mean(c[1100:] == 1))
    # the window forgets the old payoff after ~10 tries of action 0; the counts
    # need as many bad outcomes as the ~900 good ones before the mean drops below 0.5
    assert np.mean(after_win) > 0.85
    assert np.mean(after_cnt) < 0.15


# --------------------------------------------------------------------------- passive observer
def test_passive_observer_does_at_least_as_well_as_model_free_alone():
    from simlab.training.harness import EpisodeTask, evaluate_q, run_episodes
    from simlab.training.synthetic import synthetic_arena_mdp

    mdp = synthetic_arena_mdp(np.random.default_rng(0))
    episodes = 200  # 10,000 steps each
    for goal in ("g1", "g5"):
        task = EpisodeTask(mdp.T, mdp.goal_reward(goal))
        observer_q, alone_q = [], []
        for seed in range(10):
            agent_seq, env_seq = np.random.SeedSequence(seed).spawn(2)
            po = make_agent("passive-observer", 41, 16, np.random.default_rng(agent_seq))
            run_episodes(po, task, episodes, np.random.default_rng(env_seq))
            assert po.controlling == "observer"  # it took over half-way
            # the same Q-learner (same hyper-parameters) learning on its own
            mf = QLearningAgent(41, 16, po.config.observer, np.random.default_rng(agent_seq))
            run_episodes(mf, task, episodes, np.random.default_rng(env_seq))
            observer_q.append(po.Q)
            alone_q.append(mf.Q)
        ev_obs = evaluate_q(task, np.array(observer_q), 0.9)
        ev_mf = evaluate_q(task, np.array(alone_q), 0.9)
        assert ev_obs.greedy_returns.mean() >= ev_mf.greedy_returns.mean()


def test_passive_observer_stops_the_actor_after_take_over():
    po = make_agent("passive-observer", 3, 2, np.random.default_rng(0))
    po.update(0, 1, 1.0, 2)
    assert po.actor.model.n_sa[0, 1] == 1 and po.Q[0, 1] > 0
    po.take_over()
    po.update(0, 1, 1.0, 2)
    assert po.actor.model.n_sa[0, 1] == 1  # the actor no longer learns
    assert po.controlling == "observer"


# --------------------------------------------------------------------------- configs, registry
@pytest.mark.parametrize(
    ("build", "field"),
    [
        (lambda: QLearningConfig(alpha=1.5), "alpha"),
        (lambda: QLearningConfig(gamma=1.0), "gamma"),
        (lambda: QLearningConfig(epsilon=-0.1), "epsilon"),
        (lambda: QLearningConfig(tau=0.0), "tau"),
        (lambda: QLearningConfig(selection="boltzman"), "selection"),
        (lambda: ModelBasedConfig(plan_every=-1), "plan_every"),
        (lambda: ModelBasedConfig(max_sweeps=0), "max_sweeps"),
        (lambda: SlidingWindowConfig(window=0), "window"),
        (lambda: RMaxConfig(m=0), "m"),
    ],
)
def test_configs_reject_bad_values_naming_the_field(build, field):
    with pytest.raises(ConfigError) as err:
        build()
    assert err.value.key == field


def test_selection_accepts_names():
    assert QLearningConfig(selection="softmax").selection is Selection.SOFTMAX
    assert QLearningConfig(selection="epsilon-greedy").selection is Selection.EPSILON_GREEDY


def test_registry_names_and_overrides():
    assert set(AGENTS) >= {"q-learning", "q-softmax", "mb-egreedy", "vi-softmax", "rmax",
                           "sliding-window", "passive-observer"}  # fmt: skip
    rng = np.random.default_rng(0)
    assert isinstance(make_agent("vi-softmax", 3, 2, rng), ModelBasedAgent)
    assert make_agent("vi-softmax", 3, 2, rng).config.selection is Selection.SOFTMAX
    assert make_agent("vi-softmax", 3, 2, rng, tau=0.05).config.tau == 0.05
    assert isinstance(make_agent("sliding-window", 3, 2, rng), SlidingWindowAgent)
    assert isinstance(make_agent("passive-observer", 3, 2, rng), PassiveObserverAgent)
    assert agent_config("passive-observer", {"observer.alpha": 0.5}).observer.alpha == 0.5
    assert agent_config("rmax", {"m": 5}).m == 5


def test_unknown_agent_and_parameter_names_are_clear_errors():
    rng = np.random.default_rng(0)
    with pytest.raises(ConfigError, match="known agents: q-learning, q-softmax"):
        make_agent("dqn", 3, 2, rng)
    with pytest.raises(ConfigError, match=r"unknown parameter 'temperature'.*tau"):
        make_agent("vi-softmax", 3, 2, rng, temperature=0.1)
    with pytest.raises(ConfigError, match="Generator"):
        QLearningAgent(3, 2, None, 0)


def test_every_agent_is_deterministic_given_its_generator():
    for name in AGENTS:
        runs = []
        for _ in range(2):
            rng = np.random.default_rng(5)
            agent = make_agent(name, 6, 3, rng)
            s = 0
            for _t in range(300):
                a = agent.act(s)
                s2 = (s + a) % 6
                agent.update(s, a, float(s2 == 5), s2)
                s = s2
            runs.append(agent.Q.copy())
        np.testing.assert_array_equal(runs[0], runs[1])
