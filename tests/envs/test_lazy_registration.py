"""Issue 17 part 2: ``import simlab`` does not import Gymnasium, yet its environments are
registered as soon as Gymnasium is imported (fresh interpreters: the import order matters)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _run(code: str) -> str:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    return subprocess.run([sys.executable, "-c", code], env=env, check=True,
                          capture_output=True, text=True).stdout.strip()


def test_import_simlab_leaves_gymnasium_out() -> None:
    assert _run("import sys, simlab; print('gymnasium' in sys.modules)") == "False"


@pytest.mark.parametrize("code", [
    "import simlab\nimport gymnasium as gym",
    "import gymnasium as gym\nimport simlab",
    "import simlab\nfrom gymnasium.envs.registration import registry\nimport gymnasium as gym",
])
def test_envs_registered_whatever_the_import_order(code: str) -> None:
    out = _run(code + "\nfrom simlab.envs import ENV_ENTRY_POINTS\n"
               "print(all(gym.spec(i).entry_point == e for i, e in ENV_ENTRY_POINTS.items()),"
               " gym.spec('simlab/VisitLab-Social-v0').max_episode_steps)")
    assert out == "True 40"
