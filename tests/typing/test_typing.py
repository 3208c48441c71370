"""simlab is a typed package: ``py.typed`` ships in the wheel, and ``mypy --strict`` checks
a user's script against simlab's own annotations (PEP 561)."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def test_py_typed_is_in_the_built_wheel(tmp_path: Path) -> None:
    pytest.importorskip("hatchling")
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
                    "-q", "-w", str(tmp_path), str(ROOT)], check=True, capture_output=True)
    (wheel,) = tmp_path.glob("simlab-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    assert {"simlab/py.typed", "discretize/py.typed"} <= names
    assert "simlab/agents/policy.py" in names


def test_mypy_strict_passes_on_a_user_script_and_sees_simlab_types(tmp_path: Path) -> None:
    pytest.importorskip("mypy")
    # run where a user would: outside the source tree, simlab found as an installed package
    for name in ("user_script.py", "wrong_usage.py"):
        shutil.copy(HERE / name, tmp_path / name)
    out = subprocess.run([sys.executable, "-m", "mypy", "--strict", "--no-error-summary",
                          "--cache-dir", str(tmp_path / ".mypy_cache"),
                          "user_script.py", "wrong_usage.py"],
                         cwd=tmp_path, capture_output=True, text=True)
    errors = [line for line in out.stdout.splitlines() if ": error:" in line]
    assert not [e for e in errors if e.startswith("user_script.py")], out.stdout
    wrong = [e for e in errors if e.startswith("wrong_usage.py")]
    assert len(wrong) == 2, out.stdout
    assert '"goal_conditioned"' in wrong[0] and '"bool"' in wrong[0]
    assert "[return-value]" in wrong[1]
