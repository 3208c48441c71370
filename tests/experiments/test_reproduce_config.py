"""``simlab reproduce``'s options as ReproduceConfig: --config FILE under the command line,
--help defaults, unknown keys refused naming file and key, --list without --out, and
reproduce() by config or by its old arguments alike (on the example experiment)."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from simlab.base.errors import ConfigError
from simlab.cli import main
from simlab.cli.reproduce import add_arguments
from simlab.experiments.reproduce import ReproduceConfig, reproduce

EXAMPLE = Path(__file__).resolve().parents[2] / "simlab" / "experiments" / "example.toml"


def _parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    return parser.parse_args(argv)


def test_config_file_gives_options_and_the_command_line_wins(tmp_path):
    toml = tmp_path / "r.toml"
    toml.write_text(f'experiments = "{EXAMPLE}"\nout = "from-file"\nseed = 4\nworkers = 1\n'
                    'progress = false\nbudget = "full"\nonly = ["example_coin"]\n')
    cfg = ReproduceConfig.from_args(_parse(["--config", str(toml), "--seed", "5",
                                            "--out", str(tmp_path / "cli")]))
    assert (cfg.seed, cfg.out, cfg.workers, cfg.progress) == (5, tmp_path / "cli", 1, False)
    assert (cfg.budget, cfg.only, cfg.experiments) == ("full", ("example_coin",), str(EXAMPLE))
    assert cfg.backend == "local" and cfg.workers == 1 and not cfg.strict
    plain = ReproduceConfig.from_args(_parse([]))
    assert plain == ReproduceConfig() and plain.workers is None  # None: all cores


def test_cli_runs_from_a_config_file_and_lists_without_out(tmp_path, capsys):
    toml = tmp_path / "r.toml"
    toml.write_text(f'experiments = "{EXAMPLE}"\nworkers = 1\nprogress = false\n')
    assert main(["reproduce", "--config", str(toml), "--list"]) == 0
    assert capsys.readouterr().out.startswith("example_coin ")
    assert main(["reproduce", "--config", str(toml)]) == 2  # no --out
    assert "--out: missing" in capsys.readouterr().err
    out = tmp_path / "out"
    assert main(["reproduce", "--config", str(toml), "--out", str(out), "--seed", "2"]) == 0
    assert "1 checks PASS, 0 FAIL" in capsys.readouterr().out
    assert '"seed": 2' in (out / "results.json").read_text()


def test_help_shows_the_defaults(capsys):
    with pytest.raises(SystemExit):
        main(["reproduce", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for part in ("(default quick)", "(default local)", "(default 0)", "--no-progress",
                 "--list", "--config FILE", "default: all cores"):
        assert part in text, part


def test_unknown_key_names_file_and_key_before_anything_runs(tmp_path, capsys):
    toml = tmp_path / "r.toml"
    toml.write_text(f'experiments = "{EXAMPLE}"\nbugdet = "full"\n')
    out = tmp_path / "out"
    assert main(["reproduce", "--config", str(toml), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert str(toml) in err and "bugdet" in err and "budget" in err
    assert not out.exists()
    with pytest.raises(ConfigError) as info:
        ReproduceConfig(budget="medium")
    assert info.value.key == "budget"
    with pytest.raises(ConfigError, match="--out"):
        reproduce(ReproduceConfig(experiments=EXAMPLE))


def test_config_object_and_keywords_give_the_same_results(tmp_path):
    cfg = ReproduceConfig(out=tmp_path / "a", experiments=EXAMPLE, workers=1, progress=False,
                          seed=3)
    by_config = reproduce(cfg, log=None)
    by_keywords = reproduce(tmp_path / "b", experiments=[EXAMPLE], workers=1, progress=False,
                            seed=3, log=None)
    a, b = by_config.entry("example_coin"), by_keywords.entry("example_coin")
    assert a["status"] == "ok" and a["metrics"] == b["metrics"] and a["seed"] == 3
    with pytest.raises(ConfigError, match="unknown option"):
        reproduce(tmp_path / "c", experiments=EXAMPLE, wrkers=1)
