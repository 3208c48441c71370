"""The meta-controller: criteria on hand-worked cases, entropy, low-pass costs, costs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simlab.agents.kernels import ALL_VALID
from simlab.base.errors import ConfigError
from simlab.online import meta
from simlab.online.loop import run_online
from simlab.online.task import OnlineTask

from .conftest import chain

EC = meta.criterion_code("entropy_and_cost")


def _choose(criterion: str, h_mf, h_mb, c_mf, c_mb, kappa=1.0, seed=0):
    return meta.choose_expert(meta.criterion_code(criterion), h_mf, h_mb, c_mf, c_mb, kappa,
                              np.random.default_rng(seed))


@pytest.mark.parametrize(("h_mf", "h_mb", "c_mf", "c_mb", "kappa", "expected"), [
    # MF unsure (0.9), MB sure (0.2): -(0.9 + e^-0.9 * 1/300) = -0.9014 < -(0.2 + 0.4066)
    (0.9, 0.2, 1.0, 300.0, 1.0, meta.EXPERT_MB),
    # MF fairly sure (0.3): -(0.3 + 0.7408/300) = -0.3025 > -(0.2 + 0.7408) = -0.9408
    (0.3, 0.2, 1.0, 300.0, 1.0, meta.EXPERT_MF),
    # same entropies as the first case, kappa 0 (weight 1): -0.9033 vs -1.2: MF
    (0.9, 0.2, 1.0, 300.0, 0.0, meta.EXPERT_MF),
    # kappa 5: weight e^-4.5 = 0.0111: -(0.2 + 0.0111) > -(0.9 + 0.00004): MB
    (0.9, 0.2, 1.0, 300.0, 5.0, meta.EXPERT_MB),
    # equal costs: the cost terms cancel, the lower entropy wins
    (0.5, 0.4, 7.0, 7.0, 1.0, meta.EXPERT_MB),
    # no cost known yet (0/0 counts as 0): entropies only; a tie goes to MF
    (0.6, 0.6, 0.0, 0.0, 1.0, meta.EXPERT_MF),
])
def test_entropy_and_cost_hand_worked(h_mf, h_mb, c_mf, c_mb, kappa, expected) -> None:
    v_mf = -(h_mf + math.exp(-kappa * h_mf) * (c_mf / max(c_mf, c_mb) if max(c_mf, c_mb) else 0))
    v_mb = -(h_mb + math.exp(-kappa * h_mf) * (c_mb / max(c_mf, c_mb) if max(c_mf, c_mb) else 0))
    assert (meta.EXPERT_MB if v_mb > v_mf else meta.EXPERT_MF) == expected  # the formula
    assert _choose("entropy_and_cost", h_mf, h_mb, c_mf, c_mb, kappa) == expected


def test_entropy_criterion_and_fixed_experts() -> None:
    assert _choose("entropy", 0.7, 0.3, 1.0, 500.0) == meta.EXPERT_MB  # cost ignored
    assert _choose("entropy", 0.3, 0.7, 500.0, 1.0) == meta.EXPERT_MF
    assert _choose("entropy", 0.5, 0.5, 0.0, 0.0) == meta.EXPERT_MF  # tie -> MF
    assert _choose("mb", 1.0, 1.0, 0.0, 9.0) == meta.EXPERT_MB
    assert _choose("mf", 1.0, 0.0, 9.0, 0.0) == meta.EXPERT_MF


def test_random_criterion_is_a_fair_coin_drawn_from_the_generator() -> None:
    rng = np.random.default_rng(3)
    picks = [meta.choose_expert(meta.criterion_code("random"), 0.0, 0.0, 0.0, 0.0, 1.0, rng)
             for _ in range(4000)]
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
    ag = meta.make_meta_agent(mf, mb, 4, 2, criterion="mf")
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
        meta.make_meta_agent(mf, mb, 3, 2, criterion="coin")
    with pytest.raises(ConfigError, match="cost_alpha"):
        meta.make_meta_agent(mf, mb, 3, 2, cost_alpha=0.0)
    with pytest.raises(ConfigError, match="kappa"):
        meta.make_meta_agent(mf, mb, 3, 2, kappa=-1.0)
