"""Issue 17 part 2: a dataset worker process imports what a walk needs, not PyArrow,
pandas, SciPy or Gymnasium (each 0.1-1 s per fresh process)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from simlab.data import schema, walkers

ROOT = Path(__file__).resolve().parents[2]
HEAVY = ("pyarrow", "pandas", "scipy", "gymnasium", "matplotlib", "numba")


def test_walker_action_count_is_the_schema_one() -> None:
    assert walkers.N_ACTIONS == schema.N_ACTIONS == 16


def test_worker_imports_stay_light() -> None:
    code = ("import sys\nimport simlab.data.walkers\nfrom simlab.physics.driver import "
            "DecisionDriver\nfrom simlab.physics.motion import noisy_pose\n"
            "from simlab.physics.world import World\n"
            f"print(' '.join(m for m in {HEAVY!r} if m in sys.modules))")
    env = dict(os.environ,
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    out = subprocess.run([sys.executable, "-c", code], env=env, check=True,
                         capture_output=True, text=True).stdout.strip()
    assert out == ""
