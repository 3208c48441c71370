"""``simlab visitlab`` end to end with tiny budgets."""

from __future__ import annotations

import json

import numpy as np

from simlab.cli import main
from simlab.visitlab.results import load_results


def test_train_writes_curves_plot_and_summary(tmp_path, capsys):
    out = tmp_path / "social"
    code = main(["visitlab", "train", "--task", "social", "--agent", "q-learning,mb-egreedy",
                 "--human", "easy,hard", "--trials", "20", "--seeds", "2", "--seed", "3",
                 "--set", "epsilon=0.2", "--out", str(out), "--no-progress"])
    assert code == 0
    assert {p.name for p in out.iterdir()} == {"curves.npz", "curves.png", "summary.json"}
    assert (out / "curves.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    summary = json.loads((out / "summary.json").read_text())
    labels = [r["label"] for r in summary["runs"]]
    assert labels == ["q-learning / easy", "q-learning / hard", "mb-egreedy / easy",
                      "mb-egreedy / hard"]
    for run in summary["runs"]:
        assert run["n_seeds"] == 2 and run["n_trials"] == 20
        assert run["config"]["agent_config"]["epsilon"] == 0.2
        assert run["config"]["seed"] == 3
    runs = load_results(out / "curves.npz")
    assert [r.label for r in runs] == labels
    assert runs[0].returns.shape == (2, 20) and runs[0].q.shape == (2, 2560, 30)
    assert runs[1].config["human"]["name"] == "hard"
    assert "plateau" in capsys.readouterr().out


def test_train_is_reproducible_and_refuses_to_overwrite(tmp_path, capsys):
    args = ["visitlab", "train", "--task", "gotohuman", "--episode", "fixed_positions",
            "--agent", "vi-softmax", "--trials", "15", "--seeds", "2", "--no-progress"]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    assert main([*args, "--out", str(tmp_path / "b")]) == 0
    a = load_results(tmp_path / "a" / "curves.npz")[0]
    b = load_results(tmp_path / "b" / "curves.npz")[0]
    np.testing.assert_array_equal(a.returns, b.returns)
    np.testing.assert_array_equal(a.q, b.q)
    before = (tmp_path / "a" / "summary.json").read_bytes()
    assert main([*args, "--out", str(tmp_path / "a")]) == 2
    assert "already exists" in capsys.readouterr().err
    assert (tmp_path / "a" / "summary.json").read_bytes() == before
    assert main([*args, "--out", str(tmp_path / "a"), "--overwrite", "--seed", "1"]) == 0
    assert (tmp_path / "a" / "summary.json").read_bytes() != before


def test_train_reports_bad_input_in_one_line(tmp_path, capsys):
    base = ["visitlab", "train", "--trials", "2", "--seeds", "1", "--no-progress",
            "--out", str(tmp_path / "x")]
    assert main([*base, "--agent", "sarsa"]) == 2
    assert "unknown agent" in capsys.readouterr().err
    assert main([*base, "--human", "grumpy"]) == 2
    assert "unknown human" in capsys.readouterr().err
    assert main([*base, "--set", "epsilon"]) == 2
    assert "KEY=VALUE" in capsys.readouterr().err
    assert main([*base, "--task", "nav", "--human", "easy"]) == 2
    assert "no human" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_show_prints_frames_and_uses_a_trained_q(tmp_path, capsys):
    assert main(["visitlab", "show", "--task", "social", "--human", "medium", "--steps", "3",
                 "--seed", "1", "--png", str(tmp_path / "f.png")]) == 0
    text = capsys.readouterr().out
    assert text.count("action ") == 3 and "level=" in text
    assert (tmp_path / "f.png").read_bytes()[:4] == b"\x89PNG"
    out = tmp_path / "nav"
    assert main(["visitlab", "train", "--task", "nav", "--agent", "mb-egreedy", "--trials",
                 "400", "--seeds", "1", "--out", str(out), "--no-progress"]) == 0
    capsys.readouterr()
    assert main(["visitlab", "show", "--task", "nav", "--q", str(out / "curves.npz")]) == 0
    text = capsys.readouterr().out
    # the greedy policy of a trained agent ends the 50-step trial with most steps rewarded
    totals = [float(line.split("total ")[1]) for line in text.splitlines() if "total " in line]
    assert len(totals) == 50 and totals[-1] >= 40


def test_plot_combines_curves_files(tmp_path, capsys):
    for name in ("a", "b"):
        assert main(["visitlab", "train", "--task", "gotohuman", "--agent", "q-learning",
                     "--trials", "10", "--seeds", "1", "--seed", "1" if name == "a" else "2",
                     "--out", str(tmp_path / name), "--no-progress"]) == 0
    capsys.readouterr()
    png = tmp_path / "both.png"
    assert main(["visitlab", "plot", str(tmp_path / "a" / "curves.npz"),
                 str(tmp_path / "b" / "curves.npz"), "--labels", "first,second",
                 "--out", str(png)]) == 0
    out = capsys.readouterr().out
    assert "first: plateau" in out and "second: plateau" in out
    assert png.read_bytes()[:4] == b"\x89PNG"
    assert main(["visitlab", "plot", str(tmp_path / "a" / "curves.npz"), "--labels", "x,y",
                 "--out", str(tmp_path / "c.png")]) == 2
    assert "labels" in capsys.readouterr().err
    assert main(["visitlab", "plot", str(tmp_path / "a" / "summary.json"),
                 "--out", str(tmp_path / "d.png")]) == 2
    assert "not a Visit-the-lab curves file" in capsys.readouterr().err


def test_combined_runs_trained_modules_and_writes_a_gif(tmp_path, capsys):
    common = ["--seeds", "1", "--no-progress"]
    assert main(["visitlab", "train", "--task", "nav", "--agent", "rmax", "--start", "random",
                 "--goal", "random", "--trials", "300", *common,
                 "--out", str(tmp_path / "nav")]) == 0
    assert main(["visitlab", "train", "--task", "social", "--agent", "mb-egreedy",
                 "--human", "easy", "--trials", "300", *common,
                 "--out", str(tmp_path / "soc")]) == 0
    assert main(["visitlab", "train", "--task", "gotohuman", "--agent", "mb-egreedy",
                 "--trials", "100", *common, "--out", str(tmp_path / "gth")]) == 0
    capsys.readouterr()
    args = ["visitlab", "combined", "--nav", str(tmp_path / "nav" / "curves.npz"),
            "--social", str(tmp_path / "soc" / "curves.npz"),
            "--gotohuman", str(tmp_path / "gth" / "curves.npz"), "--trials", "5",
            "--steps", "30", "--gif", str(tmp_path / "ep.gif")]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "goal rooms per 30-step trial" in out and "human 'easy'" in out
    assert (tmp_path / "ep.gif").read_bytes()[:6] in (b"GIF89a", b"GIF87a")
    assert main(args) == 2  # the GIF exists
    assert "already exists" in capsys.readouterr().err
    # modules given in the wrong order: the file, the module it holds and where it goes
    for option, wrong, home in (("--nav", "gth", "--gotohuman"), ("--nav", "soc", "--social"),
                                ("--social", "nav", "--nav")):
        swapped = [*args]
        swapped[swapped.index(option) + 1] = str(tmp_path / wrong / "curves.npz")
        assert main([*swapped, "--overwrite"]) == 2
        err = capsys.readouterr().err
        assert str(tmp_path / wrong / "curves.npz") in err and f"{option}:" in err, err
        assert f"give this file to {home}" in err and len(err.strip().splitlines()) == 1


def test_start_and_goal_are_navigation_options(tmp_path, capsys):
    assert main(["visitlab", "train", "--task", "social", "--start", "random", "--trials", "2",
                 "--seeds", "1", "--no-progress", "--out", str(tmp_path / "x")]) == 2
    assert "start" in capsys.readouterr().err
