"""The numba warm-up fills the cache that a later process's particle filter loads."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import simlab

ROOT = Path(simlab.__file__).resolve().parent.parent

# A replay-like filter update in a fresh process: how many numba compilations it ran.
_UPDATE = """
import json
import numpy as np
from numba.core import event
from simlab.localization.filter import ParticleFilter
from simlab.localization.likelihood import LikelihoodField
from simlab.localization.maps import arena_map
from simlab.physics.arena import load_arena
rec = event.RecordingListener()
event.register("numba:compile", rec)
pf = ParticleFilter(LikelihoodField(arena_map(load_arena("table"), 0.02)),
                    rng=np.random.default_rng(3))
pf.init_gaussian(np.array([0.1, -0.2, 0.5]))
pf.predict(np.zeros(3), np.array([0.02, 0.0, 0.05]))
class Scan:
    ranges = np.linspace(0.2, 0.6, 360)
    angles = np.arange(360) * (2 * np.pi / 360)
    sensor_offset = np.array([-0.032, 0.0])
pf.update(Scan())
print(json.dumps(len(rec.buffer)))
"""


def _run(code: str, cache: Path) -> str:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache),
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True)
    return res.stdout.strip().splitlines()[-1]


def test_warm_cache_means_no_compile(tmp_path) -> None:
    cold = int(json.loads(_run(_UPDATE, tmp_path / "cold")))
    assert cold > 0  # a cold cache compiles (else the check below proves nothing)
    warm_dir = tmp_path / "warm"
    _run("from simlab.orchestration.warmup import warm_kernels; print(warm_kernels(agent=None))", warm_dir)
    assert any(warm_dir.rglob("*.nbi"))
    assert int(json.loads(_run(_UPDATE, warm_dir))) == 0


def test_start_warmup_process_ends(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    from simlab.orchestration.warmup import start_warmup

    with start_warmup(agent=None, mcl=True) as w:
        assert w.wait()
        assert w.ok and w.done and w.future.result() > 0
        assert any(tmp_path.rglob("*_field_kernel*.nbi"))
        # the warmed process stays up to be lent to later stages, with their modules loaded
        pid = w.worker.submit(os.getpid).result()
        assert pid != os.getpid()
        assert w.worker.submit(_loaded, "simlab.replay.loop").result()
    assert w.worker is w.pool  # closed now: a new submit is refused
    with pytest.raises(RuntimeError):
        w.pool.submit(os.getpid)


def _loaded(name: str) -> bool:
    return name in sys.modules
