"""The experiment TOML schema: every shipped file loads; bad files name file and key;
check operators compare as documented."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from simlab.base.errors import ConfigError
from simlab.experiments.spec import (
    FAIL,
    NOT_CHECKED,
    PASS,
    Check,
    default_experiments_dir,
    discover_experiments,
    load_experiment,
    select,
)

GOOD = """\
name = "toy"
title = "Toy"
reference = "Thesis Fig. 0"
claim = "It works."
runner = "example.coin"

[params]
p = 0.5

[budget.quick]
seeds = 2
flips = 10

[budget.full]
seeds = 10
flips = 1000

[[expect]]
metric = "p_hat"
op = "between"
value = [0.4, 0.6]
thesis = "fair coin"
"""


def _write(tmp_path: Path, text: str, name: str = "toy.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_shipped_experiments_load_and_resolve_their_runners():
    specs = discover_experiments(resolve_runner=True)
    names = [s.name for s in specs]
    assert {"fig4_8_entropy", "fig4_9_empirical_training", "fig4_10_replay"} <= set(names)
    assert len(names) == len(set(names))
    for s in specs:
        assert s.path is not None and s.path.parent == default_experiments_dir()
        assert s.budget("quick")["seeds"] >= 1 and s.budget("full")["seeds"] >= 1
        for c in s.checks:
            assert c.thesis


def test_natural_order_puts_fig4_10_after_fig4_9():
    names = [s.name for s in discover_experiments()]
    physics = [n for n in names if n.startswith(("fig4_8", "fig4_9", "fig4_10"))]
    assert physics == ["fig4_8_entropy", "fig4_9_empirical_training", "fig4_10_replay"]


def test_good_file_parses(tmp_path):
    spec = load_experiment(_write(tmp_path, GOOD), resolve_runner=True)
    assert spec.name == "toy" and spec.runner == "example.coin"
    assert spec.params == {"p": 0.5}
    assert spec.budget("quick") == {"seeds": 2, "flips": 10}
    (check,) = spec.checks
    assert check.op == "between" and check.value == (0.4, 0.6)
    assert check.budgets == ("quick", "full")


@pytest.mark.parametrize(
    ("old", "new", "key"),
    [
        ('name = "toy"\n', "", "name"),
        ('runner = "example.coin"\n', "", "runner"),
        ('title = "Toy"\n', 'title = ""\n', "title"),
        ('name = "toy"\n', 'name = "Bad Name"\n', "name"),
        ("[budget.full]\nseeds = 10\n", "[budget.full]\n", "budget.full.seeds"),
        ("[budget.quick]\nseeds = 2\n", "[budget.quick]\nseeds = 0\n", "budget.quick.seeds"),
        ('op = "between"\n', 'op = "almost"\n', "expect[0].op"),
        ('thesis = "fair coin"\n', "", "expect[0].thesis"),
        ("value = [0.4, 0.6]\n", "value = [0.6, 0.4]\n", "expect[0].value"),
        ("value = [0.4, 0.6]\n", 'value = "x"\n', "expect[0].value"),
        ('thesis = "fair coin"\n', 'thesis = "fair coin"\nbudgets = ["slow"]\n',
         "expect[0].budgets"),
        ('runner = "example.coin"\n', 'runner = "coin"\n', "runner"),
    ],
)
def test_bad_files_name_the_file_and_key(tmp_path, old, new, key):
    assert old in GOOD
    path = _write(tmp_path, GOOD.replace(old, new, 1))
    with pytest.raises(ConfigError) as err:
        load_experiment(path)
    assert err.value.path == str(path)
    assert err.value.key == key
    assert str(path) in str(err.value) and key in str(err.value)


def test_missing_budget_table_and_unknown_keys(tmp_path):
    text = GOOD.replace("[budget.full]\nseeds = 10\nflips = 1000\n", "")
    with pytest.raises(ConfigError) as err:
        load_experiment(_write(tmp_path, text))
    assert err.value.key == "budget.full"
    with pytest.raises(ConfigError, match="unknown key"):
        load_experiment(_write(tmp_path, "titel = 'x'\n" + GOOD))
    with pytest.raises(ConfigError) as err:
        load_experiment(_write(tmp_path, GOOD + "[budget.medium]\nseeds = 3\n"))
    assert err.value.key == "budget"
    with pytest.raises(ConfigError) as err:
        load_experiment(_write(tmp_path, GOOD.replace('thesis = "fair coin"\n',
                                                      'thesis = "fair coin"\ntol = 0.1\n')))
    assert err.value.key == "expect[0]"


@pytest.mark.parametrize(
    ("runner", "problem"),
    [("nosuchgroup.x", "no runner group"), ("example.nosuch", "unknown runner")],
)
def test_unknown_runner_names_the_file(tmp_path, runner, problem):
    path = _write(tmp_path, GOOD.replace("example.coin", runner))
    load_experiment(path)  # the key's syntax is fine; only resolving finds it missing
    with pytest.raises(ConfigError) as err:
        load_experiment(path, resolve_runner=True)
    assert err.value.path == str(path) and err.value.key == "runner"
    assert problem in str(err.value)


def test_not_toml_and_duplicate_names(tmp_path):
    with pytest.raises(ConfigError, match="not valid TOML") as err:
        load_experiment(_write(tmp_path, "name = \n"))
    assert err.value.path is not None
    d = tmp_path / "dir"
    d.mkdir()
    _write(d, GOOD, "a.toml")
    _write(d, GOOD, "b.toml")
    with pytest.raises(ConfigError, match="also used by") as err:
        discover_experiments(d)
    assert err.value.key == "name"


def test_select_only(tmp_path):
    d = tmp_path / "dir"
    d.mkdir()
    _write(d, GOOD, "a.toml")
    _write(d, GOOD.replace('name = "toy"', 'name = "other"'), "b.toml")
    specs = discover_experiments(d)
    assert [s.name for s in select(specs, "toy")] == ["toy"]
    assert [s.name for s in select(specs, None)] == ["other", "toy"]
    with pytest.raises(ConfigError, match="unknown experiment"):
        select(specs, "toy,nope")


# ----------------------------------------------------------------------------- checks


def _c(op, value, **kw):
    return Check(metric="m", op=op, value=value, thesis="t", **kw)


@pytest.mark.parametrize(
    ("check", "x", "status"),
    [
        (_c(">=", 1.0), 1.0, PASS), (_c(">=", 1.0), 0.999, FAIL),
        (_c(">", 1.0), 1.0, FAIL), (_c(">", 1.0), 1.001, PASS),
        (_c("<=", 2), 2, PASS), (_c("<", 2), 2, FAIL),
        (_c("==", 9), 9, PASS), (_c("==", 9), 8, FAIL),
        (_c("between", (1.0, 2.0)), 1.0, PASS), (_c("between", (1.0, 2.0)), 2.0, PASS),
        (_c("between", (1.0, 2.0)), 2.01, FAIL),
        (_c("approx", 10.0, tol=0.5), 10.4, PASS), (_c("approx", 10.0, tol=0.5), 10.6, FAIL),
        (_c("approx", 10.0, rel_tol=0.1), 10.9, PASS),
        (_c("approx", 10.0, rel_tol=0.1), 8.9, FAIL),
        (_c(">=", 0.0), True, PASS),
    ],
)
def test_number_operators(check, x, status):
    assert check.evaluate({"m": x}, "quick").status == status


def test_metric_operators_with_factor():
    c = _c("greater_than_metric", "base", factor=5.0)
    out = c.evaluate({"m": 10.1, "base": 2.0}, "full")
    assert out.status == PASS and out.ours == 10.1 and out.detail == "10.1 vs 10"
    assert c.evaluate({"m": 10.0, "base": 2.0}, "full").status == FAIL
    assert c.evaluate({"m": 10.0, "base": None}, "full").status == FAIL
    assert c.describe() == "m > 5 × base"
    lt = _c("less_than_metric", "base")
    assert lt.evaluate({"m": 1.0, "base": 2.0}, "full").status == PASS
    assert lt.evaluate({"m": 2.0, "base": 2.0}, "full").status == FAIL


def test_missing_or_empty_metrics_fail_and_budgets_are_respected():
    c = _c(">=", 0.0)
    assert c.evaluate({}, "quick").status == FAIL
    assert c.evaluate({"m": None}, "quick").status == FAIL
    assert c.evaluate({"m": math.nan}, "quick").status == FAIL
    full_only = _c(">=", 0.0, budgets=("full",))
    out = full_only.evaluate({"m": -1.0}, "quick")
    assert out.status == NOT_CHECKED and out.ours == -1.0
    assert full_only.evaluate({"m": -1.0}, "full").status == FAIL


def test_results_table_shows_both_sides_of_a_metric_comparison():
    from simlab.experiments.report import render_results

    c = Check(metric="rate", op="greater_than_metric", value="random", thesis="beats random",
              factor=5.0)
    o = c.evaluate({"rate": 12.0, "random": 3.0}, "full")
    entry = {"name": "x", "title": "T", "reference": "Fig. 1", "claim": "C", "runner": "a.b",
             "budget": "full", "status": "ok", "metrics": {"rate": 12.0, "random": 3.0},
             "checks": [{"metric": "rate", "check": c.describe(), "thesis": c.thesis,
                         "op": c.op, "status": o.status, "ours": o.ours, "detail": o.detail}],
             "figures": [], "notes": []}
    md = render_results({"seed": 0}, [entry])
    row = next(line for line in md.splitlines() if "beats random" in line)
    assert "`rate > 5 × random`" in row and "| 12 vs 15 |" in row and "**FAIL**" in row
