"""Save/load of Q-tables, models and agents: npz without pickle, atomic, no overwrite."""

from __future__ import annotations

import zipfile

import numpy as np
import pytest

from simlab.agents import (
    AGENTS,
    CountModel,
    WindowModel,
    load_agent,
    load_model,
    load_q_table,
    make_agent,
    save_agent,
    save_model,
    save_q_table,
)
from simlab.agents import kernels as K
from simlab.errors import ConfigError, DataError


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
    with pytest.raises(DataError, match="not a readable npz"):
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
