"""Pieces of the physics experiments with known answers: settings, seeds, the stage
cache, the paired entropy difference, the linearity of a cumulative reward."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.experiments.physics import linearity_r2, paired_entropy_difference
from simlab.experiments.spec import discover_experiments
from simlab.orchestration.stages import (
    MARKER,
    PhysicsChain,
    PhysicsSettings,
    chain_seed,
)

PHYSICS = ("fig4_8_entropy", "fig4_9_empirical_training", "fig4_10_replay")


def test_settings_merge_and_validate():
    s = PhysicsSettings.from_tables({"hours": 10.0, "states": 41}, {"seeds": 2, "hours": 1})
    assert s.hours == 1.0 and isinstance(s.hours, float) and s.seeds == 2 and s.states == 41
    assert s.pose_source == PhysicsSettings().pose_source
    for params, budget, key in [({"hourz": 1.0}, {}, "params.hourz"),
                                ({}, {"hours": 0}, "budget.hours"),
                                ({}, {"runs": 2.5}, "budget.runs"),
                                ({"video": 1}, {}, "params.video"),
                                ({"pose_source": "gps"}, {}, "params.pose_source")]:
        with pytest.raises(ConfigError) as err:
            PhysicsSettings.from_tables(params, budget)
        assert err.value.key == key


@pytest.mark.parametrize("budget", ["quick", "full"])
def test_the_three_physics_experiments_share_one_chain(budget):
    """Equal settings in the three TOMLs: one map, dataset and training for all three."""
    specs = {s.name: s for s in discover_experiments()}
    settings = {PhysicsSettings.from_tables(specs[n].params, specs[n].budget(budget))
                for n in PHYSICS}
    assert len(settings) == 1
    (s,) = settings
    if budget == "full":  # the thesis's numbers (4.5): 41 states, ~10 h, ~2000 episodes, 3 h
        assert (s.states, s.hours, s.episodes, s.replay_hours) == (41, 10.0, 2000, 3.0)
        assert s.agent == "vi-softmax"


def test_chain_seeds_are_distinct_and_reproducible():
    seeds = {(stage, i): chain_seed(0, stage, i)
             for stage in ("map", "dataset", "train", "replay", "baseline") for i in range(3)}
    assert len(set(seeds.values())) == len(seeds)
    assert chain_seed(0, "dataset", 1) == seeds["dataset", 1]
    assert chain_seed(1, "dataset", 1) != seeds["dataset", 1]


def test_stage_cache_builds_once_and_rebuilds_an_interrupted_stage(tmp_path):
    calls = []

    def build(d):
        calls.append(d)
        (d / "out.txt").write_text("x")
        return {"n": len(calls)}

    a = PhysicsChain(tmp_path, PhysicsSettings(), 0).cached_stage("toy", {"k": 1}, build)
    assert a.built and a.summary == {"n": 1} and (a.path / MARKER).is_file()
    b = PhysicsChain(tmp_path, PhysicsSettings(), 0).cached_stage("toy", {"k": 1}, build)
    assert not b.built and b.path == a.path and b.summary == {"n": 1} and len(calls) == 1
    c = PhysicsChain(tmp_path, PhysicsSettings(), 0).cached_stage("toy", {"k": 2}, build)
    assert c.path != a.path and len(calls) == 2
    (a.path / MARKER).unlink()  # as if the build had been killed before finishing
    (a.path / "partial.tmp").write_text("junk")
    d = PhysicsChain(tmp_path, PhysicsSettings(), 0).cached_stage("toy", {"k": 1}, build)
    assert d.built and d.summary == {"n": 3} and not (d.path / "partial.tmp").exists()
    assert json.loads((d.path / MARKER).read_text())["key"]["k"] == 1


def test_stage_cache_is_rebuilt_when_the_code_changes(tmp_path, monkeypatch):
    import simlab.orchestration.cache as pc

    def build(d):
        return {}

    a = PhysicsChain(tmp_path, PhysicsSettings(), 0).cached_stage("toy", {"k": 1}, build)
    assert (json.loads((a.path / MARKER).read_text())["key"]["code"]
            == pc.code_fingerprint("physics"))
    monkeypatch.setattr(pc, "code_fingerprint", lambda scope: "edited-physics")
    b = PhysicsChain(tmp_path, PhysicsSettings(), 0).cached_stage("toy", {"k": 1}, build)
    assert b.built and b.path != a.path


def test_paired_entropy_difference_on_known_arrays():
    rng = np.random.default_rng(0)
    S = 6
    slow = rng.random((S, 8))
    H = np.concatenate([slow, slow + 0.25], axis=1)
    visited = np.ones((S, 16), dtype=bool)
    visited[0, 3] = False  # pair (0, 3) has no slow estimate: excluded
    visited[1, 8 + 5] = False  # pair (1, 5) has no fast estimate: excluded
    H[0, 8 + 3] = 99.0
    mean, half, n = paired_entropy_difference([H], [visited])
    assert n == S * 8 - 2 and mean == pytest.approx(0.25) and half == pytest.approx(0.0, abs=1e-12)
    # two datasets pool their pairs; differences +0.25 and -0.25 average to 0
    H2 = np.concatenate([slow, slow - 0.25], axis=1)
    mean, half, n = paired_entropy_difference([H, H2], [visited, np.ones((S, 16), bool)])
    assert n == 2 * S * 8 - 2
    assert mean == pytest.approx((0.25 * (S * 8 - 2) - 0.25 * S * 8) / n)
    assert half == pytest.approx(1.96 * np.std(np.r_[np.full(S * 8 - 2, 0.25),
                                                     np.full(S * 8, -0.25)], ddof=1) / math.sqrt(n))


def test_linearity_of_cumulative_reward():
    duration = 3600.0
    steady = np.arange(1, 101) * 36.0  # one reward every 36 s
    assert linearity_r2(steady, duration) > 0.999
    late = np.linspace(3300.0, 3600.0, 100)  # everything in the last 5 minutes
    assert linearity_r2(late, duration) < 0.6
    assert math.isnan(linearity_r2(np.array([10.0]), duration))
