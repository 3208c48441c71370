"""Every experiment of ``experiments/`` (discovered, so new TOMLs are covered as they
land) runs with ``--budget quick``; its quick checks hold; results.md lists every check
and links existing figures; the physics experiments share one chain; the same
experiment gives the same metrics through the CLI and on Ray."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from simlab.cli import main
from simlab.experiments.reproduce import reproduce
from simlab.experiments.spec import PASS, discover_experiments

#: Every test shares the module's quick reproduce run (minutes of CPU): the slow tier.
pytestmark = pytest.mark.slow

SPECS = discover_experiments()
NAMES = [s.name for s in SPECS]


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce") / "quick"
    return reproduce(out, budget="quick", progress=False, log=None)


@pytest.mark.parametrize("name", NAMES)
def test_experiment_runs_and_its_quick_checks_hold(quick, name):
    e = quick.entry(name)
    assert e["status"] == "ok", e.get("error")
    spec = next(s for s in SPECS if s.name == name)
    assert len(e["checks"]) == len(spec.checks)
    for c, check in zip(e["checks"], spec.checks, strict=True):
        if "quick" in check.budgets:
            assert c["status"] == PASS, f"{name}: {c['check']} = {c['ours']} ({c['detail']})"
        else:
            assert c["status"] == "not checked"
    for f in e["figures"]:
        path = quick.out / f
        assert path.is_file() and path.stat().st_size > 0
        if path.suffix == ".png":
            assert path.read_bytes()[:4] == b"\x89PNG"
    assert e["wall_seconds"] > 0


def test_results_files_list_every_check_and_figure(quick):
    md = quick.results_md.read_text()
    table = json.loads(quick.results_json.read_text())
    assert [e["name"] for e in table["experiments"]] == NAMES
    rows = [line for line in md.splitlines() if line.startswith("| ") and "Holds" not in line
            and line.count("|") == 7]
    n_checks = sum(len(s.checks) for s in SPECS)
    assert len(rows) == n_checks
    assert sum("**PASS**" in r or "not checked" in r for r in rows) == n_checks
    for link in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", md):
        assert (quick.out / link).is_file(), link


def test_physics_experiments_share_one_dataset_and_agree_with_its_files(quick):
    cache = quick.out / "_cache" / "physics"
    for stage in ("map", "states", "dataset", "mdp", "train"):
        assert len(list(cache.glob(f"{stage}-*"))) == 1, stage
    (mdp_dir,) = cache.glob("mdp-*")
    summary = json.loads((mdp_dir / "mdp.json").read_text())
    m8 = quick.entry("fig4_8_entropy")["metrics"]
    assert m8["entropy_slow_bits"] == pytest.approx(summary["entropy_bits"]["slow_mean"])
    assert m8["entropy_fast_bits"] == pytest.approx(summary["entropy_bits"]["fast_mean"])
    assert m8["transitions"] == summary["transitions"]
    assert m8["fast_minus_slow_ci95_low"] <= m8["fast_minus_slow_paired_bits"] \
        <= m8["fast_minus_slow_ci95_high"]
    m9 = quick.entry("fig4_9_empirical_training")["metrics"]
    (train_dir,) = cache.glob("train-*")
    goals = json.loads((train_dir / "summary.json").read_text())["goals"]
    assert m9["goals"] == len(goals)
    assert m9["min_greedy_ratio"] == pytest.approx(min(g["greedy_ratio"] for g in goals.values()))
    m10 = quick.entry("fig4_10_replay")["metrics"]
    assert m10["ratio_to_random_mdp"] == pytest.approx(
        m10["rate_per_hour"] / m10["predicted_random_rate_per_hour"])
    replay = json.loads((quick.out / "fig4_10_replay" / "replay_seed0" / "replay.json")
                        .read_text())
    assert replay["result"]["rewards"] == m10["rewards"]
    assert replay["result"]["rate_per_hour"] == pytest.approx(m10["rate_per_hour"])


def _with_cache(quick, dst: Path) -> Path:
    dst.mkdir()
    shutil.copytree(quick.out / "_cache", dst / "_cache")
    return dst


def test_cli_reuses_the_cache_and_gives_the_same_metrics(quick, tmp_path, capsys):
    out = _with_cache(quick, tmp_path / "cli")
    code = main(["reproduce", "--only", "fig4_9_empirical_training", "--out", str(out),
                 "--no-progress"])
    assert code == 0
    assert "0 FAIL" in capsys.readouterr().out
    table = json.loads((out / "results.json").read_text())
    (entry,) = table["experiments"]
    assert entry["metrics"] == quick.entry("fig4_9_empirical_training")["metrics"]
    assert any("reused from the shared cache" in n for n in entry["notes"])


def test_ray_backend_gives_the_same_metrics(quick, tmp_path):
    ray = pytest.importorskip("ray")
    out = _with_cache(quick, tmp_path / "ray")
    ray.init(num_cpus=2, include_dashboard=False)
    try:
        res = reproduce(out, only="fig4_10_replay", budget="quick", backend="ray",
                        progress=False, log=None)
    finally:
        ray.shutdown()
    entry = res.entry("fig4_10_replay")
    assert entry["status"] == "ok", entry.get("error")
    assert entry["backend"].startswith("ray")
    local = quick.entry("fig4_10_replay")["metrics"]
    assert entry["metrics"].keys() == local.keys()
    for k, v in local.items():
        assert entry["metrics"][k] == pytest.approx(v, rel=1e-12, nan_ok=True), k
    assert np.isfinite(entry["metrics"]["rate_per_hour"])
