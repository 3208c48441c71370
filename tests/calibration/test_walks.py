"""A candidate's walk runs in memory: the rows ``collect`` writes, walk by walk on the workers."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from simlab.base.actions import parse_action_set
from simlab.data.backends import make_backend
from simlab.data.collect import CollectConfig, collect, part_states, plan_walks, walk_results
from simlab.data.count_model import count_transitions
from simlab.data.dataset import read_dataset
from simlab.data.walkers import KinematicParams, WalkerCache


def _cfg(states, out, seed: int, **kw) -> CollectConfig:
    return CollectConfig(arena="table", states=states, out=out, transitions=240, seed=seed,
                         simulator="kinematic", params=KinematicParams(), part_size=25,
                         start_states="all", progress=False, **kw)


@pytest.mark.parametrize("workers", [1, 2])
def test_walks_in_memory_are_the_rows_collect_writes(lattice9, tmp_path: Path,
                                                     workers: int) -> None:
    """Several plans share one backend's workers; each plan's parts, in walk and part
    order, hold the rows ``collect`` writes for it (walks of several parts each)."""
    plans = [plan_walks(_cfg(lattice9, Path(os.devnull), seed)) for seed in (3, 4)]
    backend = make_backend("local", workers, None)
    try:
        results = walk_results(plans, backend)
    finally:
        backend.close()
    for seed, plan, parts in zip((3, 4), plans, results, strict=True):
        assert plan.walks == 9
        assert len(parts) > plan.walks  # 240 / 9 transitions a walk, 25 a part
        keys = [(r.worker, r.part) for r in parts]
        assert keys == sorted(keys)
        collect(_cfg(lattice9, tmp_path / f"d{seed}", seed))
        written = read_dataset(tmp_path / f"d{seed}")
        s = np.concatenate([part_states(r, plan.disc)[0] for r in parts])
        s_next = np.concatenate([part_states(r, plan.disc)[1] for r in parts])
        a = np.concatenate([r.columns["a"] for r in parts])
        assert s.size == written.num_rows == 240
        np.testing.assert_array_equal(s, written.column("s").to_numpy())
        np.testing.assert_array_equal(a, written.column("a").to_numpy())
        np.testing.assert_array_equal(s_next, written.column("s_next").to_numpy())
    # the two seeds walk differently: the comparison above can tell plans apart
    assert not np.array_equal(
        [r.columns["a"][0] for r in results[0]], [r.columns["a"][0] for r in results[1]])


def test_a_calibration_walk_counts_the_rows_collect_writes(lattice9, tmp_path: Path) -> None:
    from simlab.calibration.walks import action_set_options, simulate_counts

    aset = parse_action_set(8, "ccw-east")
    sim = simulate_counts("table", lattice9, KinematicParams(), transitions=180, seed=5,
                          action_set=aset, simulator="kinematic", start_states="all")
    collect(CollectConfig(arena="table", states=lattice9, out=tmp_path / "d",
                                transitions=180, seed=5, simulator="kinematic",
                                params=KinematicParams(), start_states="all", progress=False,
                                **action_set_options(aset)))
    t = read_dataset(tmp_path / "d")
    counts = count_transitions(t.column("s").to_numpy(), t.column("a").to_numpy(),
                               t.column("s_next").to_numpy(), 9, 8)
    assert sim.rows == 180 == int(counts.sum())
    np.testing.assert_array_equal(sim.counts, counts)
    assert sim.blocked == int(t.column("blocked").to_numpy(zero_copy_only=False).sum())


class _Walker:
    def __init__(self, key: str) -> None:
        self.key, self.closed = key, False

    def close(self) -> None:
        self.closed = True


class _Spec:
    def __init__(self, key: str) -> None:
        self.key = key


def test_the_walker_cache_closes_the_world_used_longest_ago(monkeypatch) -> None:
    import simlab.data.walkers as walkers

    built: list[_Walker] = []

    def build(spec: _Spec) -> _Walker:
        built.append(_Walker(spec.key))
        return built[-1]

    monkeypatch.setattr(walkers, "build_walker", build)
    cache = WalkerCache(size=2)
    a, b = cache.get(_Spec("a")), cache.get(_Spec("b"))
    assert cache.get(_Spec("a")) is a  # kept, and now the most recently used
    c = cache.get(_Spec("c"))  # makes room: b was used longest ago
    assert b.closed and not a.closed and not c.closed
    assert cache.get(_Spec("b")) is not b and len(built) == 4  # b is built anew
    assert a.closed  # a was then the oldest
    cache.close()
    assert all(w.closed for w in built)
