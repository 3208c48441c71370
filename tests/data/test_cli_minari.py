"""The three CLI commands end to end (kinematic simulator) and the Minari export."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.cli import main
from simlab.data.dataset import read_dataset
from simlab.data.schema import MANIFEST_NAME


def test_collect_estimate_cli(tmp_path: Path, grid_states_file: Path,
                              capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "walk"
    code = main(["collect", "--states", str(grid_states_file), "--transitions", "300",
                 "--seed", "2", "--out", str(out), "--simulator", "kinematic",
                 "--part-size", "100", "--no-progress"])
    assert code == 0
    assert "300 transitions in 3 parts" in capsys.readouterr().out
    assert read_dataset(out).num_rows == 300

    code = main(["estimate", str(out), "--out", str(tmp_path / "mdp.npz")])
    assert code == 0
    printed = capsys.readouterr().out
    assert "25 states x 16 actions from 300 transitions" in printed
    assert "slow" in printed and "fast" in printed
    summary = json.loads((tmp_path / "mdp.json").read_text())
    assert summary["transitions"] == 300

    # second collect into the same directory: one-line error, exit 2, nothing touched
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    code = main(["collect", "--states", str(grid_states_file), "--transitions", "300",
                 "--out", str(out), "--simulator", "kinematic", "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "--resume" in err
    assert {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


def test_estimate_cli_errors_are_one_line(tmp_path: Path, dataset_copy: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    (dataset_copy / MANIFEST_NAME).write_text("{")
    code = main(["estimate", str(dataset_copy), "--out", str(tmp_path / "mdp.npz")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and MANIFEST_NAME in err
    code = main(["estimate", str(tmp_path / "nowhere"), "--out", str(tmp_path / "mdp.npz")])
    assert code == 2 and "no manifest" in capsys.readouterr().err


def test_estimate_cli_from_counts(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "robot.csv"
    path.write_text("s,a,s_next,count\n0,0,1,3\n1,8,0,1\n1,8,2,1\n")
    code = main(["estimate", "--counts", str(path), "--n-states", "3", "--out",
                 str(tmp_path / "m.npz"), "--no-plot"])
    assert code == 0
    with np.load(tmp_path / "m.npz", allow_pickle=False) as z:
        assert z["entropy"][1, 8] == pytest.approx(1.0)
        assert z["visited"].sum() == 2
    path.write_text("s,a,s_next,count\n0,0,1,-3\n")
    code = main(["estimate", "--counts", str(path), "--out", str(tmp_path / "n.npz")])
    err = capsys.readouterr().err
    assert code == 2 and str(path) in err and "line 2" in err


@pytest.fixture()
def minari_home(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    pytest.importorskip("minari")
    home = tmp_path / "minari"
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(home))
    return home


def test_minari_export_loads_back(kinematic_dataset: Path, minari_home: Path) -> None:
    import minari

    from simlab.envs.minari_export import export_minari

    result = export_minari(kinematic_dataset, "simlab/kin-walk-v0", episode_length=128,
                           goal="C")
    assert str(minari_home) in result.path
    data = minari.load_dataset("simlab/kin-walk-v0")
    table = read_dataset(kinematic_dataset)
    assert data.total_steps == table.num_rows == result.steps
    assert data.observation_space.n == 25 and data.action_space.n == 16
    s = table.column("s").to_numpy()
    a = table.column("a").to_numpy()
    s_next = table.column("s_next").to_numpy()
    row = 0
    for episode in data.iterate_episodes():
        n = len(episode.actions)
        assert n <= 128
        np.testing.assert_array_equal(episode.actions, a[row:row + n])
        np.testing.assert_array_equal(episode.observations[:-1], s[row:row + n])
        np.testing.assert_array_equal(episode.observations[1:], s_next[row:row + n])
        # reward 1 exactly when s' is the goal's state (12 on the 5 x 5 lattice)
        np.testing.assert_array_equal(episode.rewards, (s_next[row:row + n] == 12) * 1.0)
        assert episode.truncations[-1] and not episode.terminations.any()
        assert episode.infos["pose"].shape == (n + 1, 3)
        row += n
    assert row == table.num_rows


def test_minari_cli_refuses_an_existing_id(kinematic_dataset: Path, minari_home: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    args = ["export-minari", str(kinematic_dataset), "--id", "simlab/cli-walk-v0"]
    assert main(args) == 0
    assert "episodes" in capsys.readouterr().out
    assert main(args) == 2
    assert "already exists" in capsys.readouterr().err
    assert main([*args, "--overwrite"]) == 0
    assert main([*args[:-1], "simlab/cli-walk-v1", "--goal", "nowhere"]) == 2
    assert "unknown goal" in capsys.readouterr().err


def test_minari_round_trip_recovers_a_working_env(kinematic_dataset: Path,
                                                  minari_home: Path) -> None:
    import minari

    from simlab.envs.minari_export import export_minari

    export_minari(kinematic_dataset, "simlab/trip-v0", episode_length=64, goal="C")
    data = minari.load_dataset("simlab/trip-v0")
    env = data.recover_environment()
    try:
        assert env.spec.max_episode_steps == 64
        assert env.observation_space == data.observation_space
        assert env.action_space == data.action_space
        s, _ = env.reset(seed=0, options={"pose": (0.0, 0.0, np.pi / 2)})
        assert s == 12  # the lattice's centre state, as in the data's numbering
        s2, r, *_ = env.step(0)
        assert env.observation_space.contains(s2) and r == float(s2 == 12)
        assert env.unwrapped.goal.name == "C"
    finally:
        env.close()


@pytest.mark.parametrize("bad_id", ["badid", "simlab/no version", "simlab//x-v0"])
def test_minari_bad_id_writes_nothing(kinematic_dataset: Path, minari_home: Path,
                                      bad_id: str, capsys: pytest.CaptureFixture[str]) -> None:
    before = sorted(p.relative_to(minari_home.parent) for p in minari_home.parent.rglob("*"))
    code = main(["export-minari", str(kinematic_dataset), "--id", bad_id])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "Minari id" in err
    after = sorted(p.relative_to(minari_home.parent) for p in minari_home.parent.rglob("*"))
    assert after == before


def test_minari_failed_export_leaves_no_partial_dataset(kinematic_dataset: Path,
                                                        minari_home: Path,
                                                        monkeypatch: pytest.MonkeyPatch) -> None:
    import minari
    from minari.dataset._storages.arrow_storage import ArrowStorage

    from simlab.envs.minari_export import export_minari

    export_minari(kinematic_dataset, "simlab/keep-v0", episode_length=64)
    write = ArrowStorage.update_episodes

    def boom(storage, episodes):  # fail half-way: one episode written, then an error
        write(storage, list(episodes)[:1])
        raise OSError("disk full")

    with monkeypatch.context() as patch:
        patch.setattr(ArrowStorage, "update_episodes", boom)
        with pytest.raises(OSError, match="disk full"):
            export_minari(kinematic_dataset, "simlab/half-v0", episode_length=64)
        with pytest.raises(OSError, match="disk full"):
            export_minari(kinematic_dataset, "simlab/keep-v0", episode_length=64,
                          overwrite=True)
    assert sorted(minari.list_local_datasets()) == ["simlab/keep-v0"]
    assert minari.load_dataset("simlab/keep-v0").total_steps > 0  # the old one survives
    assert [p.name for p in minari_home.parent.iterdir() if p.name.startswith(".")] == []


def test_minari_export_without_a_loadable_arena_records_no_env_spec(
        kinematic_dataset: Path, minari_home: Path) -> None:
    import minari

    from simlab.envs.minari_export import export_minari

    with pytest.warns(UserWarning, match="--arena"):
        export_minari(kinematic_dataset, "simlab/noarena-v0", arena="no-such-arena")
    assert minari.load_dataset("simlab/noarena-v0").spec.env_spec is None


def test_minari_export_of_an_incomplete_dataset_warns(dataset_copy: Path,
                                                      minari_home: Path) -> None:
    import json

    from simlab.data.dataset import IncompleteDatasetWarning
    from simlab.envs.minari_export import export_minari

    manifest = dataset_copy / "_manifest.json"
    m = json.loads(manifest.read_text())
    m["complete"] = False
    manifest.write_text(json.dumps(m))
    with pytest.warns(IncompleteDatasetWarning, match="Minari dataset covers only its finished"):
        export_minari(dataset_copy, "simlab/part-walk-v0", episode_length=64)


# ----------------------------------------------------------- options (ExportMinariConfig)
def test_minari_cli_config_file_and_command_line(kinematic_dataset: Path, minari_home: Path,
                                                 tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    import minari

    toml = tmp_path / "export.toml"
    toml.write_text('dataset_id = "simlab/cfg-walk-v0"\nepisode-length = 50\ngoal = "C"\n')
    code = main(["export-minari", str(kinematic_dataset), "--config", str(toml),
                 "--episode-length", "64"])
    assert code == 0 and "Minari dataset simlab/cfg-walk-v0:" in capsys.readouterr().out
    data = minari.load_dataset("simlab/cfg-walk-v0")
    assert data.spec.env_spec.max_episode_steps == 64  # the command line's
    assert data.spec.env_spec.kwargs["goal"] == "C"  # the file's
    lengths = [len(e.actions) for e in data.iterate_episodes()]
    assert max(lengths) == 64 and sum(lengths) == read_dataset(kinematic_dataset).num_rows


def test_minari_cli_help_shows_the_options(capsys: pytest.CaptureFixture[str],
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    from tests.data.test_import_log import help_blocks

    monkeypatch.setenv("COLUMNS", "200")
    with pytest.raises(SystemExit):
        main(["export-minari", "--help"])
    blocks = help_blocks(capsys.readouterr().out)
    assert "(required)" in blocks["--id"]
    assert "(default: the dataset's part size)" in blocks["--episode-length"]
    assert {"--goal", "--arena", "--overwrite", "--config"} <= set(blocks)
    assert "--author" not in blocks  # Python and TOML only


def test_minari_cli_unknown_config_key_names_the_file_and_the_key(
        kinematic_dataset: Path, minari_home: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    toml = tmp_path / "export.toml"
    toml.write_text('dataset_id = "simlab/typo-v0"\nepisode-lenght = 64\n')
    code = main(["export-minari", str(kinematic_dataset), "--config", str(toml)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert str(toml) in err and "episode-lenght: unknown option" in err
    assert not minari_home.exists() or not any(minari_home.rglob("*typo*"))


def test_minari_export_takes_the_config_or_its_fields(kinematic_dataset: Path,
                                                      minari_home: Path) -> None:
    import minari

    from simlab.envs.minari_export import ExportMinariConfig, export_minari

    by_config = export_minari(ExportMinariConfig(
        dataset=kinematic_dataset, dataset_id="simlab/by-config-v0", episode_length=96,
        goal="C", author="lab"))
    by_fields = export_minari(str(kinematic_dataset), "simlab/by-fields-v0",
                              episode_length=96, goal="C", author="lab")
    assert (by_config.episodes, by_config.steps) == (by_fields.episodes, by_fields.steps)
    a, b = minari.load_dataset("simlab/by-config-v0"), minari.load_dataset("simlab/by-fields-v0")
    assert a.storage.metadata["author"] == b.storage.metadata["author"] == {"lab"}
    for x, y in zip(a.iterate_episodes(), b.iterate_episodes(), strict=True):
        np.testing.assert_array_equal(x.observations, y.observations)
        np.testing.assert_array_equal(x.actions, y.actions)
        np.testing.assert_array_equal(x.rewards, y.rewards)
    with pytest.raises(ConfigError, match="episode_length"):
        export_minari(kinematic_dataset, "simlab/zero-v0", episode_length=0)
    assert "simlab/zero-v0" not in minari.list_local_datasets()


def test_ctrl_c_while_minari_builds_the_env_is_one_line_and_130(
        kinematic_dataset: Path, minari_home: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    # Minari makes the recorded env to read its spaces: a Ctrl-C inside PyBullet's connect
    # left a half-made client whose destructor printed an AttributeError traceback
    import sys

    from simlab.physics._bullet import pybullet

    def interrupted(*args: object, **kwargs: object) -> int:
        raise KeyboardInterrupt

    ignored: list[object] = []
    monkeypatch.setattr(pybullet, "connect", interrupted)
    monkeypatch.setattr(sys, "unraisablehook", ignored.append)
    code = main(["export-minari", str(kinematic_dataset), "--id", "simlab/cut-v0"])
    import gc

    gc.collect()
    err = capsys.readouterr().err
    assert code == 130
    assert err == "simlab export-minari: interrupted\n"
    assert ignored == []
    assert not (minari_home / "simlab" / "cut-v0").exists()


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file()}


def test_minari_overwrite_interrupted_between_its_renames_keeps_the_old_dataset(
        kinematic_dataset: Path, minari_home: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Ctrl-C after the old dataset was set aside and before the new one took its place:
    the old one is back, file for file, and no staging root is left; so is it when the
    export is killed there (the next export's cleanup puts it back)."""
    import simlab.envs.minari_export as mx

    export = mx.export_minari
    export(kinematic_dataset, "simlab/keep-v0", episode_length=128)
    target = minari_home / "simlab" / "keep-v0"
    before = _files(target)
    assert any(name.endswith("metadata.json") for name in before)
    real = mx.os.replace

    def replace(src, dst):
        real(src, dst)
        if mx.PREVIOUS in Path(dst).parts:          # the old one just moved aside
            raise KeyboardInterrupt

    monkeypatch.setattr(mx.os, "replace", replace)
    with pytest.raises(KeyboardInterrupt):
        export(kinematic_dataset, "simlab/keep-v0", episode_length=64, overwrite=True)
    monkeypatch.undo()
    assert _files(target) == before
    assert not list(minari_home.parent.glob(f".{minari_home.name}{mx.STAGING_INFIX}*"))
    # killed there instead: the dataset sits only in a dead export's staging root
    dead = minari_home.parent / f".{minari_home.name}{mx.STAGING_INFIX}999999999-dead"
    (dead / mx.PREVIOUS / "simlab").mkdir(parents=True)
    real(target, dead / mx.PREVIOUS / "simlab" / "keep-v0")
    assert mx.remove_dead_staging(minari_home) == [dead]
    assert _files(target) == before and not dead.exists()
