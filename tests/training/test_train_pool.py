"""``train(pool=...)`` / ``--workers N``: the work shared with worker processes gives the
very outputs (arrays, summary, PNG bytes) of the sequential path."""

from __future__ import annotations

import concurrent.futures as cf
import json

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.cli import main
from simlab.training.train import train

RUN = dict(agent="q-softmax", goals="all", episodes=40, runs=2, seed=5,
           bounds=(0.0, 0.0, 1.5, 1.5), progress=False)  # fmt: skip


@pytest.fixture
def map_yaml(tmp_path):
    from discretize.gridmap import OccupancyMap
    from discretize.mapio import write_map

    occ = np.zeros((80, 80), dtype=np.int8)
    occ[:, :2] = 100
    path, _ = write_map(tmp_path / "map.yaml", OccupancyMap(occ, 0.02, (-0.05, -0.05, 0.0)))
    return path


def _outputs(out):
    """Every output of ``out`` by file name: npz arrays, summary (its own directory
    replaced), PNG bytes (npz bytes hold zip timestamps, so arrays are compared)."""
    found = {}
    for p in sorted(out.iterdir()):
        if p.suffix == ".npz":
            with np.load(p, allow_pickle=False) as z:
                found[p.name] = {k: z[k] for k in z.files}
        elif p.suffix == ".json":
            found[p.name] = json.loads(p.read_text().replace(str(out), "OUT"))
        else:
            found[p.name] = p.read_bytes()
    return found


def _assert_same(a, b):
    assert sorted(a) == sorted(b)
    for name in a:
        if isinstance(a[name], dict) and name.endswith(".npz"):
            assert sorted(a[name]) == sorted(b[name]), name
            for key in a[name]:
                np.testing.assert_array_equal(a[name][key], b[name][key], err_msg=name)
        else:
            assert a[name] == b[name], name


class _Eager(cf.Executor):
    """Runs every job when it is submitted: the pool does all the goals and the curves."""

    def submit(self, fn, /, *args, **kwargs):
        f = cf.Future()
        f.set_running_or_notify_cancel()
        f.set_result(fn(*args, **kwargs))
        return f


class _Idle(cf.Executor):
    """Never starts a job: this process takes every goal and the curves back."""

    def submit(self, fn, /, *args, **kwargs):
        return cf.Future()


@pytest.fixture
def sequential(small_mdp_file, map_yaml, tmp_path):
    s = train(small_mdp_file, out=tmp_path / "seq", occupancy_map=map_yaml, **RUN)
    return s, _outputs(tmp_path / "seq")


def test_a_spawned_worker_gives_the_sequential_outputs_byte_for_byte(
        small_mdp_file, map_yaml, tmp_path, sequential):
    from simlab.base.parallel import spawn_worker

    pool = spawn_worker()
    try:
        pool.submit(int).result()  # a warm pool, as the pipeline's
        s = train(small_mdp_file, out=tmp_path / "pool", occupancy_map=map_yaml, pool=pool,
                  **RUN)  # fmt: skip
    finally:
        pool.shutdown()
    seq, files = sequential
    _assert_same(_outputs(tmp_path / "pool"), files)
    np.testing.assert_array_equal(s.rewards, seq.rewards)
    assert s.goals == seq.goals and len(s.goals) == 9
    for g in seq.Q:
        np.testing.assert_array_equal(s.Q[g], seq.Q[g])


@pytest.mark.parametrize("pool", [_Eager(), _Idle()], ids=["pool-does-all", "pool-does-none"])
def test_any_split_between_pool_and_process_gives_the_same_outputs(
        small_mdp_file, map_yaml, tmp_path, sequential, pool):
    train(small_mdp_file, out=tmp_path / "o", occupancy_map=map_yaml, pool=pool, **RUN)
    _assert_same(_outputs(tmp_path / "o"), sequential[1])


def test_a_pool_without_outputs_returns_the_sequential_results(small_mdp_file, sequential):
    s = train(small_mdp_file, pool=_Eager(), **RUN)
    np.testing.assert_array_equal(s.rewards, sequential[0].rewards)
    assert s.goals == sequential[0].goals and s.files == {}


def test_cli_workers_gives_the_sequential_outputs(small_mdp_file, tmp_path):
    args = ["train", "--mdp", str(small_mdp_file), "--goals", "g1,g2,g3", "--episodes", "30",
            "--runs", "2", "--seed", "4", "--no-progress", "--arena", "table"]
    assert main([*args, "--out", str(tmp_path / "one")]) == 0
    assert main([*args, "--out", str(tmp_path / "two"), "--workers", "2"]) == 0
    _assert_same(_outputs(tmp_path / "two"), _outputs(tmp_path / "one"))


def test_pool_is_python_only_and_excludes_workers(small_mdp_file, tmp_path, capsys):
    with pytest.raises(ConfigError, match="either a pool or workers"):
        train(small_mdp_file, pool=_Idle(), workers=2, progress=False)
    with pytest.raises(ConfigError, match="workers"):
        train(small_mdp_file, workers=0, progress=False)
    with pytest.raises(SystemExit):
        main(["train", "--mdp", str(small_mdp_file), "--out", str(tmp_path / "o"),
              "--pool", "x"])  # fmt: skip
    assert "--pool" in capsys.readouterr().err
    # nor can an options file give one: a clear error naming the file and the key
    from simlab.replay.config import ReplayConfig
    from simlab.training.train import TrainConfig

    toml = tmp_path / "train.toml"
    toml.write_text(f'mdp = "{small_mdp_file.as_posix()}"\npool = "x"\n')
    replay_options = {"arena": "table", "states": "s.json", "pool": "x"}
    for build in (lambda: TrainConfig.from_toml(toml),
                  lambda: ReplayConfig.from_mapping(replay_options, path=toml)):
        with pytest.raises(ConfigError, match="executor from Python") as err:
            build()
        assert err.value.key == "pool" and str(toml) in str(err.value)
