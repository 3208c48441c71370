"""The online loop: MF learning from MB's decisions, changes mid-run, determinism."""

from __future__ import annotations

import numpy as np
import pytest

from simlab.agents import core
from simlab.base.errors import ConfigError
from simlab.online import meta
from simlab.online.loop import run_online
from simlab.online.task import Change, OnlineTask, close_passages, parse_passages

from .conftest import chain


def _run(experts, T, task, criterion="mb", n=400, seed=0, **kw):
    mf, mb = experts
    valid = kw.pop("valid", None)
    ag = meta.make_meta_agent(mf, mb, T.shape[0], T.shape[1],
                              meta.Arbitration(criterion=criterion, **kw), valid=valid)
    ss = np.random.SeedSequence(seed).spawn(2)
    log = run_online(ag, task.compile(T), n, np.random.default_rng(ss[0]),
                     np.random.default_rng(ss[1]))
    return ag, log


def test_mf_learns_from_mb_decisions_as_a_passive_observer(experts) -> None:
    """Criterion mb: MB decides every time, MF's table is exactly Q-learning replayed on
    the logged transitions (the thesis's passive observer), and its greedy policy is the
    optimal one of the chain."""
    T = chain(6)
    ag, log = _run(experts, T, OnlineTask(goal=(5,), start_states=(0,)), n=600)
    assert np.all(log.expert == meta.EXPERT_MB)
    Q = np.full((6, 2), 1 / 1.9)  # the MF expert's q_init
    for s, a, r, s2 in zip(log.s, log.a, log.reward, log.s_next, strict=True):
        Q[s, a] += 0.6 * (r + 0.9 * Q[s2].max() - Q[s, a])
        if r > 0:
            Q[s2] = 0.0  # a reward ends the episode: the goal's values are reset
    np.testing.assert_allclose(ag.mf.Q, Q, rtol=0, atol=1e-12)
    assert np.all(ag.mf.Q[:5].argmax(axis=1) == 1)  # go right, towards the goal
    assert log.reward.sum() > 0.8 * 600 / 5  # MB heads for the goal: ~5 decisions a reward


def test_goal_change_moves_the_reward_and_restart(experts) -> None:
    T = chain(6)
    task = OnlineTask(goal=(5,), start_states=(2,), changes=(Change(200, "goal", goal=(0,)),))
    _, log = _run(experts, T, task, criterion="entropy_and_cost", n=500)
    assert np.all(log.phase[:200] == 0) and np.all(log.phase[200:] == 1)
    hit = log.reward > 0
    assert np.all(log.s_next[hit & (log.phase == 0)] == 5)
    assert np.all(log.s_next[hit & (log.phase == 1)] == 0)
    assert hit[:200].any() and hit[200:].any()  # both goals found
    after_reward = np.flatnonzero(hit[:-1]) + 1
    assert np.all(log.s[after_reward] == 2)  # a reward restarts from the start state
    free = np.flatnonzero(~hit[:-1])
    np.testing.assert_array_equal(log.s[free + 1], log.s_next[free])


def test_closed_passages_are_never_crossed_and_rows_stay_distributions(experts) -> None:
    T = chain(6, p=0.8)
    closed = close_passages(T, [(2, 3)])
    np.testing.assert_allclose(closed.sum(axis=2), 1.0)
    assert np.all(closed[2, :, 3] == 0) and np.all(closed[3, :, 2] == 0)
    assert closed[2, 1, 2] == pytest.approx(1.0)  # the blocked move's other outcome: stay
    # hand-worked: a row with outcomes 3 (0.5), 1 (0.3), 2 (0.2) loses 3 and keeps the
    # others in proportion, 0.6 and 0.4; a row whose only outcome was 3 stays put
    T2 = np.zeros((4, 2, 4))
    T2[2, 0, [3, 1, 2]] = (0.5, 0.3, 0.2)
    T2[2, 1, 3] = 1.0
    T2[[0, 1, 3], :, 0] = 1.0
    c2 = close_passages(T2, [(2, 3)])
    np.testing.assert_allclose(c2[2, 0], [0.0, 0.6, 0.4, 0.0])
    np.testing.assert_allclose(c2[2, 1], [0.0, 0.0, 1.0, 0.0])
    np.testing.assert_array_equal(np.delete(closed, [2, 3], axis=0), np.delete(T, [2, 3], 0))
    # the goal (5) is beyond the passage: rewards stop once it closes
    task = OnlineTask(goal=(5,), start_states=(0,),
                      changes=(Change(300, "passages", passages=((2, 3),)),))
    _, log = _run(experts, T, task, n=700)
    crossed = ((log.s == 2) & (log.s_next == 3)) | ((log.s == 3) & (log.s_next == 2))
    assert crossed[:300].any() and not crossed[300:].any()
    # after the last reward restart the robot is trapped on the left: no reward later on
    assert log.reward[400:].sum() == 0


def test_passage_parsing() -> None:
    assert parse_passages(["20-21", "6<->7", [1, 2]]) == ((20, 21), (6, 7), (1, 2))
    for bad in ("20", "a-b", "3-3"):
        with pytest.raises(ConfigError, match="passage"):
            parse_passages([bad])


def test_task_states_are_checked_naming_the_field() -> None:
    T = chain(4)
    with pytest.raises(ConfigError, match=r"new_goal.*states \[9\]"):
        OnlineTask(goal=(3,), start_states=(0,),
                   changes=(Change(5, "goal", goal=(9,)),)).compile(T, source="m.npz")
    with pytest.raises(ConfigError, match="start_states"):
        OnlineTask(goal=(3,), start_states=(4,)).compile(T)
    with pytest.raises(ConfigError, match="change_at"):
        Change(0, "goal", goal=(1,))


@pytest.mark.parametrize("criterion", ["random", "entropy", "entropy_and_cost"])
def test_seeded_runs_are_bit_identical(experts, criterion) -> None:
    T = chain(6, p=0.7)
    task = OnlineTask(goal=(5,), start_states=(1, 2), changes=(Change(150, "goal", goal=(0,)),))
    _, a = _run(experts, T, task, criterion=criterion, n=300, seed=4)
    _, b = _run(experts, T, task, criterion=criterion, n=300, seed=4)
    _, c = _run(experts, T, task, criterion=criterion, n=300, seed=5)
    for col, x in a.columns().items():
        if col != "seconds":  # the wall clock is recorded, never decided on by default
            np.testing.assert_array_equal(x, b.columns()[col], err_msg=col)
    assert not np.array_equal(a.s, c.s)
    assert np.all(a.seconds >= 0)


def test_valid_mask_limits_actions_and_entropies(experts) -> None:
    T = np.zeros((3, 3, 3))
    T[:, :, :] = np.eye(3)[:, None, :]  # every action stays ...
    T[0, 2] = np.eye(3)[1]
    T[1, 2] = np.eye(3)[2]  # ... but action 2 moves right
    valid = np.ones((3, 3), dtype=bool)
    valid[:, 0] = False
    _, log = _run(experts, T, OnlineTask(goal=(2,), start_states=(0,)), criterion="random",
                  n=200, valid=valid)
    assert not np.any(log.a == 0)
    assert core.as_mask(valid, 3, 3).shape == (3, 3)


def test_an_arm_draws_the_same_streams_whatever_runs_beside_it() -> None:
    """Common random numbers, in one process too: the seed of run i is shared by every
    arm's job, and an arm's results do not depend on the arms run before it."""
    from simlab.data.mdp import mdp_from_arrays
    from simlab.online.command import OnlineConfig, online

    m = mdp_from_arrays(chain(6, p=0.7))
    common = dict(mdp=m, goal=(5,), start_states=(0,), decisions=150, seeds=2, workers=1,
                  progress=False, plots=False)
    both = online(OnlineConfig(criteria=("mb", "entropy_and_cost"), **common)).logs
    alone = online(OnlineConfig(criteria=("entropy_and_cost",), **common)).logs
    for a, b in zip(both["entropy_and_cost_k1"], alone["entropy_and_cost_k1"], strict=True):
        np.testing.assert_array_equal(a["s"], b["s"])
        np.testing.assert_array_equal(a["expert"], b["expert"])
    # and the two arms of one run start in the same state (the same environment stream)
    assert both["mb"][0]["s"][0] == both["entropy_and_cost_k1"][0]["s"][0]


def test_the_reward_band_of_the_figure_stays_at_or_above_zero(monkeypatch) -> None:
    """Cumulative rewards are >= 0: a run that earned nothing beside one that earned much
    has mean - std < 0, and the band is clipped there."""
    from matplotlib.axes import Axes

    from simlab.online.report import _figures

    lows = []
    real = Axes.fill_between

    def spy(self, x, y1, *args, **kwargs):
        lows.append(np.min(y1))
        return real(self, x, y1, *args, **kwargs)

    monkeypatch.setattr(Axes, "fill_between", spy)
    n = 50
    rich = np.zeros(n)
    rich[::2] = 1.0
    runs = [dict(reward=rich, backups=np.ones(n), expert=np.ones(n)),
            *[dict(reward=np.zeros(n), backups=np.ones(n), expert=np.ones(n))] * 3]
    summary = {"task": {"changes": []}}
    _figures({"mb": runs}, summary, 10)
    assert len(lows) == 2 and min(lows) == 0.0
