"""``simlab calibrate-pool``: several calibrations of one lab read together (kinematic)."""

from __future__ import annotations

import json
import math
import re
import shutil
import tomllib
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from simlab.base.actions import parse_action_set
from simlab.base.errors import ConfigError
from simlab.calibration.config import RealTable
from simlab.calibration.pool import (
    OPEN_SHARE,
    PooledField,
    _merge,
    _transfer_markdown,
    pool_command,
    pool_transfer,
    range_share,
    read_run,
)
from simlab.calibration.profile import Profile, told_band
from simlab.calibration.space import ParameterSpace, ParamSpec
from simlab.cli import main
from simlab.data.walkers import KinematicParams
from tests.calibration.conftest import hidden_walk, write_counts_csv
from tests.calibration.test_transfer import lattice, lattice_counts

CCW8 = parse_action_set(8, "ccw-east")


def test_merge_keeps_disjoint_spans_and_the_open_ends_of_the_spans_that_hold_them() -> None:
    spans = [(0.5, 0.9, False, True), (0.0, 0.2, True, False), (0.1, 0.4, False, False)]
    assert _merge(spans) == ((0.0, 0.4, True, False), (0.5, 0.9, False, True))
    # a span inside another adds nothing; a shared end stays open if either is open there
    assert _merge([(0.0, 1.0, False, False), (0.2, 0.3, True, True)]) == (
        (0.0, 1.0, False, False),)
    assert _merge([(0.0, 1.0, False, False), (0.5, 1.0, False, True)]) == (
        (0.0, 1.0, False, True),)
    f = PooledField("x", False, (0.1, 0.6), (), _merge(spans))
    assert [f.admits(v) for v in (-5.0, 0.3, 0.45, 0.7, 7.0)] == [True, True, False, True, True]
    g = PooledField("m", True, ("a",), (("a",), ("b",)), ("a", "b"))
    assert g.admits("b") and not g.admits("c")
    assert PooledField("y", False, (), (None,), None).admits(0.0) is None


def test_range_share_measures_the_union_in_the_units_the_search_samples() -> None:
    lin = ParamSpec("x", 0.0, 2.0)
    assert range_share(lin, ((0.0, 0.4, False, False), (1.0, 1.8, False, False))) == (
        pytest.approx(0.6))
    # an open end reaches the range's edge, a value past the range counts to its edge only
    assert range_share(lin, ((1.0, 1.5, False, True),)) == pytest.approx(0.5)
    assert range_share(lin, ((-3.0, 0.5, False, False),)) == pytest.approx(0.25)
    log = ParamSpec("hz", 1.0, 100.0, "log")
    assert range_share(log, ((1.0, 10.0, True, False),)) == pytest.approx(0.5)
    cat = ParamSpec("m", choices=("a", "b", "c", "d"))
    assert range_share(cat, ("a", "c")) == 0.5
    assert range_share(lin, None) is None


def test_the_pool_transfer_scores_each_winner_and_draws_the_ensemble_walk_by_walk() -> None:
    """Run 0 walks as the robot (the truth sampled), run 1 always stays; run 2's walks are
    run 0's first and run 1's second: what the ensemble of runs 0 and 1 draws on two seeds."""
    rng = np.random.default_rng(5)
    truth = lattice_counts(CCW8, n=1000, success=0.6) / 1000.0
    setup = SimpleNamespace(real=RealTable(rng.multinomial(12, truth), CCW8),
                            goals=list(range(9)), disc=lattice())
    w1, w2 = rng.multinomial(24, truth), rng.multinomial(24, truth)
    stays = np.zeros_like(w1)
    stays[np.arange(9), :, np.arange(9)] = 24
    walks = [[w1, w2], [stays, stays], [w1, stays]]
    t = pool_transfer(setup, walks, 0, [0, 1], "stay", np.random.default_rng(1))
    assert t is not None and t.goals == tuple(range(9)) and t.left_out == ()
    assert t.transitions == int((w1 + w2).sum()) == t.perfect.transitions
    # the truth sampled scores as a perfect twin with its data, within the line's resamples
    line = t.perfect.overall[np.isfinite(t.perfect.overall)]
    assert line.size >= 15 and line.min() - 0.02 <= t.ratios[0] <= line.max() + 0.02
    assert math.isinf(t.ratios[1])                     # planned on stays: never arrives
    assert t.ensemble == (0, 1) and t.ensemble_ratio == t.ratios[2]
    json.dumps(t.to_json(), allow_nan=False)           # inf is written as null
    assert t.to_json()["ratios"][1] is None
    # pool.md reads the ensemble against the pool's winner, "never arrives" for inf
    res = SimpleNamespace(transfer=t, seeds=(1, 2), best=0,
                          runs=[SimpleNamespace(path=Path(f"run{i}")) for i in range(3)])
    md = "\n".join(_transfer_markdown(res))
    assert "| 1 | run1 | never arrives |" in md and "#0, #1 in turn" in md
    res.transfer = replace(t, ratios=(1.2, math.inf, 1.3), ensemble_ratio=1.1)
    assert ": 1.100, lower than the pool's winner's 1.200." in "\n".join(_transfer_markdown(res))
    res.transfer = replace(t, ratios=(math.inf,) * 3, ensemble_ratio=math.inf)
    assert ": never arrives, as the pool's winner's." in "\n".join(_transfer_markdown(res))
    alone = pool_transfer(setup, walks, 0, [0], "stay", np.random.default_rng(1))
    assert alone is not None and alone.ensemble == () and alone.ensemble_ratio is None
    # a goal no real transition ends in is left out; none reached: no transfer
    never = setup.real.counts.copy()
    never[:, :, 4] = 0
    cut = SimpleNamespace(real=RealTable(never, CCW8), goals=[4, 8], disc=lattice())
    t = pool_transfer(cut, walks, 0, [0], "stay", np.random.default_rng(1))
    assert t is not None and t.goals == (8,) and t.left_out == (4,)
    cut = SimpleNamespace(real=RealTable(never, CCW8), goals=[4], disc=lattice())
    assert pool_transfer(cut, walks, 0, [0], "stay", np.random.default_rng(1)) is None


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory, lattice9) -> dict[str, Path]:
    """A hidden kinematic walk and two profiled calibrations of it (seeds 0 and 7)."""
    d = tmp_path_factory.mktemp("pool")
    states = d / "states.json"
    lattice9.save(states)
    sim = hidden_walk(lattice9, KinematicParams(drive_time=0.9), CCW8, 1.0, 4, "kinematic")
    real = write_counts_csv(d / "real.csv", sim.counts)
    runs = []
    for seed in (0, 7):
        out = d / f"cal{seed}"
        assert main(["calibrate", "--real", str(real), "--states", str(states), "--out",
                     str(out), "--simulator", "kinematic", "--n-actions", "8", "--convention",
                     "ccw-east", "--hours-per-candidate", "0.5", "--candidates", "3",
                     "--workers", "1", "--n-boot", "20", "--no-progress", "--real-hours",
                     f"{sim.hours}", "--transfer-seeds", "2", "--profile-step", "0.25",
                     "--seed", str(seed)]) == 0
        runs.append(out)
    return {"real": real, "states": states, "run0": runs[0], "run7": runs[1], "dir": d}


def _pool(lab: dict[str, Path], runs: list[Path], out: Path, **kw):
    kw = {"real": lab["real"], "seeds": 2, **kw}
    return pool_command(runs=tuple(runs), states=lab["states"], out=out, workers=1,
                        progress=False, **kw)


def test_pool_walks_every_winner_on_the_same_fresh_seeds_and_unions_what_they_allow(
        lab, tmp_path, capsys) -> None:
    runs = [lab["run0"], lab["run7"]]
    # a copy of a run walks exactly as the run (common random numbers): the copy of the
    # best joins it with no gap
    copies = [tmp_path / "copy0", tmp_path / "copy7"]
    for run, copy in zip(runs, copies, strict=True):
        shutil.copytree(run, copy)
    _as_an_old_report(copies[1])  # its profile read with the normal band, no dof kept
    # a run whose winner is moved far from the data: worse than sampling, left out
    bad = tmp_path / "bad"
    shutil.copytree(lab["run7"], bad)
    doc = (bad / "primitives.toml").read_text()
    moved = re.sub(r"(?m)^drive_time = .*$", "drive_time = 0.05", doc, count=1)
    assert moved != doc
    (bad / "primitives.toml").write_text(moved)
    out = tmp_path / "pool"
    assert main(["calibrate-pool", "--runs", *map(str, [*runs, *copies, bad]), "--real",
                 str(lab["real"]), "--states", str(lab["states"]), "--out", str(out),
                 "--seeds", "2", "--workers", "1", "--no-progress"]) == 0
    printed = capsys.readouterr().out
    assert "runs within sampling of the best" in printed
    assert sorted(p.name for p in out.iterdir()) == ["pool.json", "pool.md", "primitives.toml"]
    rep = json.loads((out / "pool.json").read_text())
    scores = np.array([r["scores"] for r in rep["runs"]])
    assert rep["seeds"] == [100_000, 100_001]
    assert np.array_equal(scores[:2], scores[2:4])            # the copies: the same walks
    mean = scores.mean(axis=1)
    assert rep["best"] == int(np.argmin(mean))
    # five runs of two walks each: five degrees of freedom behind the spread (Student's t)
    assert rep["dof"] == 5 and rep["band"] == pytest.approx(told_band(5))
    assert rep["limit"] == pytest.approx(told_band(5) * rep["sigma"] / np.sqrt(2))
    joined = [i for i in range(5) if mean[i] - mean[rep["best"]] <= rep["limit"]]
    assert rep["joined"] == sorted(joined, key=lambda i: (mean[i], i))
    assert {rep["best"], rep["best"] + 2} <= set(rep["joined"]) and 4 not in rep["joined"]
    assert (0 in rep["joined"]) == (2 in rep["joined"])      # a copy as its original
    assert mean[4] > mean[rep["best"]] + rep["limit"]
    # the old report's profile was re-read with Student's band for its two twin walks
    assert any("re-read with Student's band" in n and f"{copies[1]} (2 walks)" in n
               for n in rep["notes"])
    # every joined run's allowed values lie in the union, field by field
    for f in rep["fields"]:
        assert len(f["spans"]) == len(rep["joined"]) and f["allowed"]
        for lo, hi, _, _ in f["spans"]:
            assert any(a <= lo + 1e-12 and hi <= b + 1e-12 for a, b, _, _ in f["allowed"])
    # the pool's winner is [primitives]; each joined winner an [[ensemble]] member
    toml = tomllib.loads((out / "primitives.toml").read_text())
    best = rep["runs"][rep["best"]]["path"]
    winner = tomllib.loads((Path(best) / "primitives.toml").read_text())["primitives"]
    assert toml["primitives"] == winner
    members = toml["ensemble"]
    assert len(members) == len(rep["joined"]) and members[0] == winner
    assert (out / "pool.md").read_text().startswith("# Pool of 5 calibrations")
    # the pool's distances also against a twin equal to the robot at one pool walk
    pf = rep["perfect_twin_floor"]
    assert pf > 0 and toml["calibration"]["perfect_twin_floor_median"] == pytest.approx(pf)
    d_best = np.array([r["distances"] for r in rep["runs"]])[rep["best"]].mean()
    assert f"{d_best / pf:.2f}x a twin equal to the robot" in printed
    assert f"a twin equal to the robot would lie {pf:.4f}" in (out / "pool.md").read_text()
    # the copies' policies score as their originals'; the ensemble draws the joined in turn
    t = rep["transfer"]
    assert t["ratios"][:2] == t["ratios"][2:4] and len(t["ratios"]) == 5
    m = len(rep["joined"])
    assert t["ensemble_runs"] == [rep["joined"][j % m] for j in range(2)]
    assert "## Policies on the real model" in (out / "pool.md").read_text()
    # each winner's pool walks tested pair by pair: a copy lists what its original lists,
    # and the pairs every run lists are those in each run's list
    c = rep["contradictions"]
    assert len(c["runs"]) == 5 and c["runs"][:2] == c["runs"][2:4]
    each = [{(r["state"], r["action"]) for r in run["pairs"]} for run in c["runs"]]
    assert {tuple(p) for p in c["common"]} == set.intersection(*each)
    assert "## Where every winner contradicts the robot" in (out / "pool.md").read_text()
    # several joined runs: no "one basin" sentence, in pool.md or on the terminal
    assert "one basin" not in (out / "pool.md").read_text() and "one basin" not in printed
    # the same pool again: the same walks, bit for bit
    again = _pool(lab, [*runs, *copies, bad], tmp_path / "again").result
    assert np.array_equal(again.scores, scores)
    # the union covers at least the widest joined span's share of the range; pool.md names
    # the fields it leaves open, and only those
    line = next((x for x in (out / "pool.md").read_text().splitlines()
                 if x.startswith("Left open")), "")
    named = line.split(": ", 1)[1].split(". ")[0].split(", ") if line else []
    for f, spec in zip(rep["fields"], again.space.specs, strict=True):
        if not spec.categorical:
            widest = max(range_share(spec, (tuple(sp),)) for sp in f["spans"])
            assert widest - 1e-12 <= f["share"] <= 1.0 + 1e-12
        assert (f["field"] in named) == (f["share"] >= OPEN_SHARE)


def test_a_pair_no_winner_reproduces_is_listed_by_every_run(lab, tmp_path,
                                                             capsys) -> None:
    # The real table given to the pool doctored at its busiest pair (the same transitions
    # in all: where the robot mostly stayed it now always moves to another state): both
    # winners stay there as the robot did when they were calibrated, so both list it, and
    # pool.md names it among the pairs every run lists.
    counts = np.zeros((9, 8, 9), dtype=np.int64)
    for s, a, s2, n in np.loadtxt(lab["real"], delimiter=",", skiprows=1, dtype=np.int64):
        counts[s, a, s2] = n
    n = counts.sum(axis=2)
    s, a = np.unravel_index(np.argmax(n), n.shape)
    assert counts[s, a, s] >= n[s, a] / 2
    counts[s, a] = 0
    counts[s, a, (s + 1) % 9] = n[s, a]
    doctored = write_counts_csv(tmp_path / "doctored.csv", counts)
    out = tmp_path / "pool"
    assert main(["calibrate-pool", "--runs", str(lab["run0"]), str(lab["run7"]), "--real",
                 str(doctored), "--states", str(lab["states"]), "--out", str(out),
                 "--seeds", "2", "--workers", "1", "--no-progress"]) == 0
    assert f" {s} a{a}" in capsys.readouterr().out.split("contradicts beyond sampling")[1]
    res = _pool(lab, [lab["run0"], lab["run7"]], tmp_path / "again", real=doctored).result
    assert (s, a) in res.common_contradictions
    for c in res.contradictions:
        row = next(r for r in c.pairs if (r["state"], r["action"]) == (s, a))
        assert row["stay_real"] == 0.0 and row["stay_twin"] > 0.5
    md = (tmp_path / "pool" / "pool.md").read_text()
    assert "pairs are listed by every run" in md and f"| {s} | {a} | {n[s, a]} | 0.00 |" in md


def test_a_pool_that_joins_only_its_winner_says_it_is_one_basin(lab, tmp_path,
                                                                 capsys) -> None:
    """A run moved far from the data is left out: the union is the winner's profile alone,
    and pool.md and the command say so."""
    bad = tmp_path / "bad"
    shutil.copytree(lab["run7"], bad)
    doc = (bad / "primitives.toml").read_text()
    (bad / "primitives.toml").write_text(
        re.sub(r"(?m)^drive_time = .*$", "drive_time = 0.05", doc, count=1))
    out = tmp_path / "pool"
    assert main(["calibrate-pool", "--runs", str(lab["run0"]), str(bad), "--real",
                 str(lab["real"]), "--states", str(lab["states"]), "--out", str(out),
                 "--seeds", "2", "--workers", "1", "--no-progress"]) == 0
    rep = json.loads((out / "pool.json").read_text())
    assert rep["joined"] == [0]
    assert "its profile alone, one basin" in (out / "pool.md").read_text()
    assert "its profile alone, one basin" in capsys.readouterr().out


def _as_an_old_report(run: Path) -> None:
    """Rewrite ``run``'s report as calibrate wrote it before the profile kept its spread's
    degrees of freedom: no ``dof``, each field told and bounded with the normal band."""
    rep = json.loads((run / "report.json").read_text())
    space = ParameterSpace.from_json(rep["space"])
    old = Profile.from_json(rep["profile"]).restated(space, None).to_json()
    del old["dof"]
    rep["profile"] = old
    (run / "report.json").write_text(json.dumps(rep))


def test_an_old_report_is_read_with_students_band_for_its_walks(lab, tmp_path) -> None:
    """A profile written before the degrees of freedom were kept (read with the normal band)
    is re-read as calibrate now writes it: the same moves, Student's band for the walks its
    spread came from (the two twin walks), so every field's verdict, allowed values and open
    sides equal the current report's."""
    new = read_run(lab["run7"])
    assert new.restated is None and new.profile is not None and new.profile.dof == 1
    old = tmp_path / "old"
    shutil.copytree(lab["run7"], old)
    _as_an_old_report(old)
    stored = Profile.from_json(json.loads((old / "report.json").read_text())["profile"])
    assert stored.dof is None and stored.band == pytest.approx(told_band(None))
    back = read_run(old)
    assert back.restated == 2 and back.profile == new.profile
    # the normal band is narrower: the old statement allowed no more than the new one
    for f, g in zip(stored.fields, new.profile.fields, strict=True):
        if f.allowed is not None and not isinstance(f.value, str):
            assert g.allowed[0] <= f.allowed[0] + 1e-12 and f.allowed[1] <= g.allowed[1] + 1e-12


def test_pool_refuses_before_any_walk(lab, tmp_path) -> None:
    run0, run7 = lab["run0"], lab["run7"]
    with pytest.raises(ConfigError, match="needs two or more"):
        _pool(lab, [run0], tmp_path / "a")
    with pytest.raises(ConfigError, match="given twice"):
        _pool(lab, [run0, run0], tmp_path / "a")
    with pytest.raises(ConfigError, match=r"no report\.json"):
        _pool(lab, [run0, tmp_path], tmp_path / "a")
    with pytest.raises(ConfigError, match="walked by this calibration"):
        _pool(lab, [run0, run7], tmp_path / "a", first_seed=6)
    with pytest.raises(ConfigError, match="seeds"):
        _pool(lab, [run0, run7], tmp_path / "a", seeds=1)
    other = tmp_path / "other"
    shutil.copytree(run7, other)
    rep = json.loads((other / "report.json").read_text())
    rep["config"]["objective"] = "tv"
    (other / "report.json").write_text(json.dumps(rep))
    with pytest.raises(ConfigError, match="objective"):
        _pool(lab, [run0, other], tmp_path / "a")
    # another real table than the runs'
    short = lab["dir"] / "short.csv"
    lines = lab["real"].read_text().splitlines()
    short.write_text("\n".join(lines[:-3]) + "\n")
    with pytest.raises(ConfigError, match="the runs were calibrated against"):
        _pool(lab, [run0, run7], tmp_path / "a", real=short)
    with pytest.raises(ConfigError, match="the options say"):
        _pool(lab, [run0, run7], tmp_path / "a", n_actions=16)
    assert not (tmp_path / "a").exists()
    # an output of someone else is never replaced, even with --overwrite
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "pool.md").write_text("my notes\n")
    with pytest.raises(ConfigError, match="already exists"):
        _pool(lab, [run0, run7], tmp_path / "b")
    with pytest.raises(ConfigError, match="not written by simlab calibrate-pool"):
        _pool(lab, [run0, run7], tmp_path / "b", overwrite=True)
    assert (tmp_path / "b" / "pool.md").read_text() == "my notes\n"
    assert main(["calibrate-pool", "--runs", str(run0), "--real", str(lab["real"]),
                 "--states", str(lab["states"]), "--out", str(tmp_path / "c")]) == 2
