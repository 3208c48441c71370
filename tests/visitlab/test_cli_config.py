"""``simlab visitlab``'s options as CommandConfigs: the environment group shared by train
and show, --config FILE under the command line, --help defaults, unknown keys refused
naming file and key, and train / train_command by config or by fields alike."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest

import simlab.commands as commands
from simlab.base.errors import ConfigError
from simlab.cli import main
from simlab.cli.visitlab import add_arguments, train_config_from_args
from simlab.visitlab.combined import CombinedConfig
from simlab.visitlab.results import PlotConfig
from simlab.visitlab.training import (
    ShowConfig,
    TrainRuns,
    VisitlabEnvOptions,
    VisitlabTrainConfig,
    train,
    train_command,
)


def _parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    return parser.parse_args(argv)


def test_train_and_show_share_the_environment_group():
    for cls in (VisitlabTrainConfig, ShowConfig):
        assert issubclass(cls, VisitlabEnvOptions)
    nav = ShowConfig(task="nav", start="3", goal="random", steps=20, layout_seed=2)
    assert nav.env_kwargs() == {"layout_seed": 2, "start": 3, "goal": "random",
                                "max_steps": 20}
    social = VisitlabTrainConfig(human="easy, hard", out="o", layout="lab")
    assert social.humans() == ["easy", "hard"]
    assert social.env_kwargs("hard") == {"layout": "lab", "human": "hard"}
    assert VisitlabEnvOptions().humans() == [None] and VisitlabEnvOptions().env_kwargs() == {}
    refused = [({"task": "social", "start": "random"}, "--start"),
               ({"task": "nav", "episode": "fixed"}, "--episode"),
               ({"task": "nav", "human": "easy"}, "--human"),
               ({"human": "grumpy"}, "human"), ({"steps": 0}, "steps"), ({"seed": -1}, "seed")]
    for fields, key in refused:
        with pytest.raises(ConfigError) as info:
            VisitlabEnvOptions(**fields)
        assert info.value.key == key, fields


def test_train_config_file_and_command_line(tmp_path):
    toml = tmp_path / "t.toml"
    toml.write_text('task = "nav"\nagent = "q-learning"\ntrials = 5\nseeds = 1\n'
                    'progress = false\nout = "from-file"\nset = ["epsilon=0.3", "alpha=0.5"]\n')
    cfg = train_config_from_args(_parse(["train", "--config", str(toml), "--trials", "7",
                                         "--set", "epsilon=0.2", "--out", str(tmp_path / "o")]))
    assert (cfg.task, cfg.agent, cfg.trials, cfg.seeds, cfg.progress) == (
        "nav", "q-learning", 7, 1, False)
    assert cfg.out == tmp_path / "o" and cfg.agent_overrides == {"epsilon": 0.2, "alpha": 0.5}
    table = tmp_path / "table.toml"
    table.write_text('out = "x"\n[agent_overrides]\nplan_every = 100\n')
    assert VisitlabTrainConfig.from_toml(table).agent_overrides == {"plan_every": 100}
    assert VisitlabTrainConfig.from_toml(toml).agent_overrides == {"epsilon": 0.3, "alpha": 0.5}


def test_train_cli_from_a_config_file(tmp_path, capsys):
    toml = tmp_path / "t.toml"
    toml.write_text('task = "gotohuman"\nagent = "q-learning"\ntrials = 4\nseeds = 1\n'
                    'progress = false\nset = ["epsilon=0.3"]\n')
    out = tmp_path / "o"
    assert main(["visitlab", "train", "--config", str(toml), "--trials", "6",
                 "--set", "epsilon=0.2", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "q-learning: plateau" in text and f"wrote {out / 'curves.npz'}" in text
    (run,) = json.loads((out / "summary.json").read_text())["runs"]
    assert run["n_trials"] == 6 and run["config"]["agent_config"]["epsilon"] == 0.2


def test_show_combined_and_plot_read_config_files(tmp_path, capsys):
    toml = tmp_path / "s.toml"
    toml.write_text('task = "nav"\nsteps = 5\nseed = 1\n')
    assert main(["visitlab", "show", "--config", str(toml), "--steps", "2"]) == 0
    assert capsys.readouterr().out.count("action ") == 2
    comb = tmp_path / "c.toml"
    comb.write_text('nav = "n.npz"\nsocial = "s.npz"\ngotohuman = "g.npz"\n'
                    'weights = [0.2, 0.3, 0.5]\ngif = "./ep.gif"\n')
    cfg = CombinedConfig.from_args(_parse(["combined", "--config", str(comb), "--trials", "3"]))
    assert cfg.speed_weights() == (0.2, 0.3, 0.5) and cfg.trials == 3 and cfg.gif == "./ep.gif"
    assert CombinedConfig(nav="n", social="s", gotohuman="g").speed_weights() == (0.1, 0.1, 0.8)
    with pytest.raises(ConfigError) as info:
        CombinedConfig(nav="n", social="s", gotohuman="g", weights="a,b,c")
    assert info.value.key == "--weights"
    plot = tmp_path / "p.toml"
    plot.write_text('labels = "a, b"\ntitle = "T"\nout = "p.png"\n')
    cfg = PlotConfig.from_args(_parse(["plot", "x.npz", "y.npz", "--config", str(plot),
                                       "--title", "U"]))
    assert cfg.curves == (Path("x.npz"), Path("y.npz"))
    assert (cfg.label_list(), cfg.title, cfg.out) == (["a", "b"], "U", "p.png")


def test_help_shows_the_defaults(capsys):
    expected = {"train": ("(default mb-egreedy)", "(default 10)", "(default social)",
                          "(default thesis)", "(default 1)", "--set KEY=VALUE", "--config FILE"),
                "show": ("(default social)", "(default 0)", "--seed-index"),
                "plot": ("curves.npz files", "--labels"),
                "combined": ("(default gridworld)", "(default 0.1,0.1,0.8)", "(default 100)")}
    for action, parts in expected.items():
        with pytest.raises(SystemExit):
            main(["visitlab", action, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        for part in parts:
            assert part in text, (action, part)


def test_unknown_key_names_file_and_key(tmp_path, capsys):
    toml = tmp_path / "t.toml"
    toml.write_text('task = "nav"\ntrails = 5\n')
    out = tmp_path / "o"
    assert main(["visitlab", "train", "--config", str(toml), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert str(toml) in err and "trails" in err and "trials" in err
    assert not out.exists()
    assert main(["visitlab", "show", "--config", str(toml)]) == 2
    assert "trails" in capsys.readouterr().err


def test_train_by_config_or_fields_or_the_old_call(tmp_path):
    fields = {"task": "nav", "agent": "q-learning,mb-egreedy", "trials": 8, "seeds": 2,
              "seed": 3, "steps": 10, "progress": False, "agent_overrides": {"epsilon": 0.3}}
    cfg = VisitlabTrainConfig(**fields, out=tmp_path / "a")
    seen = []
    by_config = commands.visitlab_train(cfg)  # simlab.commands' function takes the config
    by_fields = train_command(**fields, out=tmp_path / "b", on_result=seen.append)
    assert isinstance(by_config, TrainRuns) and [r.label for r in seen] == [
        "q-learning", "mb-egreedy"]
    assert by_config.files == tuple(tmp_path / "a" / n for n in
                                    ("curves.npz", "curves.png", "summary.json"))
    assert all(f.is_file() for f in by_config.files + by_fields.files)
    old = train("nav", "q-learning", trials=8, seeds=2, seed=3, progress=False, max_steps=10,
                agent_overrides={"epsilon": 0.3})
    for a, b in zip(by_config.results, by_fields.results, strict=True):
        np.testing.assert_array_equal(a.returns, b.returns)
        np.testing.assert_array_equal(a.q, b.q)
        assert a.config == b.config
    np.testing.assert_array_equal(by_config.results[0].returns, old.returns)
    assert by_config.results[0].config == old.config
    with pytest.raises(ConfigError, match="unknown agent"):
        train_command(task="nav", agent="q-learning,sarsa", out=tmp_path / "c")
    assert not (tmp_path / "c").exists()
