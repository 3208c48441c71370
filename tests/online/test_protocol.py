"""The published protocol's rules, each on a hand-worked MDP whose trajectory does not depend
on the agent (every action of a state has the same outcome), and the agent's side of them."""

from __future__ import annotations

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.online import meta
from simlab.online.loop import run_online
from simlab.online.protocol import MAX_RESTARTS, PROTOCOLS, Protocol
from simlab.online.task import Change, OnlineTask

Q0 = 1 / 1.9  # the experts' initial value (conftest)


def ring(S: int = 4, A: int = 2) -> np.ndarray:
    """Every action moves 0 -> 1 -> 2 -> 0; state 3 is a trap (every action stays)."""
    T = np.zeros((S, A, S))
    for s, s2 in ((0, 1), (1, 2), (2, 0), (3, 3)):
        T[s, :, s2] = 1.0
    return T


def trap_from(s: int, T: np.ndarray | None = None) -> np.ndarray:
    """``T`` (default :func:`ring`) in which every action of ``s`` leads to the trap 3."""
    T = ring() if T is None else T.copy()
    T[s] = 0.0
    T[s, :, 3] = 1.0
    return T


def _run(experts, task, rules, n=12, criterion="mb", seed=0, T=None, **arb):
    mf, mb = experts
    T = ring() if T is None else T
    ag = meta.make_meta_agent(mf, mb, T.shape[0], T.shape[1],
                              meta.Arbitration(criterion=criterion, **arb))
    ss = np.random.SeedSequence(seed).spawn(2)
    log = run_online(ag, task.compile(T), n, np.random.default_rng(ss[0]),
                     np.random.default_rng(ss[1]), rules)
    return ag, log


TASK = OnlineTask(goal=(2,), start_states=(0,))


# ------------------------------------------------------------------ environment's rules
def test_the_reset_is_a_decision_in_the_goal(experts) -> None:
    """Teleport: 0 -> 1 -> 2 (rewarded), then the next decision is in 0: a reward every 2
    decisions, 6 in 12. Published: the agent decides once more in 2, and that decision's
    move goes to the start 0 whatever the model's row of 2 says: a reward every 3
    decisions (t = 1, 4, 7, 10), 4 in 12."""
    _, tele = _run(experts, TASK, Protocol().loop_rules(-1, 0))
    np.testing.assert_array_equal(tele.s, [0, 1] * 6)
    assert tele.reward.sum() == 6 and not np.any(tele.s == 2)
    T = ring()
    T[2, :, 3] = 1.0  # the goal's own row leads to the trap: the reset ignores it
    T[2, :, 0] = 0.0
    rules = Protocol(reset="goal-decision").loop_rules(-1, 0)
    _, pub = _run(experts, TASK, rules, T=T)
    np.testing.assert_array_equal(pub.s, [0, 1, 2] * 4)
    np.testing.assert_array_equal(np.flatnonzero(pub.reward), [1, 4, 7, 10])
    assert np.all(pub.s_next[pub.s == 2] == 0) and np.all(pub.reward[pub.s == 2] == 0)


@pytest.mark.parametrize("reset", ["teleport", "goal-decision"])
def test_the_decision_at_the_change_pays_nothing(experts, reset) -> None:
    """Published: the reward of the decision at the change index is forced to 0, with or
    without a change; the robot that arrived in the goal still restarts from it."""
    hit = 3 if reset == "teleport" else 4  # a rewarded decision of each reset
    pays = Protocol(reset=reset).loop_rules(hit, 0)
    silent = Protocol(reset=reset, change_pays=False).loop_rules(hit, 0)
    _, a = _run(experts, TASK, pays)
    _, b = _run(experts, TASK, silent)
    assert a.reward[hit] == 1.0 and b.reward[hit] == 0.0
    np.testing.assert_array_equal(np.delete(a.reward, hit), np.delete(b.reward, hit))
    np.testing.assert_array_equal(a.s, b.s)  # the run goes on as if it had paid
    if reset == "goal-decision":
        assert b.s[hit + 1] == 2 and b.s_next[hit + 1] == 0


def test_the_first_state_is_the_first_start_state_or_drawn(experts) -> None:
    task = OnlineTask(goal=(2,), start_states=(1, 0))
    firsts = {int(_run(experts, task, Protocol(first_state="first").loop_rules(-1, 1),
                       n=1, seed=k)[1].s[0]) for k in range(6)}
    drawn = {int(_run(experts, task, Protocol().loop_rules(-1, 1), n=1, seed=k)[1].s[0])
             for k in range(12)}
    assert firsts == {1} and drawn == {0, 1}


def test_the_phantom_start_is_learned_before_the_first_decision(experts) -> None:
    """Published: the run's "previous decision" is (s0, action 0, reward 0, s0): MF's
    Q(0, 0) = q0 + 0.6 (0 + 0.9 q0 - q0) = 0.94 q0, MB knows (0, 0) -> 0, and 0 counts as
    visited (no first-visit plan of the other expert there)."""
    rules = Protocol(phantom_start=True, first_state="first").loop_rules(-1, 0)
    ag, _ = _run(experts, TASK, rules, n=0)
    assert ag.mf.Q[0, 0] == pytest.approx(0.94 * Q0) and ag.mf.Q[0, 1] == Q0
    assert ag.mb.model.n_sa[0, 0] == 1 and ag.mb.model.n_sa.sum() == 1
    assert ag.seen[0] and not ag.seen[1:].any()
    ag, _ = _run(experts, TASK, Protocol(first_state="first").loop_rules(-1, 0), n=0)
    assert np.all(ag.mf.Q == Q0) and ag.mb.model.n_sa.sum() == 0 and not ag.seen.any()


def test_a_run_without_reward_restarts_with_its_experts_kept(experts) -> None:
    """No reward can come (the goal 3 is the unreachable trap): every 5 decisions the run
    starts again from its first state, at most MAX_RESTARTS times; the experts keep
    learning across restarts (MB has counted every transition), the first-visit memory is
    cleared, and the log holds the last attempt."""
    task = OnlineTask(goal=(3,), start_states=(0,))
    rules = Protocol(restart_after=5, first_state="first").loop_rules(-1, 0)
    ag, log = _run(experts, task, rules, n=12, criterion="entropy")
    assert log.restarts == MAX_RESTARTS and log.reward.sum() == 0
    assert ag.mb.model.n_sa.sum() == MAX_RESTARTS * 5 + 12
    np.testing.assert_array_equal(log.s, [0, 1, 2] * 4)
    _, ok = _run(experts, TASK, rules, n=12)  # a reward in time: no restart
    assert ok.restarts == 0 and ok.reward.sum() == 6


# ------------------------------------------------------------------ changes and choices
def test_after_swaps_the_model_at_the_change(experts) -> None:
    """From decision 4 on the world is the other model (0 leads to the trap): the
    decisions before it follow the ring, the one at 4 (in 0) falls in the trap."""
    task = OnlineTask(goal=(2,), start_states=(0,),
                      changes=(Change(4, "model", after=(trap_from(0),)),))
    _, log = _run(experts, task, None)
    np.testing.assert_array_equal(log.s_next[:4], [1, 2, 1, 2])
    np.testing.assert_array_equal(log.s_next[4:], 3)
    np.testing.assert_array_equal(log.phase, [0] * 4 + [1] * 8)


@pytest.mark.parametrize(("use_states", "after", "chosen"), [
    ((3, 0), ("ring", "trap"), 1),  # state 0 saw 2 decisions, the trap 3 none: the second
    ((0, 1), ("trap", "ring"), 0),  # 2 and 2: a tie goes to the first listed
    ((1, 0), ("ring", "trap"), 0),  # a tie again: the first listed, whatever its state
])
def test_the_more_used_alternative_happens(experts, use_states, after, chosen) -> None:
    """Teleport on the ring: decisions in 0, 1, 0, 1 before the change at 4."""
    models = {"ring": ring(), "trap": trap_from(0)}
    task = OnlineTask(goal=(2,), start_states=(0,), changes=(
        Change(4, "model", after=tuple(models[k] for k in after), use_states=use_states),))
    _, log = _run(experts, task, None)
    assert np.all(log.phase[4:] == 1 + chosen)
    counts = {0: 2, 1: 2, 3: 0}
    np.testing.assert_array_equal(log.use_counts, [-1] + [counts[u] for u in use_states])
    assert (log.s_next[4] == 3) == (after[chosen] == "trap")


def test_passages_by_use_close_only_the_more_used(experts) -> None:
    """The ring's passages 0-1 and 1-2, counted in 0 and 1 (2 and 2: a tie, the first
    listed closes): 0 -> 1 is closed, 1 -> 2 stays open; all at once closes both."""
    by_use = Change(4, "passages", passages=((0, 1), (1, 2)), use_states=(0, 1))
    _, log = _run(experts, OnlineTask(goal=(2,), start_states=(0,), changes=(by_use,)), None)
    assert np.all(log.s[4:] == 0) and np.all(log.s_next[4:] == 0)  # stuck in 0
    T = ring()
    T[0, 1] = 0.0
    T[0, 1, 2] = 1.0  # from 0, action 1 jumps to 2 (over the passage 0-1)
    _, jump = _run(experts, OnlineTask(goal=(2,), start_states=(0,), changes=(by_use,)),
                   None, T=T, n=40)
    assert jump.reward[4:].sum() > 0  # 1-2 is still open: 2 is reached past 0-1
    both = Change(4, "passages", passages=((0, 1), (1, 2)))
    c = OnlineTask(goal=(2,), start_states=(0,), changes=(both,)).compile(T)
    assert c.cdf.shape[0] == 2 and np.all(c.use_state == -1)


def test_alternatives_are_checked() -> None:
    T = ring()
    with pytest.raises(ConfigError, match="counting state"):
        Change(4, "model", after=(T, T))  # two models and no way to choose
    with pytest.raises(ConfigError, match="3 counting states for 2"):
        Change(4, "model", after=(T, T), use_states=(1, 2, 3))
    with pytest.raises(ConfigError, match="only a model change"):
        Change(4, "goal", goal=(1,), after=(T, T), use_states=(1, 2))
    with pytest.raises(ConfigError, match=r"5 states x 2 actions, the run.s 4 x 2"):
        OnlineTask(goal=(2,), start_states=(0,), changes=(
            Change(4, "model", after=(np.ones((5, 2, 5)) / 5,)),)).compile(T)


def test_a_start_state_that_is_a_goal_is_refused() -> None:
    """Else a reward restarts the run in the goal and every decision that stays pays."""
    with pytest.raises(ConfigError, match=r"start_states.*\[2\].*standing still"):
        OnlineTask(goal=(2,), start_states=(0, 2))
    with pytest.raises(ConfigError, match=r"start_states.*\[0\].*new goal"):
        OnlineTask(goal=(2,), start_states=(0,), changes=(Change(5, "goal", goal=(0,)),))


# ------------------------------------------------------------------------ agent's rules
def test_values_are_zeroed_at_first_pay_and_the_goals_moves_forgotten(experts) -> None:
    """State 2 is left twice (MB knows its moves), then pays: both experts' values of 2 are
    0, and with forget_goal_moves MB's model of 2 is emptied, so a plan keeps V(2) = 0;
    without it the plan values 2 again at gamma V(0). The same happens again when the new
    goal 3, left before, first pays."""
    mf, mb = experts
    for forget in (True, False):
        ag = meta.make_meta_agent(mf, mb, 4, 2, meta.Arbitration(forget_goal_moves=forget))
        for s, s2 in ((2, 0), (2, 0), (3, 0), (0, 1)):
            meta.learn(ag, s, 0, 0.0, s2)
        meta.learn(ag, 1, 1, 1.0, 2)  # 2 pays for the first time
        assert np.all(ag.mf.Q[2] == 0.0) and np.all(ag.mb.Q[2] == 0.0)
        meta.expert_plan(ag.mb, ag.valid)
        assert (ag.mb.model.n_sa[2].sum() == 0) == forget
        assert ag.mb.Q[2, 0] == (0.0 if forget else pytest.approx(0.9 * ag.mb.Q[0].max(), abs=1e-3))
        meta.learn(ag, 0, 1, 1.0, 3)  # the new goal 3 first pays
        meta.expert_plan(ag.mb, ag.valid)
        assert np.all(ag.mf.Q[3] == 0.0)
        assert (ag.mb.Q[3, 0] == 0.0) == forget and (ag.mb.model.n_sa[3].sum() == 0) == forget
    np.testing.assert_array_equal(ag.paid, [False, False, True, True])


@pytest.mark.parametrize("mb_name", ["sliding-window", "vi-softmax"])
def test_forgotten_moves_are_learned_afresh(mb_name) -> None:
    from simlab.agents.kernels import model_reward
    from simlab.agents.registry import agent_config

    mf = agent_config("q-softmax", {"q_init": Q0})
    mb = agent_config(mb_name, {"q_init": Q0, "plan_every": 0})
    ag = meta.make_meta_agent(mf, mb, 4, 2, meta.Arbitration(forget_goal_moves=True))
    meta.learn(ag, 2, 0, 0.0, 0)
    meta.learn(ag, 1, 1, 1.0, 2)
    assert ag.mb.model.n_sa[2, 0] == 0 and model_reward(ag.mb.model, 2, 0) == 0.0
    meta.learn(ag, 0, 1, 0.0, 1)
    meta.learn(ag, 2, 0, 0.0, 3)  # left again (the goal moved): a fresh model of (2, 0)
    T = np.zeros(4)
    from simlab.agents.kernels import model_transition_row

    model_transition_row(ag.mb.model, 2, 0, T)
    np.testing.assert_array_equal(T, [0, 0, 0, 1])


@pytest.mark.parametrize("learn_from_goal", [False, True])
def test_no_learning_from_the_rewarded_state(experts, learn_from_goal) -> None:
    """The move that starts where a reward was just obtained (the published reset's) is not
    learned by either expert; the next one, or one starting elsewhere, is."""
    mf, mb = experts
    ag = meta.make_meta_agent(mf, mb, 4, 2, meta.Arbitration(learn_from_goal=learn_from_goal))
    meta.learn(ag, 1, 1, 1.0, 2)
    meta.learn(ag, 2, 0, 0.0, 0)  # the reset's move, from the goal
    assert (ag.mf.Q[2, 0] == 0.0) != learn_from_goal
    assert ag.mb.model.n_sa[2, 0] == int(learn_from_goal)
    meta.learn(ag, 0, 1, 0.0, 1)
    assert ag.mb.model.n_sa[0, 1] == 1 and ag.mf.Q[0, 1] != Q0
    # after a reward, a transition that starts elsewhere (simlab's teleport) is learned
    meta.learn(ag, 1, 1, 1.0, 2)
    meta.learn(ag, 0, 0, 0.0, 1)
    assert ag.mb.model.n_sa[0, 0] == 1


@pytest.mark.parametrize("criterion", ["entropy", "entropy_and_cost"])
def test_ties_of_the_entropy_criteria_can_be_a_coin(criterion) -> None:
    code = meta.criterion_code(criterion)
    rng = np.random.default_rng(5)
    picks = [meta.choose_expert(code, 0.5, 0.5, 0.0, 0.0, 1.0, 3.0, rng, True)
             for _ in range(2000)]
    expect = np.random.default_rng(5).random(2000) < 0.5  # one draw per tie, MB below 0.5
    np.testing.assert_array_equal(np.array(picks) == meta.EXPERT_MB, expect)
    rng = np.random.default_rng(5)
    assert meta.choose_expert(code, 0.5, 0.5, 0.0, 0.0, 1.0, 3.0, rng) == meta.EXPERT_MF
    assert meta.choose_expert(code, 0.6, 0.5, 0.0, 0.0, 1.0, 3.0, rng, True) == meta.EXPERT_MB
    assert rng.random() == np.random.default_rng(5).random()  # no draw without a tie


# ------------------------------------------------------------------------ whole runs
@pytest.mark.parametrize("criterion", ["random", "entropy_and_cost"])
def test_published_runs_are_deterministic_by_seed(experts, criterion) -> None:
    from .conftest import chain

    T = chain(6, p=0.7)
    task = OnlineTask(goal=(5,), start_states=(1, 2), changes=(
        Change(150, "model", after=(chain(6, 0.9), chain(6, 0.5)), use_states=(3, 4)),))
    rules = PROTOCOLS["published"].loop_rules(150, 1)
    arb = dict(ties="random", forget_goal_moves=True)
    _, a = _run(experts, task, rules, n=300, criterion=criterion, seed=4, T=T, **arb)
    _, b = _run(experts, task, rules, n=300, criterion=criterion, seed=4, T=T, **arb)
    _, c = _run(experts, task, rules, n=300, criterion=criterion, seed=5, T=T, **arb)
    for col, x in a.columns().items():
        if col != "seconds":
            np.testing.assert_array_equal(x, b.columns()[col], err_msg=col)
    np.testing.assert_array_equal(a.use_counts, b.use_counts)
    assert not np.array_equal(a.s, c.s)


@pytest.mark.parametrize("mb_name", ["sliding-window", "vi-softmax"])
def test_the_goals_reward_counts_for_the_moves_once_rewarded_into_it(mb_name) -> None:
    """Published: MB's reward of arriving in a goal counts only for the moves (pairs) through
    which a reward was obtained there; simlab: for every move that reached it. (0, 1) and
    (3, 1) both reached 1 before 1 paid; then 1 pays through (0, 1)."""
    from simlab.agents.kernels import model_reward
    from simlab.agents.registry import agent_config

    mf = agent_config("q-softmax", {"q_init": Q0})
    mb = agent_config(mb_name, {"q_init": Q0, "plan_every": 0})
    for links in (True, False):
        ag = meta.make_meta_agent(mf, mb, 4, 2, meta.Arbitration(reward_links=links,
                                                                 reward_ends=False))
        meta.learn(ag, 0, 1, 0.0, 1)
        meta.learn(ag, 3, 1, 0.0, 1)
        meta.learn(ag, 0, 1, 1.0, 1)  # 1 pays, through (0, 1)
        assert model_reward(ag.mb.model, 0, 1) == 1.0  # both its arrivals in 1 now pay
        assert model_reward(ag.mb.model, 3, 1) == (0.0 if links else 1.0)
        meta.learn(ag, 3, 1, 1.0, 1)  # now (3, 1) too
        assert model_reward(ag.mb.model, 3, 1) == 1.0
        meta.learn(ag, 0, 1, 0.0, 1)  # the goal stopped paying: every linked move forgets it
        assert model_reward(ag.mb.model, 0, 1) == 0.0 and model_reward(ag.mb.model, 3, 1) == 0.0
        if links:
            np.testing.assert_array_equal(ag.link[[0, 3], 1], [1, 1])
            assert (ag.link == -1).sum() == 6
