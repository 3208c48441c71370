"""Numba kernels: action selection, Q-learning, sampling, sparse and window models."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from simlab.agents import kernels as K


def _freq_close(counts: np.ndarray, p: np.ndarray, n: int, z: float = 5.0) -> bool:
    """Every empirical frequency within ``z`` binomial standard errors of ``p``."""
    se = np.sqrt(np.maximum(p * (1 - p), 1e-12) / n)
    return bool(np.all(np.abs(counts / n - p) <= z * se + 1e-12))


@njit(cache=True)
def _draw_many_jit(kind, q, eps, tau, rng, n):
    out = np.empty(n, dtype=np.int64)
    for i in range(n):
        if kind == 0:
            out[i] = K.greedy_action(q, rng)
        elif kind == 1:
            out[i] = K.epsilon_greedy_action(q, eps, rng)
        else:
            out[i] = K.softmax_action(q, tau, rng)
    return out


def _draw_many(kind, q, eps, tau, seed, n):
    return _draw_many_jit(kind, q, eps, tau, np.random.default_rng(seed), n)


N = 40_000


def test_greedy_breaks_ties_uniformly_and_never_picks_a_lower_value():
    q = np.array([0.5, 2.0, -1.0, 2.0, 2.0, 1.9])
    draws = _draw_many(0, q, 0.0, 0.0, 1, N)
    counts = np.bincount(draws, minlength=6)
    assert counts[[0, 2, 5]].sum() == 0
    assert _freq_close(counts[[1, 3, 4]], np.full(3, 1 / 3), N)
    # a unique maximum is returned without consuming randomness
    rng = np.random.default_rng(3)
    state = rng.bit_generator.state
    assert K.greedy_action(np.array([0.0, 1.0, 0.5]), rng) == 1
    assert rng.bit_generator.state == state


def test_epsilon_greedy_explores_with_probability_epsilon():
    q = np.array([0.0, 1.0, 0.0, 0.0])
    eps = 0.2
    counts = np.bincount(_draw_many(1, q, eps, 0.0, 2, N), minlength=4)
    p = np.full(4, eps / 4)
    p[1] += 1 - eps
    assert _freq_close(counts, p, N)


def test_softmax_matches_boltzmann_probabilities():
    q = np.array([1.0, 1.2, 0.7, 1.2, -3.0])
    tau = 0.3
    w = np.exp(q / tau)
    p = w / w.sum()
    np.testing.assert_allclose(K.softmax_probabilities(q, tau, np.empty(5)), p, rtol=1e-12)
    counts = np.bincount(_draw_many(2, q, 0.0, tau, 3, N), minlength=5)
    assert _freq_close(counts, p, N)


def test_softmax_is_numerically_stable_for_large_values():
    q = np.array([1e6, 1e6 - 0.1, 1e6 + 0.1])
    tau = 0.1
    # naive exp(q / tau) overflows; the stable form gives exp((q - max) / tau)
    p = np.exp(np.array([-1.0, -2.0, 0.0]))
    p /= p.sum()
    out = K.softmax_probabilities(q, tau, np.empty(3))
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out, p, rtol=1e-9)
    counts = np.bincount(_draw_many(2, q, 0.0, tau, 4, N), minlength=3)
    assert _freq_close(counts, p, N)


def test_softmax_zero_temperature_is_greedy():
    q = np.array([0.0, 3.0, 3.0])
    draws = _draw_many(2, q, 0.0, 0.0, 5, 4000)
    assert set(np.unique(draws)) == {1, 2}


def test_same_seed_same_actions_and_generator_state_is_shared_with_python():
    q = np.zeros(7)
    a = _draw_many(2, q, 0.0, 0.1, 11, 100)
    b = _draw_many(2, q, 0.0, 0.1, 11, 100)
    np.testing.assert_array_equal(a, b)
    # the njit call advances the caller's Generator
    r1 = np.random.default_rng(9)
    r2 = np.random.default_rng(9)
    K.softmax_action(q, 0.1, r1)
    assert r1.random() != r2.random()


def test_q_learning_update_matches_equation():
    Q = np.array([[0.0, 1.0], [2.0, 4.0]])
    td = K.q_learning_update(Q, 0, 1, 0.5, 1, 0.7, 0.9)
    # r + gamma * max Q[1] - Q[0, 1] = 0.5 + 3.6 - 1 = 3.1; Q[0,1] = 1 + 0.7 * 3.1
    assert td == pytest.approx(3.1)
    assert Q[0, 1] == pytest.approx(1 + 0.7 * 3.1)
    assert Q[0, 0] == 0.0 and Q[1, 1] == 4.0
    K.q_learning_update(Q, 1, 0, 1.0, 1, 1.0, 0.0)  # terminal: no bootstrap
    assert Q[1, 0] == pytest.approx(1.0)


@njit(cache=True)
def _draw_cdf(p, rng, n):
    cdf = np.cumsum(p)
    a = np.empty(n, dtype=np.int64)
    b = np.empty(n, dtype=np.int64)
    for i in range(n):
        a[i] = K.sample_from_cdf(cdf, rng)
        b[i] = K.sample_categorical(p, rng)
    return a, b


def test_samplers_follow_probabilities_and_skip_zeros():
    p = np.array([0.0, 0.25, 0.0, 0.5, 0.25, 0.0])
    a, b = _draw_cdf(p, np.random.default_rng(6), N)
    for draws in (a, b):
        counts = np.bincount(draws, minlength=6)
        assert counts[[0, 2, 5]].sum() == 0
        assert _freq_close(counts, p, N)


# --------------------------------------------------------------------------- count model
def _random_log(rng, S, A, n, branching):
    """Transitions with at most ``branching`` possible successors per pair."""
    succ = rng.integers(0, S, size=(S, A, branching))
    s = rng.integers(0, S, n)
    a = rng.integers(0, A, n)
    s2 = succ[s, a, rng.integers(0, branching, n)]
    r = rng.normal(size=n)
    return s, a, r, s2


def test_count_model_equals_dense_counting_and_grows_without_dropping():
    rng = np.random.default_rng(0)
    S, A = 13, 4
    s, a, r, s2 = _random_log(rng, S, A, 3000, 3)
    m = K.CountModel(S, A, 1)  # capacity 1: forces many reallocations
    for i in range(len(s)):
        K.count_model_observe(m, s[i], a[i], r[i], s2[i])
    counts = np.zeros((S, A, S))
    np.add.at(counts, (s, a, s2), 1)
    n_sa = counts.sum(-1)
    r_sum = np.zeros((S, A))
    np.add.at(r_sum, (s, a), r)
    T, R = m.transition_matrix()
    visited = n_sa > 0
    np.testing.assert_array_equal(m.n_sa, n_sa)
    np.testing.assert_allclose(T[visited], counts[visited] / n_sa[visited][:, None], rtol=1e-12)
    np.testing.assert_allclose(T[visited].sum(-1), 1.0, rtol=1e-12)
    assert np.all(T[~visited] == 0)
    np.testing.assert_allclose(R[visited], r_sum[visited] / n_sa[visited], rtol=1e-9)
    distinct = int((counts > 0).sum())
    assert m.n_entries == distinct  # one pool entry per distinct triple
    assert m.n_pairs == int(visited.sum())
    assert distinct <= m.capacity < 2 * distinct  # doubling growth
    ss, aa, nn, cc = K.count_model_triples(m)
    back = np.zeros((S, A, S))
    np.add.at(back, (ss, aa, nn), cc)
    np.testing.assert_array_equal(back, counts)


def test_count_model_memory_is_proportional_to_distinct_triples():
    rng = np.random.default_rng(1)
    S, A = 400, 10
    sizes = []
    for branching in (1, 4):
        s, a, r, s2 = _random_log(rng, S, A, 40_000, branching)
        m = K.CountModel(S, A, 16)
        for i in range(len(s)):
            K.count_model_observe(m, s[i], a[i], r[i], s2[i])
        pool = m.memory_bytes - 5 * 8 * S * A  # minus the fixed per-pair arrays
        assert pool == 24 * m.capacity
        sizes.append((m.n_entries, pool))
    (e1, p1), (e4, p4) = sizes
    assert e4 > 3 * e1
    assert p1 < 2 * 24 * e1 and p4 < 2 * 24 * e4
    assert S * A * S * 8 > 20 * (p4 + 5 * 8 * S * A)  # far below a dense S*A*S table


def test_count_model_backup_and_value_iteration_match_dense_planning():
    rng = np.random.default_rng(2)
    S, A, gamma = 9, 3, 0.9
    s, a, r, s2 = _random_log(rng, S, A, 2000, 3)
    m = K.CountModel(S, A, 8)
    for i in range(len(s)):
        K.count_model_observe(m, s[i], a[i], r[i], s2[i])
    T, R = m.transition_matrix()
    assert np.all(m.n_sa > 0)
    # one backup by hand
    Q = rng.normal(size=(S, A))
    before = Q[4, 1]
    expected = R[4, 1] + gamma * T[4, 1] @ Q.max(1)
    delta = K.count_model_backup(m, Q, 4, 1, gamma, 1)
    assert Q[4, 1] == pytest.approx(expected)
    assert delta == pytest.approx(abs(expected - before))  # the change it made, not just >= 0
    assert delta > 0
    kept = Q.copy()  # a pair below m_known visits is skipped: no change, delta 0
    assert K.count_model_backup(m, Q, 4, 1, gamma, int(m.n_sa[4, 1]) + 1) == 0.0
    assert np.array_equal(Q, kept)
    # sweeps converge to the dense fixed point
    Qd = np.zeros((S, A))
    for _ in range(2000):
        Qd = R + gamma * T @ Qd.max(1)
    Q = np.zeros((S, A))
    sweeps = K.count_model_value_iteration(m, Q, gamma, 10_000, 1e-12, 1)
    assert 1 < sweeps < 10_000
    np.testing.assert_allclose(Q, Qd, atol=1e-9)


def test_pairs_below_m_known_keep_their_initial_value():
    S, A, gamma = 3, 2, 0.9
    m = K.CountModel(S, A, 4)
    K.count_model_observe(m, 0, 0, 1.0, 1)
    K.count_model_observe(m, 0, 0, 1.0, 1)
    K.count_model_observe(m, 1, 1, 0.0, 2)
    Q = K.rmax_q_init(S, A, 1.0, gamma)
    assert np.all(Q == pytest.approx(10.0))
    K.count_model_value_iteration(m, Q, gamma, 100, 0.0, 2)
    # (0,0) known (2 visits): 1 + 0.9 * max Q[1] = 1 + 0.9 * 10; (1,1) unknown: stays 10
    assert Q[0, 0] == pytest.approx(10.0)
    assert Q[1, 1] == pytest.approx(10.0)
    assert K.count_model_backup(m, Q, 1, 1, gamma, 2) == 0.0
    K.count_model_observe(m, 1, 1, 0.0, 2)
    K.count_model_backup(m, Q, 1, 1, gamma, 2)
    assert Q[1, 1] == pytest.approx(0.9 * 10.0)


# --------------------------------------------------------------------------- window model
def test_window_model_counts_only_the_last_h_outcomes():
    S, A, H = 5, 2, 4
    m = K.WindowModel(S, A, H, 1)
    outcomes = [1, 1, 2, 3, 4, 4, 4, 0]
    rewards = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]
    for s2, r in zip(outcomes, rewards, strict=True):
        n = K.window_model_observe(m, 2, 1, r, s2)
    assert n == 8
    assert K.window_model_visits(m, 2, 1) == H
    row = np.empty(S)
    assert K.window_model_transition_row(m, 2, 1, row) == H
    np.testing.assert_allclose(row, [0.25, 0, 0, 0, 0.75])  # last four: 4, 4, 4, 0
    assert K.window_model_reward(m, 2, 1) == pytest.approx((4 + 5 + 6 + 7) / 4)
    # more pairs than the initial capacity: slots grow, older windows intact
    for s in range(S):
        K.window_model_observe(m, s, 0, 1.0, 3)
    assert m.n_pairs == S + 1
    np.testing.assert_allclose(m.transition_matrix()[0][2, 1], [0.25, 0, 0, 0, 0.75])
    Q = np.zeros((S, A))
    K.window_model_backup(m, Q, 2, 1, 0.5, 1)
    assert Q[2, 1] == pytest.approx(5.5)


def test_window_model_with_large_window_equals_count_model():
    rng = np.random.default_rng(4)
    S, A = 6, 3
    s, a, r, s2 = _random_log(rng, S, A, 500, 3)
    cm = K.CountModel(S, A, 2)
    wm = K.WindowModel(S, A, 10_000, 2)
    for i in range(len(s)):
        K.count_model_observe(cm, s[i], a[i], r[i], s2[i])
        K.window_model_observe(wm, s[i], a[i], r[i], s2[i])
    Tc, Rc = cm.transition_matrix()
    Tw, Rw = wm.transition_matrix()
    np.testing.assert_allclose(Tw, Tc, atol=1e-12)
    np.testing.assert_allclose(Rw, Rc, atol=1e-12)
    Q1, Q2 = np.zeros((S, A)), np.zeros((S, A))
    K.count_model_value_iteration(cm, Q1, 0.9, 5000, 1e-12, 1)
    K.window_model_value_iteration(wm, Q2, 0.9, 5000, 1e-12, 1)
    np.testing.assert_allclose(Q1, Q2, atol=1e-9)


# --------------------------------------------------------------------------- generic API
@njit(cache=True)
def _rmax_run(model, Q, steps, m):
    # deterministic 2-state world: action 0 stays, action 1 swaps; reward 1 in state 1
    s = 0
    replans = np.zeros(steps, dtype=np.int64)
    for t in range(steps):
        a = t % 2
        s2 = s if a == 0 else 1 - s
        n = K.model_based_update(
            model, Q, s, a, 1.0 if s2 == 1 else 0.0, s2, 0.5, m, True, True, 100, 1e-12
        )
        replans[t] = n
        s = s2
    return replans


def test_model_based_update_replans_when_a_pair_becomes_known():
    for make in (lambda: K.CountModel(2, 2, 2), lambda: K.WindowModel(2, 2, 3, 2)):
        model = make()
        Q = K.rmax_q_init(2, 2, 1.0, 0.5)  # optimistic value 2
        n = _rmax_run(model, Q, 4, 2)
        # visits: (0,0) (0,1) (1,0) (1,1) once each -> none known (m=2): Q untouched
        np.testing.assert_array_equal(n, [1, 1, 1, 1])
        assert np.all(Q == 2.0)
        _rmax_run(model, Q, 4, 2)  # second visits: all known, VI on the true model
        # true values (gamma 0.5): V1 = 1/(1-0.5) = 2 staying; Q(0,1) = 1 + 0.5*2 = 2,
        # Q(0,0) = 0 + 0.5*V0 with V0 = 2 -> 1; Q(1,1) = 0 + 0.5*V0 = 1; Q(1,0) = 1 + 0.5*2
        np.testing.assert_allclose(Q, [[1.0, 2.0], [2.0, 1.0]], atol=1e-9)


# --------------------------------------------------------------------------- docstring example
@njit(cache=True)
def _chain_step(s, a, n_states):
    s_next = min(s + 1, n_states - 1) if a == 1 else max(s - 1, 0)
    return s_next, 1.0 if s_next == n_states - 1 else 0.0


@njit(cache=True)
def _train(Q, Q_obs, model, rng, n_trials, n_steps, gamma, tau, alpha, plan_every):
    S = Q.shape[0]
    t = 0
    returns = np.zeros(n_trials)
    for trial in range(n_trials):
        s = 0
        for _ in range(n_steps):
            a = K.softmax_action(Q[s], tau, rng)
            s_next, r = _chain_step(s, a, S)
            K.model_based_update(model, Q, s, a, r, s_next, gamma, 1, True, False, 0, 0.0)
            K.q_learning_update(Q_obs, s, a, r, s_next, alpha, gamma)
            t += 1
            if t % plan_every == 0:
                K.model_value_iteration(model, Q, gamma, 50, 1e-6, 1)
            returns[trial] += r
            s = s_next
    return returns


def test_fused_loop_example_from_the_module_docstring_learns_the_chain():
    S, A = 10, 2
    model = K.count_model_new(S, A, 64)
    Q, Q_obs = np.zeros((S, A)), np.zeros((S, A))
    returns = _train(Q, Q_obs, model, np.random.default_rng(0), 200, 30, 0.9, 0.1, 0.5, 100)
    # optimal: 9 steps right then stay at the end (action 1 keeps s = 9): 30 - 9 = 21
    assert returns[-20:].mean() >= 0.9 * 21
    assert np.all(Q.argmax(1) == 1)
    assert model.n_sa.sum() == 200 * 30
    again = _train(
        np.zeros((S, A)),
        np.zeros((S, A)),
        K.count_model_new(S, A, 64),
        np.random.default_rng(0),
        200,
        30,
        0.9,
        0.1,
        0.5,
        100,
    )
    np.testing.assert_array_equal(returns, again)
