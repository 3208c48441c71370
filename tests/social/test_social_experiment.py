"""The social_table_closed_loop experiment runs the physics walk's segments on the
reproduction's executor (ctx.executor), and its data do not depend on which executor:
in-process, a real local pool, or the pipeline's own path without an executor."""

from __future__ import annotations

import json

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.base.parallel import InProcessExecutor, LocalExecutor
from simlab.experiments.context import RunContext, experiment_seed
from simlab.experiments.social import closed_loop
from simlab.social.pipeline import social_pipeline
from simlab.social.walk import WalkConfig, social_walk

NAME = "social_table_closed_loop"
PARAMS = {"arena": "table", "human": "easy", "agent": "mb-egreedy", "variant": "paper",
          "module": "both"}
#: a tiny budget shaped like the full one (``workers`` included: it gives way to ctx's)
BUDGET = {"seeds": 1, "hours": 0.01, "trials": 300, "walk_steps": 80, "workers": 2,
          "gif_decisions": 2}


class _Recording(InProcessExecutor):
    """An in-process executor that notes the functions it ran."""

    def __init__(self) -> None:
        super().__init__()
        self.ran: list[str] = []

    def map(self, fn, kwargs_list, *, desc=None, progress=False):
        self.ran += [fn.__name__] * len(kwargs_list)
        return super().map(fn, kwargs_list, desc=desc, progress=progress)


def _ctx(tmp_path, executor, tag):
    out = tmp_path / tag
    out.mkdir()
    return RunContext(name=NAME, out=out, seed=experiment_seed(0, NAME), root_seed=0,
                      budget_name="quick", cache=tmp_path / "_cache", progress=False,
                      backend_name="local", executor=executor)


def _data(summary):
    """summary.json without what says how or where it ran (wall clocks, the walk's
    workers, the output folder)."""
    if isinstance(summary, dict):
        return {k: _data(v) for k, v in summary.items()
                if "wall" not in k and k not in ("walk_workers", "out")}
    if isinstance(summary, list):
        return [_data(v) for v in summary]
    return summary


def _arrays(run_dir):
    return [np.load(run_dir / f, allow_pickle=False)
            for f in ("social_q.npy", "social_q_empirical.npy")]


def test_same_data_on_any_executor(tmp_path):
    recording = _Recording()
    a = closed_loop(dict(PARAMS), dict(BUDGET), _ctx(tmp_path, recording, "inproc"))
    assert recording.ran == ["walk_segment"] * 4  # the walk's 4 segments ran on ctx's
    with LocalExecutor(2) as pool:
        b = closed_loop(dict(PARAMS), dict(BUDGET), _ctx(tmp_path, pool, "pool"))
    assert a.metrics == b.metrics
    assert a.details["summary"]["empirical_training"]["walk_workers"] == 1
    assert b.details["summary"]["empirical_training"]["walk_workers"] == 2
    assert _data(a.details["summary"]) == _data(b.details["summary"])
    # the pipeline as `simlab social-pipeline --workers 1` runs it (no executor)
    direct = tmp_path / "direct"
    social_pipeline(out=direct, seed=0, runs=1, hours=0.01, trials=300, walk_steps=80,
                    gif_decisions=2, **PARAMS)
    summary = json.loads((direct / "summary.json").read_text())
    assert _data(summary) == json.loads(json.dumps(_data(a.details["summary"])))
    for x, y, z in zip(_arrays(tmp_path / "inproc" / "run"), _arrays(tmp_path / "pool" / "run"),
                       _arrays(direct), strict=True):
        assert np.array_equal(x, y) and np.array_equal(x, z)


def test_an_executor_and_workers_are_refused_together(tmp_path):
    with pytest.raises(ConfigError, match="workers"):
        social_pipeline(out=tmp_path / "x", module="empirical", workers=2,
                        executor=InProcessExecutor())
    assert not (tmp_path / "x").exists()
    with pytest.raises(ConfigError, match="executor"):
        social_walk(WalkConfig(steps=5, workers=2), processes=2, executor=InProcessExecutor())
