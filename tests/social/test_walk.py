"""The social random walk as a dataset (issue 18, part 2): determinism, decoding, T rows."""

from __future__ import annotations

import numpy as np
import pytest

from simlab.data.dataset import open_dataset
from simlab.data.estimate import count_transitions, transition_matrix
from simlab.social.actions import N_SOCIAL_ACTIONS
from simlab.social.walk import (
    ACTION_NAMES,
    N_SOCIAL_STATES,
    SocialStates,
    WalkConfig,
    decode_social,
    social_walk,
    write_social_dataset,
)

CFG = WalkConfig(steps=60, episode_steps=20, workers=2, seed=11)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    out = tmp_path_factory.mktemp("social") / "ds"
    result, walks = write_social_dataset(out, CFG, part_size=25)
    return out, result, walks


def test_same_seed_same_dataset(dataset, tmp_path):
    out, _, _ = dataset
    write_social_dataset(tmp_path / "again", CFG, part_size=25)
    a, b = open_dataset(out).table, open_dataset(tmp_path / "again").table
    assert a.equals(b)
    other = social_walk(WalkConfig(steps=60, episode_steps=20, workers=2, seed=12))
    assert not np.array_equal(other[0].a, a.column("a").to_numpy()[:60])


def test_manifest_records_social_states_and_22_actions(dataset):
    out, result, _ = dataset
    ds = open_dataset(out)
    assert ds.n_states == N_SOCIAL_STATES == 2560
    assert ds.n_actions == N_SOCIAL_ACTIONS == 22
    assert ds.action_set is None and ds.action_names == ACTION_NAMES
    assert ds.discretizer_hash == SocialStates().content_hash()
    assert result.rows == len(ds.table) == 120
    assert ds.manifest["parameters"]["state_space"] == "social"


def test_states_decode_to_valid_social_tuples(dataset):
    out, _, walks = dataset
    ds = open_dataset(out)
    for col in ("s", "s_next"):
        d = decode_social(ds.column(col))
        assert d.shape == (120, 4)
        assert np.all((d >= 0) & (d < np.array([8, 5, 8, 8])))
    # the walk's own rows and the dataset's agree; a step continues from the last s'
    w = walks[0]
    np.testing.assert_array_equal(ds.column("s")[:60], w.s)
    same_episode = w.episode[1:] == w.episode[:-1]
    np.testing.assert_array_equal(w.s[1:][same_episode], w.s_next[:-1][same_episode])
    # level 5-7 needs a HELLO first: an episode starts unengaged
    starts = np.r_[True, ~same_episode]
    assert np.all(decode_social(w.s[starts])[:, 0] < 5)
    assert np.all(np.diff(w.t) >= 0) and np.all(w.duration > 0)


def test_decode_inverts_the_index():
    from simlab.social.perception import social_obs_index

    for tup in [(0, 0, 0, 0), (7, 4, 7, 7), (3, 2, 5, 1)]:
        assert tuple(decode_social(social_obs_index(*tup))) == tup
    with pytest.raises(ValueError):
        decode_social(2560)


def test_estimated_rows_sum_to_one_over_visited_pairs(dataset):
    """The estimator's counting and normalisation on the visited sub-space (the full
    2560 x 22 x 2560 table is 1.2 GB; `simlab estimate` builds it, not a unit test)."""
    ds = open_dataset(dataset[0])
    s, a, s2 = ds.column("s"), ds.column("a"), ds.column("s_next")
    seen, idx = np.unique(np.r_[s, s2], return_inverse=True)
    counts = count_transitions(idx[:len(s)], a, idx[len(s):], len(seen), N_SOCIAL_ACTIONS)
    T, visited = transition_matrix(counts)
    assert visited.sum() == len(set(zip(s.tolist(), a.tolist(), strict=True)))
    np.testing.assert_allclose(T[visited].sum(axis=1), 1.0, atol=1e-12)
    assert counts.sum() == len(s)


def test_bad_walk_config():
    from simlab.base.errors import ConfigError

    with pytest.raises(ConfigError):
        WalkConfig(steps=0)


def test_sparse_model_matches_the_dense_estimator():
    from simlab.data.estimate import entropy_bits, mean_entropy_per_action
    from simlab.social.compare import sparse_from_counts, sparse_model

    rng = np.random.default_rng(0)
    S, A = 6, 4
    s, a, s2 = rng.integers(0, S, 300), rng.integers(0, A, 300), rng.integers(0, S, 300)
    s2[s == 0] = 5  # deterministic rows, and ties elsewhere are likely
    counts = count_transitions(s, a, s2, S, A)
    T, visited = transition_matrix(counts)
    m = sparse_model(s, a, s2, n_states=S, n_actions=A)
    np.testing.assert_array_equal(m.pairs, np.flatnonzero(visited.ravel()))
    np.testing.assert_array_equal(m.mode, T.reshape(S * A, S).argmax(axis=1)[m.pairs])
    np.testing.assert_allclose(m.entropy, entropy_bits(T).ravel()[m.pairs], atol=1e-12)
    np.testing.assert_allclose(m.mean_entropy_per_action(),
                               mean_entropy_per_action(entropy_bits(T), visited), atol=1e-12)
    np.testing.assert_allclose(m.coverage_per_state(), visited.mean(axis=1))
    assert np.array_equal(sparse_from_counts(counts).mode, m.mode)


def test_compare_with_itself_and_the_grid(dataset, tmp_path):
    from simlab.social.compare import compare, grid_walk, plot_comparison, sparse_model

    ds = open_dataset(dataset[0])
    phys = sparse_model(ds.column("s"), ds.column("a"), ds.column("s_next"))
    same = compare(phys, phys)
    assert same.agreement == 1.0 and same.common_pairs == len(phys.pairs)
    np.testing.assert_array_equal(same.coverage[0], same.coverage[1])
    g1, g2 = grid_walk(200, 4), grid_walk(200, 4)
    for x, y in zip(g1, g2, strict=True):
        np.testing.assert_array_equal(x, y)
    assert np.all(decode_social(g1[0])[:, 0] <= 7) and g1[1].max() < 22
    r = compare(phys, sparse_model(*g1))
    assert r.coverage.shape == (2, 2560) and r.entropy.shape == (2, 22)
    assert r.visited_pairs == (len(phys.pairs), len(sparse_model(*g1).pairs))
    assert plot_comparison(r, tmp_path / "cmp.png").stat().st_size > 0
    from simlab.social.compare import comparison_figure

    fig = comparison_figure(r)
    maps, bars = fig.axes[:2], fig.axes[2:4]
    colour_bars = fig.axes[4:]
    assert len(colour_bars) == 2
    assert all("share of the actions" in c.get_ylabel() for c in colour_bars)
    assert all("(" in ax.get_xlabel() and "(" in ax.get_ylabel() for ax in maps + bars)
    assert "(bits)" in bars[0].get_ylabel() and bars[0].get_legend() is not None


class _TinyStates:
    """Four states, for datasets of named actions small enough to estimate densely."""

    n_states = 4
    centres = np.zeros((4, 2))

    def state_of(self, xy):
        raise ValueError("not used")

    def content_hash(self):
        return "tiny-states"


def test_estimate_reads_a_dataset_of_named_actions(tmp_path):
    import json

    from simlab.base.errors import ConfigError
    from simlab.data.estimate import EstimateConfig, estimate
    from simlab.data.mdp import load_mdp
    from simlab.data.writer import DatasetInfo, TransitionArrays, write_dataset

    with pytest.raises(ConfigError, match="action_names"):
        DatasetInfo(discretizer=_TinyStates(), action_names=("a", "a"))
    s, a, s2 = np.array([0, 0, 1, 2, 3, 0]), np.array([2, 2, 0, 1, 2, 2]), \
        np.array([1, 2, 2, 3, 0, 1])
    walk = TransitionArrays(t=np.arange(6.0), a=a, pose=np.zeros((6, 3)),
                            pose_next=np.zeros((6, 3)), blocked=np.zeros(6, bool),
                            duration=np.ones(6), s=s, s_next=s2)
    info = DatasetInfo(discretizer=_TinyStates(), action_names=("x", "y", "z"))
    write_dataset(tmp_path / "ds", walk, info)
    with pytest.raises(ConfigError, match="outside"):
        write_dataset(tmp_path / "bad", TransitionArrays(
            t=[0.0], a=[3], pose=np.zeros((1, 3)), pose_next=np.zeros((1, 3)),
            blocked=[False], duration=[1.0], s=[0], s_next=[0]), info)
    res = estimate(EstimateConfig(dataset=tmp_path / "ds", out=tmp_path / "mdp.npz",
                                  plot=False))
    assert res.summary["action_set"] is None and res.summary["n_actions"] == 3
    mdp = load_mdp(tmp_path / "mdp.npz")
    assert mdp.action_set is None and mdp.T.shape == (4, 3, 4)
    np.testing.assert_allclose(mdp.T[0, 2], [0, 2 / 3, 1 / 3, 0])
    assert json.loads((tmp_path / "ds" / "_manifest.json").read_text())["action_set"] is None
