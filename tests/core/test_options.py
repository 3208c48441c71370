"""The command-options dataclass machinery and the shared validation checks."""

from __future__ import annotations

import argparse
import inspect
from dataclasses import FrozenInstanceError, dataclass
from pathlib import Path

import numpy as np
import pytest

from simlab.base import validation as v
from simlab.base.errors import ConfigError
from simlab.base.options import CommandConfig, command, option


@dataclass(frozen=True, kw_only=True)
class DemoConfig(CommandConfig):
    COMMAND = "demo"
    dataset: Path | None = option(None, "dataset directory", positional=True)
    out: Path = option(help="output file")
    hours: float = option(1.0, "simulated hours")
    seed: int = option(0, "root seed")
    plot: bool = option(True, "write the plot")
    overwrite: bool = option(False, "replace outputs")
    mode: str = option("mask", "rule", choices=("mask", "self-loop"))
    goals: tuple[str, ...] = option(("C",), "goal names")

    def validate(self) -> None:
        v.positive(self.hours, "hours")
        v.whole(self.seed, "seed")


def _parse(argv: list[str]) -> DemoConfig:
    parser = argparse.ArgumentParser()
    DemoConfig.add_arguments(parser)
    return DemoConfig.from_args(parser.parse_args(argv))


def test_cli_is_generated_from_the_fields() -> None:
    cfg = _parse(["data", "--out", "o.npz", "--hours", "2.5", "--no-plot", "--overwrite",
                  "--mode", "self-loop", "--goals", "N", "S"])
    assert cfg == DemoConfig(dataset=Path("data"), out=Path("o.npz"), hours=2.5, seed=0,
                             plot=False, overwrite=True, mode="self-loop", goals=("N", "S"))
    defaults = _parse(["--out", "o.npz"])
    assert defaults.dataset is None and defaults.hours == 1.0 and defaults.plot is True
    assert defaults.goals == ("C",)


def test_help_shows_every_option_with_its_default() -> None:
    parser = argparse.ArgumentParser()
    DemoConfig.add_arguments(parser)
    text = parser.format_help()
    for flag in ("--out", "--hours", "--seed", "--no-plot", "--overwrite", "--mode", "--goals",
                 "--config"):
        assert flag in text
    assert "(default 1.0)" in text and "(required)" in text


def test_config_file_then_command_line(tmp_path: Path) -> None:
    toml = tmp_path / "demo.toml"
    toml.write_text('out = "from_file.npz"\nhours = 3.0\nseed = 7\n')
    cfg = _parse(["--config", str(toml), "--seed", "9"])
    assert (cfg.out, cfg.hours, cfg.seed) == (Path("from_file.npz"), 3.0, 9)
    assert DemoConfig.from_toml(toml).seed == 7


@pytest.mark.parametrize(("text", "key"), [
    ('out = "o"\nhorus = 2.0\n', "horus"),        # misspelt key
    ('out = "o"\nseed = 1.5\n', "seed"),          # fraction where a count belongs
    ('out = "o"\nhours = -1.0\n', "hours"),       # validate() range
    ('out = "o"\nplot = 1\n', "plot"),            # 1 is not true
    ('out = "o"\nmode = "Mask"\n', "mode"),       # choices are exact
    ('hours = 2.0\n', "out"),                     # required option missing
])
def test_bad_toml_names_the_file_and_the_key(tmp_path: Path, text: str, key: str) -> None:
    toml = tmp_path / "bad.toml"
    toml.write_text(text)
    with pytest.raises(ConfigError) as info:
        DemoConfig.from_toml(toml)
    assert info.value.key == key and info.value.path == str(toml)
    assert str(toml) in str(info.value)


@dataclass(frozen=True, kw_only=True)
class FlagConfig(CommandConfig):
    dataset_id: str = option(help="dataset id", flag="id")
    episode_length: int = option(10, "steps per episode")


def test_a_field_with_its_own_flag_reads_either_key_and_errors_name_the_flag(
        tmp_path: Path) -> None:
    parser = argparse.ArgumentParser()
    FlagConfig.add_arguments(parser)
    assert FlagConfig.from_args(parser.parse_args(["--id", "a/b-v0"])).dataset_id == "a/b-v0"
    for key in ("id", "dataset_id", "dataset-id"):
        assert FlagConfig.from_mapping({key: "x", "episode-length": 3}) == FlagConfig(
            dataset_id="x", episode_length=3)
    with pytest.raises(ConfigError, match=r"dataset_id \(--id\)") as info:
        FlagConfig.from_mapping({"episode_length": 3}, path=tmp_path / "f.toml")
    assert info.value.key == "dataset_id"
    toml = tmp_path / "flag.toml"
    toml.write_text('id = "from-file"\nepisode-length = 4\n')
    assert FlagConfig.from_args(parser.parse_args(["--config", str(toml), "--id", "cli"])) == \
        FlagConfig(dataset_id="cli", episode_length=4)  # the command line wins over a file
    with pytest.raises(ConfigError, match="given twice") as info:
        FlagConfig.from_mapping({"id": "x", "dataset_id": "y"})
    assert info.value.key == "dataset_id"
    with pytest.raises(ConfigError, match="unknown option 'ids'") as info:
        FlagConfig.from_mapping({"ids": "x"})
    assert "id" in (info.value.fix or "").split(", ")


@dataclass(frozen=True, kw_only=True)
class OneOfConfig(CommandConfig):
    states: int | None = option(None, "number of states")
    radius: float | None = option(None, "cell radius")
    seed: int = option(0, "root seed")
    EXCLUSIVE = ("states", "radius")


def test_exclusive_fields_are_one_argparse_group(capsys) -> None:
    parser = argparse.ArgumentParser()
    OneOfConfig.add_arguments(parser)
    assert OneOfConfig.from_args(parser.parse_args(["--radius", "0.1", "--seed", "2"])) == \
        OneOfConfig(radius=0.1, seed=2)
    with pytest.raises(SystemExit):
        parser.parse_args(["--states", "4", "--radius", "0.1"])
    assert "not allowed with argument" in capsys.readouterr().err


def test_configs_are_frozen_and_replace_validates() -> None:
    cfg = DemoConfig(out="o.npz")
    assert cfg.out == Path("o.npz")  # strings become paths
    with pytest.raises(FrozenInstanceError):
        cfg.seed = 3  # type: ignore[misc]
    assert cfg.replace(seed=np.int64(4)).seed == 4
    with pytest.raises(ConfigError, match="seed"):
        cfg.replace(seed=True)
    assert DemoConfig.from_mapping(cfg.to_dict()) == cfg


def test_command_takes_the_config_or_its_fields() -> None:
    @command(DemoConfig)
    def demo(cfg: DemoConfig) -> tuple[Path, float]:
        return cfg.out, cfg.hours

    assert demo(DemoConfig(out="a")) == (Path("a"), 1.0)
    assert demo(None, "b", hours=2.0) == (Path("b"), 2.0)
    assert list(inspect.signature(demo).parameters)[:3] == ["dataset", "out", "hours"]
    with pytest.raises(ConfigError, match="hours"):
        demo(out="c", hours=0.0)


@pytest.mark.parametrize(("check", "good", "bad"), [
    (lambda x: v.whole(x, "n", minimum=1), [1, np.int32(5)], [0, 1.0, True, "2", None]),
    (lambda x: v.number(x, "x", low=0, high=1, high_open=True), [0, 0.5], [1, -0.1, np.nan]),
    (lambda x: v.positive(x, "x"), [1e-9, 3], [0, -1, np.inf, False]),
    (lambda x: v.probability(x, "p"), [0, 1, 0.25], [1.01, -0.0001, "0.5"]),
    (lambda x: v.discount(x), [0, 0.99], [1.0, -0.1]),
    (lambda x: v.boolean(x, "b"), [True, np.bool_(False)], [0, 1, "yes"]),
    (lambda x: v.choice(x, ("a", "b"), "c"), ["a"], ["A", None, 1]),
    (lambda x: v.spelled_path(x, "png"), [None, "./f.png", Path("f.png")], ["", 3, ["f"]]),
])
def test_validation_accepts_good_and_names_the_key_on_bad(check, good, bad) -> None:
    for value in good:
        check(value)
    for value in bad:
        with pytest.raises(ConfigError) as info:
            check(value)
        assert info.value.key is not None and repr(value) in str(info.value)


def test_a_spelled_path_comes_back_as_given() -> None:
    assert v.spelled_path("./f.png", "png") == "./f.png"  # not Path("f.png")


def test_paths_exist_checks(tmp_path: Path) -> None:
    (tmp_path / "f.txt").write_text("x")
    assert v.existing_file(tmp_path / "f.txt", "file") == tmp_path / "f.txt"
    assert v.existing_dir(str(tmp_path), "dir") == tmp_path
    with pytest.raises(ConfigError, match="not found"):
        v.existing_file(tmp_path / "missing", "file")
    with pytest.raises(ConfigError, match="found a directory"):
        v.existing_file(tmp_path, "file")
    with pytest.raises(ConfigError, match="found a file"):
        v.existing_dir(tmp_path / "f.txt", "dir")


def test_the_help_of_a_no_flag_says_it_turns_the_option_off() -> None:
    parser = argparse.ArgumentParser()
    DemoConfig.add_arguments(parser)
    text = " ".join(parser.format_help().split())
    assert "--no-plot turn off (on by default): write the plot" in text


def test_every_seed_is_checked_once_here_with_a_fix_that_fits_it() -> None:
    with pytest.raises(ConfigError, match=r"seed: .*got -3 \(seeds are non-negative: e\.g\. 3 "):
        DemoConfig(out=Path("o"), seed=-3)
    with pytest.raises(ConfigError, match=r"choose a seed in \[0, 2\*\*63 - 1\]"):
        DemoConfig(out=Path("o"), seed=2**64)
    assert DemoConfig(out=Path("o"), seed=2**63 - 1).seed == 2**63 - 1

    @dataclass(frozen=True, kw_only=True)
    class Layout(CommandConfig):
        layout_seed: int | None = option(None, "seed of a random layout")
        seeds: int = option(3, "a count, not a seed")

    assert Layout(layout_seed=None, seeds=0).layout_seed is None
    with pytest.raises(ConfigError, match="layout_seed"):
        Layout(layout_seed=-1)
