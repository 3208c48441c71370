"""The meta-controller: criteria on hand-worked cases, entropy, low-pass costs, costs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simlab.agents.kernels import ALL_VALID
from simlab.agents.registry import agent_config
from simlab.base.errors import ConfigError
from simlab.online import meta
from simlab.online.loop import run_online
from simlab.online.task import OnlineTask

from .conftest import chain

EC = meta.criterion_code("entropy_and_cost")


def _choose(criterion: str, h_mf, h_mb, c_mf, c_mb, kappa=1.0, bits=3.0, seed=0):
    return meta.choose_expert(meta.criterion_code(criterion), h_mf, h_mb, c_mf, c_mb, kappa,
                              bits, np.random.default_rng(seed))


@pytest.mark.parametrize(("h_mf", "h_mb", "c_mf", "c_mb", "kappa", "bits", "expected"), [
    # 8 actions (3 bits). MF unsure (0.9 = 2.7 bits), MB sure (0.2): weight e^-2.7 = 0.0672;
    # -(0.9 + 0.0672/300) = -0.9002 < -(0.2 + 0.0672) = -0.2672
    (0.9, 0.2, 1.0, 300.0, 1.0, 3.0, meta.EXPERT_MB),
    # MF fairly sure (0.3 = 0.9 bits): weight 0.4066; -0.3014 > -(0.2 + 0.4066)
    (0.3, 0.2, 1.0, 300.0, 1.0, 3.0, meta.EXPERT_MF),
    # kappa 0 (weight 1): -(0.9 + 1/300) = -0.9033 > -(0.2 + 1) = -1.2
    (0.9, 0.2, 1.0, 300.0, 0.0, 3.0, meta.EXPERT_MF),
    # MF half sure, 8 actions: 1.5 bits, weight e^-1.5 = 0.2231: -(0.2 + 0.2231) = -0.4231
    # > -(0.5 + 0.0007): MB ...
    (0.5, 0.2, 1.0, 300.0, 1.0, 3.0, meta.EXPERT_MB),
    # ... but with 2 actions 0.5 is 0.5 bit, weight e^-0.5 = 0.6065: -0.8065 < -0.5020: MF
    (0.5, 0.2, 1.0, 300.0, 1.0, 1.0, meta.EXPERT_MF),
    # equal costs: the cost terms cancel, the lower entropy wins
    (0.5, 0.4, 7.0, 7.0, 1.0, 3.0, meta.EXPERT_MB),
    # no cost known yet (0/0 counts as 0): entropies only; a tie goes to MF
    (0.6, 0.6, 0.0, 0.0, 1.0, 3.0, meta.EXPERT_MF),
])
def test_entropy_and_cost_hand_worked(h_mf, h_mb, c_mf, c_mb, kappa, bits, expected) -> None:
    w = math.exp(-kappa * h_mf * bits)  # MF's entropy in bits weighs the cost term
    c_max = max(c_mf, c_mb)
    v_mf = -(h_mf + w * (c_mf / c_max if c_max else 0))
    v_mb = -(h_mb + w * (c_mb / c_max if c_max else 0))
    assert (meta.EXPERT_MB if v_mb > v_mf else meta.EXPERT_MF) == expected  # the formula
    assert _choose("entropy_and_cost", h_mf, h_mb, c_mf, c_mb, kappa, bits) == expected


def test_entropy_criterion_and_fixed_experts() -> None:
    assert _choose("entropy", 0.7, 0.3, 1.0, 500.0) == meta.EXPERT_MB  # cost ignored
    assert _choose("entropy", 0.3, 0.7, 500.0, 1.0) == meta.EXPERT_MF
    assert _choose("entropy", 0.5, 0.5, 0.0, 0.0) == meta.EXPERT_MF  # tie -> MF
    assert _choose("mb", 1.0, 1.0, 0.0, 9.0) == meta.EXPERT_MB
    assert _choose("mf", 1.0, 0.0, 9.0, 0.0) == meta.EXPERT_MF


def test_random_criterion_is_a_fair_coin_drawn_from_the_generator() -> None:
    rng = np.random.default_rng(3)
    picks = [meta.choose_expert(meta.criterion_code("random"), 0.0, 0.0, 0.0, 0.0, 1.0, 3.0,
                                rng) for _ in range(4000)]
    assert abs(np.mean(picks) - 0.5) < 4 * 0.5 / math.sqrt(4000)
    expect = np.random.default_rng(3).random(4000) < 0.5  # one draw each, MB below 0.5
    np.testing.assert_array_equal(np.array(picks) == meta.EXPERT_MB, expect)


def test_normalised_entropy_bounds() -> None:
    assert meta.normalised_entropy(np.zeros(8), ALL_VALID, 0.02) == pytest.approx(1.0)
    assert meta.normalised_entropy(np.array([1.0, 0, 0, 0]), ALL_VALID, 0.02) < 1e-15
    # two actions at a value gap of tau * ln 3: probabilities 3/4, 1/4
    q = np.array([0.02 * math.log(3), 0.0])
    h = -(0.75 * math.log(0.75) + 0.25 * math.log(0.25)) / math.log(2)
    assert meta.normalised_entropy(q, ALL_VALID, 0.02) == pytest.approx(h)
    # over the valid actions only: the masked ones do not count
    vrow = np.array([True, False, True, False])
    assert meta.normalised_entropy(np.array([0.0, 5.0, 0.0, 9.0]), vrow, 0.02) == \
        pytest.approx(1.0)
    assert meta.normalised_entropy(np.array([0.0, 5.0]), np.array([True, False]), 0.02) == 0.0


def test_distribution_entropy_normalised_and_in_bits() -> None:
    h, bits = meta.distribution_entropy(np.full(8, 1 / 8), ALL_VALID)
    assert h == pytest.approx(1.0) and bits == pytest.approx(3.0)
    h, bits = meta.distribution_entropy(np.array([0.75, 0.25, 0.0, 0.0]),
                                        np.array([True, True, False, False]))
    assert bits == pytest.approx(1.0)
    assert h == pytest.approx(-(0.75 * math.log(0.75) + 0.25 * math.log(0.25)) / math.log(2))
    assert meta.distribution_entropy(np.array([0.0, 1.0, 0.0]), ALL_VALID)[0] == 0.0


def test_decisions_read_the_filtered_distributions_of_the_state(experts) -> None:
    """Hand-worked: MF's Q row at state 0 is (tau ln 3, 0), softmax (3/4, 1/4); MB's is flat.
    The first decision reads the uniform start (entropy 1); after it both filters hold
    0.6 * softmax + 0.4 * the old value, and the second decision reads those."""
    mf, mb = experts
    ag = meta.make_meta_agent(mf, mb, 3, 2, meta.Arbitration(criterion="mf"))
    ag.mf.Q[0] = (0.02 * math.log(3), 0.0)
    ag.mb.Q[0] = (0.5, 0.5)
    rng = np.random.default_rng(0)
    out = meta.decide(ag, 0, rng)
    assert out[2] == pytest.approx(1.0) and out[3] == pytest.approx(1.0)
    np.testing.assert_allclose(ag.probs[meta.EXPERT_MF, 0], [0.6 * 0.75 + 0.2, 0.6 * 0.25 + 0.2])
    np.testing.assert_allclose(ag.probs[meta.EXPERT_MB, 0], [0.5, 0.5])
    np.testing.assert_allclose(ag.probs[:, 1:], 0.5)  # other states untouched
    p = np.array([0.65, 0.35])
    out = meta.decide(ag, 0, rng)
    assert out[2] == pytest.approx(-(p * np.log(p)).sum() / math.log(2))
    assert out[3] == pytest.approx(1.0)
    np.testing.assert_allclose(ag.probs[meta.EXPERT_MF, 0], 0.6 * np.array([0.75, 0.25]) + 0.4 * p)


@pytest.mark.parametrize("reward_ends", [True, False])
def test_a_reward_resets_the_values_of_the_rewarded_state(experts, reward_ends) -> None:
    mf, mb = experts
    ag = meta.make_meta_agent(mf, mb, 3, 2, meta.Arbitration(reward_ends=reward_ends))
    ag.mf.Q[2] = 0.7
    ag.mb.Q[2] = 0.7
    meta.learn(ag, 1, 1, 1.0, 2)
    q0 = 1 / 1.9  # the MF expert's q_init
    assert ag.mf.Q[1, 1] == pytest.approx(q0 + 0.6 * (1.0 + 0.9 * 0.7 - q0))  # learned first
    expect = 0.0 if reward_ends else 0.7
    assert np.all(ag.mf.Q[2] == expect) and np.all(ag.mb.Q[2] == expect)
    meta.learn(ag, 0, 1, 0.0, 1)  # no reward: nothing is reset
    assert np.all(ag.mf.Q[1] != 0.0)


def test_lowpass_filter() -> None:
    c = 0.0
    for expected in (6.0, 8.4, 9.36):  # 10 (1 - 0.4^k)
        c = meta.lowpass(c, 10.0, 0.6)
        assert c == pytest.approx(expected)
    assert meta.lowpass(5.0, 5.0, 0.6) == 5.0


def test_costs_are_filtered_per_state_for_the_deciding_expert(experts) -> None:
    mf, mb = experts
    T = chain(4)
    task = OnlineTask(goal=(3,), start_states=(0,)).compile(T)
    ag = meta.make_meta_agent(mf, mb, 4, 2, meta.Arbitration(criterion="mf"))  # MF alone: MB never plans
    log = run_online(ag, task, 50, np.random.default_rng(0), np.random.default_rng(1))
    assert np.all(log.backups == 1) and np.all(log.expert == meta.EXPERT_MF)
    # every visit of s filters 1 into C_MF(s): after k visits 1 - 0.4^k; MB never plans
    for s in range(4):
        k = int((log.s == s).sum())
        assert ag.cost[meta.EXPERT_MF, s] == pytest.approx(1 - 0.4 ** k)
    assert np.all(ag.cost[meta.EXPERT_MB] == 0) and np.all(ag.cost_time[meta.EXPERT_MB] == 0)
    # the logged c_mf is the filter before the decision: 1 - 0.4^(visits so far)
    seen: dict[int, int] = {}
    for t in range(log.n):
        s = int(log.s[t])
        assert log.c_mf[t] == pytest.approx(1 - 0.4 ** seen.get(s, 0))
        seen[s] = seen.get(s, 0) + 1


def test_model_based_cost_is_sweeps_times_known_pairs(experts) -> None:
    from simlab.agents import core

    mf, mb = experts
    ag = meta.make_meta_agent(mf, mb, 3, 2)
    for s, a, s2 in ((0, 1, 1), (1, 1, 2), (2, 0, 1)):  # three of the six pairs known
        meta.learn(ag, s, a, float(s2 == 2), s2)
    ag.mb.Q[:] = 0.0  # far from the fixed point: value iteration needs several sweeps
    Q = ag.mb.Q.copy()
    sweeps = core.plan(ag.mb.model, Q, ag.mb.params, core.NO_MASK, core.NO_TERMINAL)
    assert sweeps >= 2
    assert meta.expert_plan(ag.mb, core.NO_MASK) == 3 * sweeps
    np.testing.assert_array_equal(ag.mb.Q, Q)
    assert meta.expert_plan(ag.mf, core.NO_MASK) == 1


def test_bad_arbitration_settings_are_refused(experts) -> None:
    mf, mb = experts
    with pytest.raises(ConfigError, match="criterion"):
        meta.make_meta_agent(mf, mb, 3, 2, meta.Arbitration(criterion="coin"))
    with pytest.raises(ConfigError, match="cost_alpha"):
        meta.make_meta_agent(mf, mb, 3, 2, meta.Arbitration(cost_alpha=0.0))
    with pytest.raises(ConfigError, match="kappa"):
        meta.make_meta_agent(mf, mb, 3, 2, meta.Arbitration(kappa=-1.0))
    with pytest.raises(ConfigError, match="prob_alpha"):
        meta.make_meta_agent(mf, mb, 3, 2, meta.Arbitration(prob_alpha=1.5))


# ------------------------------------------------------------------ MB's reward model
def _mb_experts(mb_name: str):
    mf = agent_config("q-softmax", {"alpha": 0.6, "tau": 0.02, "q_init": 1 / 1.9})
    mb = agent_config(mb_name, {"tau": 0.02, "q_init": 1 / 1.9, "max_sweeps": 100,
                                "tol": 1e-4, "plan_every": 0})
    return mf, mb


def _mb_reward(ag, s: int, a: int) -> float:
    from simlab.agents.kernels import model_reward

    return float(model_reward(ag.mb.model, s, a))


@pytest.mark.parametrize("mb_name", ["sliding-window", "vi-softmax"])
@pytest.mark.parametrize("state_reward", [True, False])
def test_one_unrewarded_arrival_forgets_the_old_goal(mb_name, state_reward) -> None:
    # 4 states, 2 actions: (0, 1) and (3, 1) lead to state 1, the goal; (0, 0) leads to 2.
    ag = meta.make_meta_agent(*_mb_experts(mb_name), 4, 2,
                              meta.Arbitration(state_reward=state_reward, reward_ends=False))
    for _ in range(3):
        meta.learn(ag, 0, 1, 1.0, 1)
    meta.learn(ag, 3, 1, 1.0, 1)
    meta.learn(ag, 0, 0, 0.0, 2)
    meta.learn(ag, 0, 0, 0.0, 2)
    assert _mb_reward(ag, 0, 1) == 1.0 and _mb_reward(ag, 3, 1) == 1.0
    meta.learn(ag, 0, 1, 0.0, 1)  # the goal moved: one arrival at 1 without reward
    if state_reward:  # the reward of arriving in 1 is now 0, for every pair leading there
        assert _mb_reward(ag, 0, 1) == 0.0 and _mb_reward(ag, 3, 1) == 0.0
    else:  # each pair averages its own rewards: 3 of 4 rewarded; (3, 1) never saw the change
        assert _mb_reward(ag, 0, 1) == pytest.approx(0.75) and _mb_reward(ag, 3, 1) == 1.0
    meta.learn(ag, 3, 0, 1.0, 2)  # the new goal 2 is found from 3
    expect = 1.0 if state_reward else 0.0  # (0, 0) reached 2 twice, unrewarded then
    assert _mb_reward(ag, 0, 0) == pytest.approx(expect)
    assert _mb_reward(ag, 3, 0) == 1.0
    np.testing.assert_array_equal(ag.arrival_reward,
                                  [0.0, 0.0, 1.0, 0.0] if state_reward else 0.0)
    # MB's next plan values the old route by the state reward: Q(0, 1) = r(1) + 0.9 V(1)
    # with V(1) = 1/1.9 (no move from 1 known)
    meta.expert_plan(ag.mb, ag.valid)
    r1 = 0.0 if state_reward else 0.75
    assert ag.mb.Q[0, 1] == pytest.approx(r1 + 0.9 / 1.9, abs=1e-3)


def test_the_arrival_reward_leaves_mf_alone(experts) -> None:
    mf, mb = experts
    on = meta.make_meta_agent(mf, mb, 3, 2, meta.Arbitration(reward_ends=False))
    off = meta.make_meta_agent(mf, mb, 3, 2, meta.Arbitration(reward_ends=False, state_reward=False))
    for ag in (on, off):
        meta.learn(ag, 0, 1, 1.0, 1)
        meta.learn(ag, 0, 1, 0.0, 1)
    np.testing.assert_array_equal(on.mf.Q, off.mf.Q)


# ------------------------------------------------------------- first visit: both plan
@pytest.mark.parametrize("both", [True, False])
def test_both_experts_plan_at_a_first_visit(experts, both) -> None:
    mf, mb = experts
    ag = meta.make_meta_agent(mf, mb, 3, 2, meta.Arbitration(criterion="entropy", plan_both_first=both))
    q0 = 1 / 1.9
    meta.learn(ag, 0, 1, 0.0, 1)  # MB's incremental backup: Q(0, 1) = 0.9 q0
    meta.learn(ag, 1, 1, 1.0, 2)  # Q(1, 1) = 1 + 0.9 q0, then the goal's values reset to 0
    assert ag.mb.Q[0, 1] == pytest.approx(0.9 * q0)
    out = meta.decide(ag, 0, np.random.default_rng(0))
    assert out[1] == meta.EXPERT_MF  # both distributions uniform at first: a tie, MF
    # a plan of MB: Q(1, 1) = 1 + 0.9 * 0, Q(0, 1) = 0.9 * 1; Q(0, 0) unknown: q0
    q_mb0 = np.array([q0, 0.9]) if both else np.array([q0, 0.9 * q0])
    np.testing.assert_allclose(ag.mb.Q[0], q_mb0, atol=1e-4)
    p = np.exp((q_mb0 - q_mb0.max()) / 0.02)
    np.testing.assert_allclose(ag.probs[meta.EXPERT_MB, 0], 0.4 * 0.5 + 0.6 * p / p.sum(),
                               atol=1e-3)
    mb_backups = out[6] - 1  # MF's plan costs 1
    if both:  # sweeps x the 2 known pairs, filtered into MB's own cost at 0
        assert mb_backups >= 2 and mb_backups % 2 == 0
        assert ag.cost[meta.EXPERT_MB, 0] == pytest.approx(0.6 * mb_backups)
    else:
        assert mb_backups == 0 and ag.cost[meta.EXPERT_MB, 0] == 0.0
    cost = ag.cost.copy()
    again = meta.decide(ag, 0, np.random.default_rng(1))  # second visit: one expert plans
    e = again[1]
    assert ag.cost[1 - e, 0] == cost[1 - e, 0]
    if e == meta.EXPERT_MF:
        assert again[6] == 1


@pytest.mark.parametrize("criterion", ["entropy", "entropy_and_cost"])
@pytest.mark.parametrize("both", [True, False])
def test_mb_has_a_cost_exactly_where_it_planned(experts, criterion, both) -> None:
    mf, mb = experts
    T = chain(6, 0.8)
    ag = meta.make_meta_agent(mf, mb, 6, 2, meta.Arbitration(criterion=criterion, plan_both_first=both))
    task = OnlineTask(goal=(5,), start_states=(0,)).compile(T)
    log = run_online(ag, task, 60, np.random.default_rng(3), np.random.default_rng(4))
    visited = np.zeros(6, dtype=bool)
    visited[log.s] = True
    np.testing.assert_array_equal(ag.seen, visited)
    first = np.zeros(log.n, dtype=bool)
    first[np.unique(log.s, return_index=True)[1]] = True
    # MB planned at its own decisions and (with both) at every first visit; its plan
    # costs 0 only at t = 0, when it knows no pair yet
    mb_planned = (log.expert == meta.EXPERT_MB) | (first & both)
    mb_planned[0] = False
    expected = np.zeros(6, dtype=bool)
    expected[log.s[mb_planned]] = True
    np.testing.assert_array_equal(ag.cost[meta.EXPERT_MB] > 0, expected)
    # a later MF decision costs 1; a first visit with both costs both plans
    assert np.all(log.backups[~first & (log.expert == meta.EXPERT_MF)] == 1)
    if both:
        assert np.all(log.backups[1:][first[1:]] > 1)
    else:
        assert np.all(log.backups[first & (log.expert == meta.EXPERT_MF)] == 1)
