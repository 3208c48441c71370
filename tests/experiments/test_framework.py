"""The reproduce driver on the example experiment and on toy runners: seeds, parallel
map, errors that do not stop the others, outputs never replaced silently, the CLI."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.base.parallel import LocalExecutor, make_executor
from simlab.cli import main
from simlab.experiments.context import RunContext, RunResult, experiment_seed
from simlab.experiments.registry import get_runner, runner
from simlab.experiments.reproduce import reproduce

EXAMPLE = Path(__file__).resolve().parents[2] / "simlab" / "experiments" / "example.toml"


def _square(x: int, seed: np.random.SeedSequence) -> tuple[int, float]:
    return x * x, float(np.random.default_rng(seed).random())


@runner("example.test_boom")
def _boom(params, budget, ctx):
    raise RuntimeError("the robot fell off the table")


@runner("example.test_bad_figure")
def _bad_figure(params, budget, ctx):
    return RunResult(metrics={"x": 1.0}, figures=[ctx.out / "missing.png"])


def _toml(tmp_path: Path, name: str, runner_key: str) -> Path:
    p = tmp_path / f"{name}.toml"
    p.write_text(f'name = "{name}"\ntitle = "t"\nreference = "r"\nclaim = "c"\n'
                 f'runner = "{runner_key}"\n[budget.quick]\nseeds = 1\n[budget.full]\nseeds = 1\n')
    return p


def _ctx(tmp_path: Path, executor) -> RunContext:
    return RunContext(name="x", out=tmp_path, seed=experiment_seed(0, "x"), root_seed=0,
                      budget_name="quick", cache=tmp_path / "_cache", progress=False,
                      backend_name="local", executor=executor)


def test_seeds_are_stable_children_and_experiment_seeds_differ(tmp_path):
    ctx = _ctx(tmp_path, LocalExecutor(1))
    a, b = ctx.seeds(3), ctx.seeds(3)
    fresh = experiment_seed(0, "x").spawn(3)
    for x, y, z in zip(a, b, fresh, strict=True):
        assert x.spawn_key == y.spawn_key == z.spawn_key
        assert np.array_equal(x.generate_state(4), z.generate_state(4))
    assert not np.array_equal(experiment_seed(0, "x").generate_state(4),
                              experiment_seed(0, "y").generate_state(4))
    assert not np.array_equal(experiment_seed(0, "x").generate_state(4),
                              experiment_seed(1, "x").generate_state(4))


def test_map_keeps_order_and_matches_in_process(tmp_path):
    seeds = experiment_seed(0, "x").spawn(5)
    jobs = [{"x": i, "seed": s} for i, s in enumerate(seeds)]
    pool = LocalExecutor(2)
    try:
        parallel = _ctx(tmp_path, pool).map(_square, jobs)
    finally:
        pool.close()
    serial = _ctx(tmp_path, LocalExecutor(1)).map(_square, jobs)
    assert [r[0] for r in parallel] == [0, 1, 4, 9, 16]
    assert parallel == serial
    with pytest.raises(ValueError, match="module-level"):
        _ctx(tmp_path, LocalExecutor(1)).map(lambda x: x, [{"x": 1}])


def test_run_result_metrics_are_validated():
    r = RunResult(metrics={"a": np.float64(1.5), "b": np.int64(3), "c": np.nan, "d": True})
    assert r.metrics == {"a": 1.5, "b": 3, "c": None, "d": True}
    assert type(r.metrics["b"]) is int
    with pytest.raises(ConfigError, match=r"metrics\.e"):
        RunResult(metrics={"e": [1, 2]})


def test_executor_options():
    with pytest.raises(ConfigError) as err:
        make_executor("local", address="auto")
    assert err.value.key == "address"
    with pytest.raises(ConfigError):
        make_executor("slurm")
    with pytest.raises(ConfigError):
        LocalExecutor(0)


def test_registry_rejects_keys_outside_the_groups_and_double_registration():
    with pytest.raises(ValueError, match="group"):
        runner("nogroup.x")
    with pytest.raises(ValueError, match="already registered"):
        runner("example.test_boom")(_square)
    assert get_runner("example.coin").__name__ == "coin"


@pytest.mark.slow
def test_example_reproduce_is_deterministic_and_independent_of_workers(tmp_path):
    a = reproduce(tmp_path / "a", experiments=EXAMPLE, workers=2, progress=False, log=None)
    b = reproduce(tmp_path / "b", experiments=EXAMPLE, workers=1, progress=False, log=None)
    c = reproduce(tmp_path / "c", experiments=EXAMPLE, seed=1, progress=False, log=None)
    ea, eb, ec = (r.entry("example_coin") for r in (a, b, c))
    assert ea["status"] == "ok" and ea["metrics"] == eb["metrics"]
    assert ea["metrics"]["p_hat"] != ec["metrics"]["p_hat"]
    # 4 seeds x 2000 flips of p = 0.3: sd of the mean 0.0051, the check allows +-0.03
    assert [c["status"] for c in ea["checks"]] == ["PASS", "not checked"]
    saved = json.loads((tmp_path / "a" / "example_coin" / "result.json").read_text())
    assert saved["metrics"] == ea["metrics"] and len(saved["details"]["estimates"]) == 4
    assert np.mean(saved["details"]["estimates"]) == pytest.approx(ea["metrics"]["p_hat"])
    # the interval of a mean of 4 seeds: Student's t for 3 degrees of freedom (3.182)
    est = np.asarray(saved["details"]["estimates"])
    assert ea["metrics"]["ci95"] == pytest.approx(3.182446 * est.std(ddof=1) / 2.0)
    md = (tmp_path / "a" / "results.md").read_text()
    assert "| **PASS** |" in md and "example_coin/estimates.png" in md
    assert (tmp_path / "a" / "example_coin" / "estimates.png").read_bytes()[:4] == b"\x89PNG"


def test_a_failing_experiment_is_reported_and_the_others_run(tmp_path):
    exps = [_toml(tmp_path, "boom", "example.test_boom"),
            _toml(tmp_path, "badfig", "example.test_bad_figure"), EXAMPLE]
    res = reproduce(tmp_path / "out", experiments=exps, workers=1, progress=False, log=None)
    assert sorted(res.errors) == ["badfig", "boom"]
    assert res.entry("example_coin")["status"] == "ok"
    boom = res.entry("boom")
    assert "the robot fell off the table" in boom["error"]
    assert "RuntimeError" in (tmp_path / "out" / "boom" / "error.txt").read_text()
    assert "does not exist" in res.entry("badfig")["error"]
    md = (tmp_path / "out" / "results.md").read_text()
    assert md.count("**ERROR**") >= 2
    assert main(["reproduce", "--experiments", str(exps[0]), "--out", str(tmp_path / "cli"),
                 "--workers", "1", "--no-progress"]) == 1


def test_outputs_are_not_replaced_without_overwrite_and_tables_merge(tmp_path):
    out = tmp_path / "out"
    other = _toml(tmp_path, "boom", "example.test_boom")
    reproduce(out, experiments=EXAMPLE, workers=1, progress=False, log=None)
    marker = out / "example_coin" / "estimates.png"
    before = marker.read_bytes()
    with pytest.raises(ConfigError, match="already exist") as err:
        reproduce(out, experiments=EXAMPLE, workers=1, progress=False, log=None)
    assert err.value.path == str(out / "example_coin")
    assert marker.read_bytes() == before
    reproduce(out, experiments=[other], workers=1, progress=False, log=None)  # another experiment
    table = json.loads((out / "results.json").read_text())
    assert [e["name"] for e in table["experiments"]] == ["boom", "example_coin"]
    res = reproduce(out, experiments=EXAMPLE, overwrite=True, seed=3, workers=1, progress=False,
                    log=None)
    table = json.loads((out / "results.json").read_text())
    coin = next(e for e in table["experiments"] if e["name"] == "example_coin")
    assert coin["seed"] == 3 and coin["metrics"] == res.entry("example_coin")["metrics"]


def test_cli_end_to_end_and_errors(tmp_path, capsys):
    out = tmp_path / "cli"
    args = ["reproduce", "--experiments", str(EXAMPLE), "--out", str(out), "--workers", "1",
            "--no-progress"]
    assert main(args) == 0
    assert "1 checks PASS, 0 FAIL" in capsys.readouterr().out
    assert (out / "results.md").is_file() and (out / "results.json").is_file()
    assert main(args) == 2  # exists, no --overwrite
    assert "--overwrite" in capsys.readouterr().err
    assert main([*args, "--overwrite", "--only", "nope"]) == 2
    assert "unknown experiment" in capsys.readouterr().err
    assert main(["reproduce", "--experiments", str(EXAMPLE)]) == 2  # no --out
    assert main(["reproduce", "--list", "--experiments", str(EXAMPLE)]) == 0
    assert "example_coin" in capsys.readouterr().out
    shutil.rmtree(out)


class _FakeRay:
    """Just enough of the ``ray`` module to run RayExecutor in-process."""

    def __init__(self):
        self.up = False
        self.calls = []

    def is_initialized(self):
        return self.up

    def init(self, **kwargs):
        self.calls.append(("init", kwargs))
        self.up = True

    def shutdown(self):
        self.calls.append(("shutdown", {}))
        self.up = False

    def cluster_resources(self):
        if not self.up:
            raise RuntimeError("Ray has not been started yet")
        return {"CPU": 3.0}

    def remote(self, **_options):
        class _Remote:
            def __init__(self, fn):
                self.fn = fn

            def remote(self, *args):
                return self.fn(*args)

        return _Remote

    def put(self, obj):
        return obj

    def wait(self, refs, num_returns=1):
        return refs[:num_returns], refs[num_returns:]

    def get(self, refs):
        return refs


def test_ray_executor_owns_only_the_runtime_it_started(tmp_path, monkeypatch):
    import sys

    fake = _FakeRay()
    monkeypatch.setitem(sys.modules, "ray", fake)
    res = reproduce(tmp_path / "a", experiments=EXAMPLE, backend="ray", progress=False, log=None)
    assert res.backend == "ray (3 CPUs)"  # described after the runtime was shut down
    assert [c[0] for c in fake.calls] == ["init", "shutdown"]
    local = reproduce(tmp_path / "b", experiments=EXAMPLE, workers=1, progress=False, log=None)
    assert res.entry("example_coin")["metrics"] == local.entry("example_coin")["metrics"]
    fake.calls.clear()
    fake.up = True  # a runtime the caller started: reused, left running
    reproduce(tmp_path / "c", experiments=EXAMPLE, backend="ray", progress=False, log=None)
    assert fake.calls == [] and fake.up
    with pytest.raises(ConfigError) as err:
        make_executor("ray", address="ray://head:10001")
    assert err.value.key == "address"


def test_unknown_runner_stops_before_anything_runs_unless_not_selected(tmp_path):
    d = tmp_path / "exps"
    d.mkdir()
    shutil.copy(EXAMPLE, d / "example.toml")
    bad = _toml(d, "zz_bad", "example.nosuch")
    with pytest.raises(ConfigError) as err:
        reproduce(tmp_path / "out", experiments=d, workers=1, progress=False, log=None)
    assert err.value.path == str(bad) and err.value.key == "runner"
    assert not (tmp_path / "out").exists()
    res = reproduce(tmp_path / "out", experiments=d, only="example_coin", workers=1,
                    progress=False, log=None)
    assert [e["name"] for e in res.entries] == ["example_coin"]
