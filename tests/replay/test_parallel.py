"""The replay's random baseline in a second process: the same results as sequentially."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from simlab.replay import scheduling as replay_module
from simlab.replay.replay import replay
from simlab.replay.summary import Schedule

WALL_KEYS = {"wall_seconds", "real_time_factor_robot", "real_time_factor_stepped"}


def _strip(summary: dict) -> dict:
    """The summary without wall-clock figures and output paths."""
    out = {}
    for k, v in summary.items():
        if k in WALL_KEYS or k in ("files", "schedule"):
            continue
        out[k] = _strip(v) if isinstance(v, dict) else v
    return out


def _logs_equal(a, b) -> None:
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            assert x.dtype == y.dtype and np.array_equal(x, y), f.name
        else:
            assert x == y, f.name


@pytest.mark.slow
@pytest.mark.parametrize("pose_source", ["truth", "mcl"])
def test_parallel_baseline_is_bit_identical(chain, tmp_path, monkeypatch, pose_source) -> None:
    # both extra processes (baseline, filter), even on a 1- or 2-core runner
    monkeypatch.setattr(replay_module, "usable_cores", lambda: 3)
    assert replay_module.schedule(True, True, pose_source == "mcl") == (
        True, pose_source == "mcl")
    runs = {}
    for parallel in (False, True):
        runs[parallel] = replay("table", chain.states, chain.qtables, hours=0.03, seed=3,
                                pose_source=pose_source, out=tmp_path / f"p{parallel}",
                                progress=False, parallel=parallel, baseline_hours=0.02,
                                video=pose_source == "mcl", max_frames=5)
    seq, par = runs[False], runs[True]
    assert seq.baseline is not None and par.baseline is not None
    assert seq.summary.schedule == Schedule(baseline_process=False, mcl_process=False)
    assert par.summary.schedule == Schedule(baseline_process=True,
                                            mcl_process=pose_source == "mcl")
    assert seq.baseline.log.n > 0 and seq.run.log.n > 0
    _logs_equal(seq.run.log, par.run.log)
    _logs_equal(seq.baseline.log, par.baseline.log)
    assert seq.baseline.stepped_seconds == par.baseline.stepped_seconds
    assert _strip(seq.summary.to_json()) == _strip(par.summary.to_json())
    assert seq.files["transitions"].read_bytes() == par.files["transitions"].read_bytes()
    if pose_source == "mcl":  # the filter ran in its own process: same updates, same frames
        assert seq.run.mcl_log.t.size > 0
        _logs_equal(seq.run.mcl_log, par.run.mcl_log)
        assert len(seq.run.frames) == len(par.run.frames) > 0
        for f, g in zip(seq.run.frames, par.run.frames, strict=True):
            assert np.array_equal(f.particles, g.particles)
            assert np.array_equal(f.estimate, g.estimate)
        # the video was encoded by the baseline's worker: the same bytes as here
        gif = seq.files["gif"].read_bytes()
        assert gif[:6] == b"GIF89a" and gif == par.files["gif"].read_bytes()


@pytest.mark.slow
def test_a_lent_worker_runs_the_baseline_and_stays_open(chain, tmp_path, monkeypatch) -> None:
    """The pipeline lends its warmed worker (issue 17): the replay runs its baseline there
    instead of starting a process, leaves it open, and the results are the same."""
    import os

    import simlab.base.parallel

    monkeypatch.setattr(replay_module, "usable_cores", lambda: 2)
    kw = dict(hours=0.02, seed=4, progress=False, baseline_hours=0.02)
    own = replay("table", chain.states, chain.qtables, out=tmp_path / "own", **kw)
    with simlab.base.parallel.spawn_worker() as lent:
        pid = lent.submit(os.getpid).result()

        def refuse():
            raise AssertionError("a second worker was started beside the lent one")

        monkeypatch.setattr(simlab.base.parallel, "spawn_worker", refuse)
        got = replay("table", chain.states, chain.qtables, out=tmp_path / "lent", pool=lent,
                     **kw)
        assert lent.submit(os.getpid).result() == pid != os.getpid()  # still open, same one
    assert got.summary.schedule.baseline_process and own.summary.schedule.baseline_process
    _logs_equal(own.run.log, got.run.log)
    _logs_equal(own.baseline.log, got.baseline.log)
    assert _strip(own.summary.to_json()) == _strip(got.summary.to_json())


def test_schedule_follows_the_core_count_not_the_load(monkeypatch) -> None:
    """The core count decides, as for the dataset's walks: on 2 or more cores the baseline
    gets a process, whatever the machine's load; the filter gets one only on 3 or more,
    where it has a core of its own; on 1 nothing does."""
    for cores, split in ((1, (False, False)), (2, (True, False)), (3, (True, True)),
                         (8, (True, True))):
        monkeypatch.setattr(replay_module, "usable_cores", lambda cores=cores: cores)
        assert replay_module.schedule(True, True, True) == split
        assert replay_module.schedule(True, False, True) == (False, split[1])
        assert replay_module.schedule(True, True, False) == (split[0], False)
        assert replay_module.schedule(False, True, True) == (False, False)
        assert replay_module.schedule(True, False, False) == (False, False)
        assert replay_module.schedule(True, True, True, cores=cores) == split


def test_one_core_runs_sequentially(chain, tmp_path, monkeypatch) -> None:
    """On one usable core no process is started (the pool is never built)."""
    monkeypatch.setattr(replay_module, "usable_cores", lambda: 1)

    def refuse(*_a, **_k):
        raise AssertionError("a process pool was started on one core")

    import concurrent.futures as cf

    monkeypatch.setattr(cf, "ProcessPoolExecutor", refuse)
    res = replay("table", chain.states, chain.qtables, hours=0.01, seed=1,
                 out=tmp_path / "one", progress=False, baseline_hours=0.01)
    assert res.baseline is not None and res.baseline.log.n > 0
