"""The Visit-the-lab runners of ``simlab reproduce``: curve metrics on hand-made curves,
the greedy-success measure, run tables, the shared run cache (built once, reused, equal
to ``simlab visitlab train``), runs shared between figures, and the Ray backend."""

from __future__ import annotations

import json

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.base.parallel import LocalExecutor
from simlab.experiments.context import RunContext, experiment_seed
from simlab.experiments.reproduce import reproduce
from simlab.experiments.visitlab import (
    curve_metrics,
    get_runs,
    greedy_success,
    parse_run,
    visitlab_seed,
)
from simlab.visitlab.actions import move_action
from simlab.visitlab.grid import gridworld
from simlab.visitlab.training import train


def test_curve_metrics_of_a_step_curve():
    # 2 seeds x 100 trials: 0 for 50 trials, then 10 (smoothing windows of 1 trial)
    r = np.zeros((2, 100))
    r[:, 50:] = 10.0
    m = curve_metrics("a", r, thresholds=[5.0, 11.0],
                      windows={"after": (0.5, 0.6), "early": (0.0, 0.1)})
    assert m["a_plateau"] == 10.0
    assert m["a_trials_to_90pct"] == 51  # trials are counted from 1
    assert m["a_trials_to_5"] == 51
    assert m["a_trials_to_11"] is None  # never reached
    assert m["a_after"] == 10.0 and m["a_early"] == 0.0
    assert m["a_std"] == 0.0 and m["a_seed_std"] == 0.0


def test_curve_metrics_band_is_the_within_window_standard_deviation():
    # 200 trials -> windows of 2 trials holding 9 and 11: mean 10, std 1
    r = np.tile(10.0 + np.where(np.arange(200) % 2 == 0, -1.0, 1.0), (3, 1))
    r[1] += 2.0  # a second seed 2 higher: per-seed plateaus 10, 12, 10
    m = curve_metrics("b", r)
    assert m["b_plateau"] == pytest.approx(32 / 3)
    assert m["b_seed_std"] == pytest.approx(np.std([10.0, 12.0, 10.0]))
    # pooled over seeds within a window: values 9, 11, 11, 13, 9, 11
    assert m["b_std"] == pytest.approx(np.std([9, 11, 11, 13, 9, 11]))


def test_greedy_success_counts_cells_that_reach_the_goal_in_time():
    lay = gridworld(2, 12, (1, 2))  # room 0: columns 0-5, room 1: columns 6-11
    nxt, labels = lay.transition_table(), lay.cell_labels
    right = np.zeros((lay.n_cells, 25))
    right[:, move_action(3, 3)] = 1.0  # RIGHT, 3 cells
    assert greedy_success(nxt, labels, right, 1, horizon=2) == 1.0
    assert greedy_success(nxt, labels, right, 1, horizon=1) == 0.5  # columns 3-5 only
    left = np.zeros((lay.n_cells, 25))
    left[:, move_action(2, 1)] = 1.0
    assert greedy_success(nxt, labels, left, 1, horizon=50) == 0.0


def test_run_tables_are_validated_with_the_key():
    budget = {"seeds": 2, "trials": 10}
    with pytest.raises(ConfigError) as e:
        parse_run({"agent": "mb-egreedy", "colour": 1}, "params.runs[0]", {"task": "nav"},
                  budget)
    assert e.value.key == "params.runs[0]"
    with pytest.raises(ConfigError) as e:
        parse_run({"agent": "nope"}, "params.runs[1]", {"task": "nav"}, budget)
    assert e.value.key == "params.runs[1].agent"
    with pytest.raises(ConfigError) as e:
        parse_run({"agent": "rmax", "task": "fly"}, "params.runs[2]", {}, budget)
    assert e.value.key == "params.runs[2].task"
    with pytest.raises(ConfigError) as e:
        parse_run({"agent": "rmax", "label": "x"}, "r", {"task": "nav"},
                  {"seeds": 1, "trials": {"social": 5}})
    assert e.value.key == "budget.trials"
    spec = parse_run({"agent": "rmax", "label": "x"}, "r", {"task": "nav"},
                     {"seeds": 1, "trials": {"nav": 7}})
    assert spec.trials == 7 and spec.seeds == 1 and spec.task == "nav"


def _ctx(tmp_path, name="t", root_seed=0):
    return RunContext(name=name, out=tmp_path / name, seed=experiment_seed(root_seed, name),
                      root_seed=root_seed, budget_name="quick", cache=tmp_path / "_cache",
                      progress=False, backend_name="local", executor=LocalExecutor(1))


def test_shared_runs_are_built_once_and_equal_the_cli_training(tmp_path):
    spec = parse_run({"agent": "mb-egreedy", "label": "a"}, "r", {"task": "nav"},
                     {"seeds": 2, "trials": 30})
    (first,) = get_runs(_ctx(tmp_path), [spec])
    same = parse_run({"agent": "mb-egreedy", "label": "other"}, "r", {"task": "nav"},
                     {"seeds": 2, "trials": 30})
    (again,) = get_runs(_ctx(tmp_path, "u"), [same])
    assert first.built and not again.built and again.path == first.path
    np.testing.assert_array_equal(again.returns, first.returns)
    np.testing.assert_array_equal(again.q, first.q)
    # seed i is seed i of `simlab visitlab train --seed visitlab_seed(root) --seeds 2`
    ref = train("nav", "mb-egreedy", trials=30, seeds=2, seed=visitlab_seed(0), progress=False)
    np.testing.assert_array_equal(first.returns, ref.returns)
    np.testing.assert_array_equal(first.q, ref.q)
    # another setting or another root seed is another run
    longer = parse_run({"agent": "mb-egreedy"}, "r", {"task": "nav"}, {"seeds": 2, "trials": 31})
    (other,) = get_runs(_ctx(tmp_path), [longer])
    assert other.built and other.path != first.path
    (reseeded,) = get_runs(_ctx(tmp_path, root_seed=1), [spec])
    assert reseeded.built and not np.array_equal(reseeded.q, first.q)


def test_kept_models_are_saved_per_seed(tmp_path):
    spec = parse_run({"agent": "mb-egreedy"}, "r", {"task": "social"}, {"seeds": 2, "trials": 20},
                     keep_model=True)
    (run,) = get_runs(_ctx(tmp_path), [spec])
    for i in range(2):
        m = run.model(i)
        assert int(m["count"].sum()) == 20 * 40  # every step observed once
        assert tuple(m["shape"]) == (2560, 30)


@pytest.fixture(scope="module")
def nav_pair(tmp_path_factory):
    out = tmp_path_factory.mktemp("visitlab") / "out"
    return reproduce(out, only="fig4_1_nav_mb_vs_mf,fig4_2_nav_mb_comparison", budget="quick",
                     progress=False, log=None)


def test_figures_share_their_model_based_runs(nav_pair):
    m1 = nav_pair.entry("fig4_1_nav_mb_vs_mf")["metrics"]
    e2 = nav_pair.entry("fig4_2_nav_mb_comparison")
    for k, v in e2["metrics"].items():
        if k != "seeds":
            assert m1[k] == v, k
    assert any("2 reused from the shared cache" in n for n in e2["notes"])
    details = json.loads((nav_pair.out / "fig4_1_nav_mb_vs_mf" / "result.json").read_text())
    assert set(details["details"]["curves"]) == {"mb_egreedy", "q_learning", "vi_softmax",
                                                 "q_softmax"}


@pytest.mark.slow
def test_ray_backend_gives_the_same_visitlab_metrics(nav_pair, tmp_path):
    ray = pytest.importorskip("ray")
    ray.init(num_cpus=2, include_dashboard=False)
    try:
        res = reproduce(tmp_path / "ray", only="fig4_2_nav_mb_comparison", budget="quick",
                        backend="ray", progress=False, log=None)
    finally:
        ray.shutdown()
    entry = res.entry("fig4_2_nav_mb_comparison")
    assert entry["status"] == "ok", entry.get("error")
    assert entry["backend"].startswith("ray")
    assert any("built" in n for n in entry["notes"])  # trained on Ray, not read from a cache
    assert entry["metrics"] == nav_pair.entry("fig4_2_nav_mb_comparison")["metrics"]


MODULES = {
    "variant": "thesis",
    "combined": {"max_steps": 12},
    "nav": {"agent": "rmax", "env": {"start": "random", "goal": "random"}},
    "gotohuman": {"agent": "mb-egreedy", "env": {"episode": "random"}},
    "social": {"agent": "mb-egreedy",
               "env": {"human": {"speed_probs": [0.0, 1.0, 0.0], "name": "fast"}}},
}
TINY = {"seeds": 2, "nav_trials": 20, "gth_trials": 10, "social_trials": 30, "trials": 4}


def test_adaptability_runs_the_named_humans_on_the_shared_modules(tmp_path):
    from simlab.experiments.visitlab import adaptability, combined

    ctx = _ctx(tmp_path, "combined")
    res = combined(dict(MODULES), dict(TINY), ctx)
    assert res.metrics["trials"] == 4 and res.metrics["max_steps"] == 12
    assert (ctx.out / "episode.gif").is_file()
    params = {**MODULES, "carry_model": [True, False],
              "humans": {"same": {"speed_probs": [0.0, 1.0, 0.0], "name": "fast"},
                         "hard": "hard"}}
    ctx2 = _ctx(tmp_path, "adapt")
    res2 = adaptability(params, dict(TINY), ctx2)
    m = res2.metrics
    assert {"same_final", "hard_final", "hard_over_same", "hard_final_q_only"} <= set(m)
    assert "pointing_final" not in m
    assert any("3 reused from the shared cache" in n for n in res2.notes)  # the modules
    with pytest.raises(ConfigError) as e:
        adaptability({**params, "carry_model": [True, True]}, dict(TINY), ctx2)
    assert e.value.key == "params.carry_model"
    with pytest.raises(ConfigError) as e:
        combined({**MODULES, "combined": {"colour": 1}}, dict(TINY), ctx)
    assert e.value.key == "params.combined"


def test_paper_social_figure_runs_the_paper_variant_at_a_tiny_budget(tmp_path):
    res = reproduce(tmp_path / "out", only="paper_fig4_social_humans", budget="quick",
                    progress=False, log=None)
    entry = res.entry("paper_fig4_social_humans")
    assert entry["status"] == "ok", entry.get("error")
    m = entry["metrics"]
    for h in ("H1", "H2", "H3"):
        for k in ("plateau", "at_5k", "at_10k", "at_15k", "at_25k"):
            assert f"{h}_{k}" in m
    # the runs are exactly `simlab visitlab train` in the paper variant (20-step trials)
    ref = train("social", "mb-egreedy", trials=200, seeds=2, seed=visitlab_seed(0),
                variant="paper", human="H1", progress=False)
    assert ref.config["agent_config"]["synchronous"] is True
    assert ref.config["max_steps"] == 20
    assert m["H1_plateau"] == pytest.approx(ref.returns[:, -20:].mean())
    text = (res.out / "results.md").read_text()
    assert "paper_fig4_social_humans" in text
