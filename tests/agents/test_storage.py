"""Save/load of Q-tables, models and agents: npz without pickle, atomic, no overwrite."""

from __future__ import annotations

import zipfile

import numpy as np
import pytest

from simlab.agents import (
    AGENTS,
    CountModel,
    WindowModel,
    greedy,
    load_agent,
    load_model,
    load_q_table,
    make_agent,
    save_agent,
    save_model,
    save_q_table,
)
from simlab.agents import kernels as K
from simlab.base.errors import ConfigError, DataError


def _drive(agent, rng, steps, S):
    s = 0
    for _ in range(steps):
        a = agent.act(s)
        s2 = int(rng.integers(0, S)) if rng.random() < 0.3 else (s + a) % S
        agent.update(s, a, float(s2 == S - 1), s2)
        s = s2


def test_q_table_round_trip_with_metadata(tmp_path):
    Q = np.random.default_rng(0).normal(size=(5, 3))
    path = save_q_table(tmp_path / "q.npz", Q, metadata={"goal": "g1", "gamma": 0.9},
                        arrays={"Q_runs": np.stack([Q, Q])})  # fmt: skip
    Q2, meta = load_q_table(path)
    np.testing.assert_array_equal(Q2, Q)
    assert meta["goal"] == "g1" and meta["kind"] == "q_table"
    with np.load(path, allow_pickle=False) as data:  # plain arrays only
        assert data["Q_runs"].shape == (2, 5, 3)
        assert data["meta_json"].dtype.kind == "U"


def test_existing_files_are_not_replaced_without_overwrite(tmp_path):
    path = save_q_table(tmp_path / "q.npz", np.zeros((2, 2)))
    with pytest.raises(ConfigError, match="already exists"):
        save_q_table(path, np.ones((2, 2)))
    np.testing.assert_array_equal(load_q_table(path)[0], 0.0)
    save_q_table(path, np.ones((2, 2)), overwrite=True)
    np.testing.assert_array_equal(load_q_table(path)[0], 1.0)
    assert [p.name for p in tmp_path.iterdir()] == ["q.npz"]  # no temporary left


def test_bad_files_give_clear_errors(tmp_path):
    np.savez(tmp_path / "noq.npz", V=np.zeros(3))
    with pytest.raises(ConfigError, match=r"missing array.*Q.*found: V"):
        load_q_table(tmp_path / "noq.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(DataError, match=r"not an npz archive \(a text file"):
        load_q_table(tmp_path / "junk.npz")
    with pytest.raises(ConfigError, match="file not found"):
        load_q_table(tmp_path / "absent.npz")
    obj = np.empty(1, dtype=object)
    obj[0] = {"a": 1}
    np.savez(tmp_path / "pickled.npz", Q=obj)
    with pytest.raises(DataError):  # object arrays need pickle: refused
        load_q_table(tmp_path / "pickled.npz")
    assert zipfile.is_zipfile(tmp_path / "pickled.npz")


@pytest.mark.parametrize("kind", ["count", "window"])
def test_models_round_trip_exactly(tmp_path, kind):
    rng = np.random.default_rng(1)
    S, A = 7, 3
    model = CountModel(S, A, 2) if kind == "count" else WindowModel(S, A, 4, 2)
    for _ in range(500):
        K.model_observe(model, rng.integers(S), rng.integers(A), rng.normal(), rng.integers(S))
    save_model(tmp_path / "m.npz", model)
    back = load_model(tmp_path / "m.npz")
    assert type(back) is type(model)
    T1, R1 = model.transition_matrix()
    T2, R2 = back.transition_matrix()
    np.testing.assert_array_equal(T1, T2)
    np.testing.assert_allclose(R1, R2, rtol=1e-12)
    np.testing.assert_array_equal(back.n_sa, model.n_sa)
    Q1, Q2 = np.zeros((S, A)), np.zeros((S, A))
    K.model_value_iteration(model, Q1, 0.9, 20, 0.0, 1)
    K.model_value_iteration(back, Q2, 0.9, 20, 0.0, 1)
    np.testing.assert_array_equal(Q1, Q2)  # same pair and successor order: same sums


@pytest.mark.parametrize("name", list(AGENTS))
def test_a_loaded_agent_continues_exactly_like_the_original(tmp_path, name):
    S, A = 6, 3
    agent = make_agent(
        name,
        S,
        A,
        np.random.default_rng(2),
        **({"plan_every": 7} if name in ("vi-softmax", "mb-egreedy", "sliding-window") else {}),
    )
    _drive(agent, np.random.default_rng(3), 200, S)
    save_agent(tmp_path / "agent.npz", agent)
    state = agent.rng.bit_generator.state
    clone = load_agent(tmp_path / "agent.npz", np.random.default_rng())
    clone.rng.bit_generator.state = state
    assert clone.name == name
    env_a, env_b = np.random.default_rng(4), np.random.default_rng(4)
    _drive(agent, env_a, 150, S)
    _drive(clone, env_b, 150, S)
    np.testing.assert_array_equal(clone.Q, agent.Q)


# --- the greedy policy carried by Q-table files -----------------------------------------

_Q_HAND = np.array([[1.0, 10.0, 2.0], [10.0, 10.0, 3.0], [5.0, 10.0, 7.0], [4.0, 4.0, 9.0]])
_VALID_HAND = np.array([[True, False, True], [False, False, False], [True, False, True],
                        [True, True, False]])


def test_greedy_skips_untried_actions_on_a_hand_worked_table():
    # column 1 holds the optimistic 10.0 of never-tried pairs; row 1 has no tried action
    # (all allowed, tie to the lowest index); row 3's best tried actions tie: lowest index
    np.testing.assert_array_equal(greedy(_Q_HAND, _VALID_HAND), [2, 0, 2, 0])
    np.testing.assert_array_equal(greedy(_Q_HAND), [1, 0, 1, 2])  # unmasked argmax


def test_greedy_of_a_file_is_the_masked_argmax(tmp_path):
    rng = np.random.default_rng(7)
    S, A = 40, 16
    Q = rng.normal(size=(S, A))
    valid = rng.random((S, A)) < 0.6
    valid[3] = False  # a state with no tried action
    Q[~valid] = 10.0  # optimistic initial values where nothing was tried
    path = save_q_table(tmp_path / "q.npz", Q, arrays={"valid": valid},
                        metadata={"unvisited": "mask"})
    expected = [int(np.flatnonzero(row)[np.argmax(q[row])]) if row.any() else int(np.argmax(q))
                for q, row in zip(Q, valid, strict=True)]
    pi = greedy(path)
    np.testing.assert_array_equal(pi, expected)
    np.testing.assert_array_equal(pi, greedy(str(path)))
    assert pi.dtype == np.int64 and all(valid[s, a] for s, a in enumerate(pi) if s != 3)
    with np.load(path, allow_pickle=False) as data:  # stored: readable without simlab
        np.testing.assert_array_equal(data["greedy"], expected)
    assert (np.argmax(Q, axis=1) != pi).any()  # the plain argmax would differ


def test_greedy_of_older_and_self_loop_files(tmp_path):
    np.savez(tmp_path / "old.npz", Q=_Q_HAND, valid=_VALID_HAND)  # no stored policy
    np.testing.assert_array_equal(greedy(tmp_path / "old.npz"), [2, 0, 2, 0])
    # under the self-loop rule an untried pair is a modelled stay: it may be chosen
    path = save_q_table(tmp_path / "loop.npz", _Q_HAND, arrays={"valid": _VALID_HAND},
                        metadata={"unvisited": "self-loop"})
    np.testing.assert_array_equal(greedy(path), [1, 0, 1, 2])


def test_greedy_refuses_bad_input_with_the_field(tmp_path):
    np.savez(tmp_path / "bad.npz", Q=_Q_HAND, greedy=np.array([0, 1, 5, 0]))
    with pytest.raises(ConfigError, match=r"bad\.npz: greedy: .*0\.\.2"):
        greedy(tmp_path / "bad.npz")
    with pytest.raises(ConfigError, match=r"valid: expected a \(4, 3\) bool mask"):
        greedy(_Q_HAND, np.ones((4, 2), dtype=bool))
    with pytest.raises(ConfigError, match="valid: a Q-table file carries its own mask"):
        greedy(tmp_path / "bad.npz", _VALID_HAND)
    with pytest.raises(ConfigError, match=r"arrays: .*'greedy'"):
        save_q_table(tmp_path / "q.npz", _Q_HAND, arrays={"greedy": np.zeros(4, dtype=int)})
