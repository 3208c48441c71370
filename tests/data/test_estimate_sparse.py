"""The sparse estimate path (issue 18): the same model as the dense path on small MDPs
(T, entropy, coverage, masks, R to 1e-12), its ``mdp.npz`` read by both loaders, and
memory that grows with the observed triples, not with S * A * S."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.data.estimate import (
    SPARSE_CELLS,
    SparseCountModel,
    coverage_report,
    empirical_mdp,
    estimate,
    sparse_count_model,
    sparse_from_dense_counts,
    use_sparse,
    valid_actions,
)
from simlab.data.mdp import load_mdp, load_sparse_mdp


def _random_log(seed: int, n: int, S: int, A: int) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    s = rng.integers(0, S, n)
    a = rng.integers(0, A, n)
    s2 = (s + rng.integers(-2, 3, n)) % S  # a few successors per pair, many pairs unvisited
    return s, a, s2


def _assert_same(sp: SparseCountModel, dense) -> None:
    np.testing.assert_allclose(sp.dense_T(), dense.T, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(sp.visited, dense.visited)
    np.testing.assert_allclose(sp.entropy, dense.entropy, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(sp.n_sa, dense.n_sa)
    np.testing.assert_allclose(sp.mean_entropy, dense.mean_entropy, rtol=0, atol=1e-12,
                               equal_nan=True)
    assert sp.coverage == dense.coverage
    assert coverage_report(sp) == coverage_report(dense)
    np.testing.assert_array_equal(valid_actions(sp.visited), valid_actions(dense.visited))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_sparse_model_equals_the_dense_one(seed: int) -> None:
    S, A = 30, 16
    s, a, s2 = _random_log(seed, 400, S, A)
    from simlab.data.estimate import count_transitions

    dense = empirical_mdp(count_transitions(s, a, s2, S, A))
    sp = sparse_count_model(s, a, s2, S, A)
    assert (~dense.visited).any()  # the self-loop rule is exercised
    _assert_same(sp, dense)
    _assert_same(sparse_from_dense_counts(dense.counts), dense)
    masks = np.random.default_rng(seed).random((3, S)) < 0.3
    np.testing.assert_allclose(sp.rewards(masks), dense.rewards(masks), rtol=0, atol=1e-12)
    # memory: one entry per distinct observed triple, one self-loop per unvisited pair
    distinct = np.unique((s * A + a) * S + s2).size
    assert sp.nnz == distinct + int((~dense.visited).sum())
    assert sp.indptr.shape == (S * A + 1,)
    assert sp.indices.shape == sp.counts.shape == sp.probabilities.shape == (sp.nnz,)


def test_sparse_memory_is_bounded_by_the_log_not_by_sxaxs() -> None:
    # the social task's size: a dense table would be 2560 * 22 * 2560 * 8 B = 1.15 GB
    S, A = 2560, 22
    s, a, s2 = _random_log(3, 4000, S, A)
    sp = sparse_count_model(s, a, s2, S, A)
    stored = sum(x.nbytes for x in (sp.indptr, sp.indices, sp.counts, sp.probabilities,
                                    sp.visited, sp.entropy))
    assert sp.nnz <= 4000 + S * A
    assert stored <= 40 * (4000 + S * A) + 8 * (S * A + 1)
    assert stored < 8 * S * A * S / 100
    assert sp.transitions == 4000
    np.testing.assert_allclose(np.add.reduceat(sp.probabilities, sp.indptr[:-1]), 1.0,
                               rtol=0, atol=1e-12)


def test_storage_choice() -> None:
    assert not use_sparse(25, 16)  # 10,000 cells
    assert use_sparse(2560, 22)  # 144 million cells
    assert use_sparse(25, 16, "sparse") and not use_sparse(2560, 22, "dense")
    assert SPARSE_CELLS == 20_000_000
    with pytest.raises(ConfigError, match="storage"):
        use_sparse(2, 2, "csr")


def test_estimate_sparse_file_matches_the_dense_file(tmp_path: Path,
                                                     kinematic_dataset: Path) -> None:
    dense = estimate(kinematic_dataset, tmp_path / "dense.npz", plot=False)
    sparse = estimate(kinematic_dataset, tmp_path / "sparse.npz", plot=False,
                      storage="sparse")
    assert isinstance(sparse.mdp, SparseCountModel)
    with np.load(tmp_path / "sparse.npz", allow_pickle=False) as z:
        assert "T" not in z.files and "counts" not in z.files
        assert json.loads(str(z["meta_json"]))["storage"] == "sparse-csr"
        np.testing.assert_allclose(z["R"], np.load(tmp_path / "dense.npz")["R"], atol=1e-12)
    summ_d = json.loads(dense.summary_path.read_text())
    summ_s = json.loads(sparse.summary_path.read_text())
    assert summ_s.pop("storage") == "sparse-csr" and summ_s.pop("stored_entries") > 0
    for d in (summ_d, summ_s):
        d.pop("files")
    assert _close_summaries(summ_s, summ_d)
    # the dense loader densifies a small sparse file; the sparse loader reads it as CSR
    a, b = load_mdp(tmp_path / "dense.npz"), load_mdp(tmp_path / "sparse.npz")
    np.testing.assert_allclose(b.T, a.T, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(b.counts, a.counts)
    np.testing.assert_array_equal(b.goal_masks, a.goal_masks)
    assert b.goal_names == a.goal_names and b.action_set == a.action_set
    np.testing.assert_array_equal(b.valid, a.valid)
    sp = load_sparse_mdp(tmp_path / "sparse.npz")
    np.testing.assert_allclose(sp.dense_T(), a.T, rtol=0, atol=1e-12)
    assert sp.P.shape == (a.n_states * a.n_actions, a.n_states)


def _close_summaries(x: dict, y: dict) -> bool:
    """Equal up to 1e-12 on floats (entropy sums in another order)."""
    if isinstance(x, dict):
        return x.keys() == y.keys() and all(_close_summaries(x[k], y[k]) for k in x)
    if isinstance(x, list):
        return len(x) == len(y) and all(_close_summaries(u, v) for u, v in zip(x, y, strict=True))
    if isinstance(x, float) and isinstance(y, float):
        return abs(x - y) <= 1e-12
    return x == y


def test_a_broken_sparse_file_names_the_array(tmp_path: Path,
                                              kinematic_dataset: Path) -> None:
    estimate(kinematic_dataset, tmp_path / "sparse.npz", plot=False, storage="sparse")
    with np.load(tmp_path / "sparse.npz", allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["probabilities"] = arrays["probabilities"] * 0.5
    np.savez(tmp_path / "bad.npz", **arrays)
    with pytest.raises(ConfigError, match="probabilities"):
        load_sparse_mdp(tmp_path / "bad.npz")
    with pytest.raises(ConfigError, match="storage"):
        estimate(kinematic_dataset, tmp_path / "x.npz", storage="csr")
