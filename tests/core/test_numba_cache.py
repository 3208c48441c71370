"""One numba cache directory per source version (simlab.base._numba_cache): an edit anywhere in
simlab's sources gives a new directory, so kernels that inline other files' kernels are
recompiled instead of reloaded stale."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from simlab.base import _numba_cache as nc
from simlab.base.fingerprint import source_fingerprint

ROOT = Path(__file__).resolve().parents[2]


def _tree(tmp_path: Path) -> Path:
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "a.py").write_text("x = 1\n")
    (pkg / "sub" / "b.py").write_text("y = 2\n")
    (pkg / "notes.txt").write_text("not source\n")
    return pkg


def _stamps(roots: list[Path]) -> str:
    return source_fingerprint(roots, (".py",), stamps=True)


def test_fingerprint_follows_every_source_file_and_nothing_else(tmp_path: Path) -> None:
    pkg = _tree(tmp_path)
    first = _stamps([pkg])
    assert len(first) == 16 and first == _stamps([pkg])
    (pkg / "notes.txt").write_text("changed, but not a .py file\n")
    assert _stamps([pkg]) == first
    b = pkg / "sub" / "b.py"
    os.utime(b, ns=(b.stat().st_atime_ns, b.stat().st_mtime_ns + 1_000_000_000))
    touched = _stamps([pkg])
    assert touched != first  # an edit deep in the tree (the inlined callee's file)
    (pkg / "c.py").write_text("z = 3\n")
    assert _stamps([pkg]) not in (first, touched)  # a new file


def test_prune_keeps_the_newest_directories(tmp_path: Path) -> None:
    root = tmp_path / "numba"
    dirs = []
    for k in range(nc.KEEP + 4):
        d = root / f"v{k:02d}"
        d.mkdir(parents=True)
        os.utime(d, (1_000_000 + k, 1_000_000 + k))
        dirs.append(d)
    current = root / "current"
    current.mkdir()
    nc._prune(root, current)
    left = sorted(p.name for p in root.iterdir())
    # the current one and the KEEP - 1 newest others
    assert left == sorted(["current", *[d.name for d in dirs[-(nc.KEEP - 1):]]])


def _child_env(tmp_path: Path, **extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items()
           if k not in ("NUMBA_CACHE_DIR", "SIMLAB_NUMBA_CACHE")}
    env.update(XDG_CACHE_HOME=str(tmp_path / "cache"), PYTHONPATH=str(ROOT), **extra)
    return env


_SHOW = ("import simlab, os, numba; "
         "print(os.environ.get('NUMBA_CACHE_DIR')); print(numba.config.CACHE_DIR)")


def test_import_simlab_points_numba_at_the_versioned_directory(tmp_path: Path) -> None:
    out = subprocess.run([sys.executable, "-c", _SHOW], env=_child_env(tmp_path),
                         capture_output=True, text=True, check=True).stdout.split()
    expected = tmp_path / "cache" / "simlab" / "numba" / _stamps(
        [ROOT / "simlab", ROOT / "discretize"])
    assert out == [str(expected), str(expected)]
    assert expected.is_dir()


def test_a_users_cache_dir_and_the_source_opt_out_are_kept(tmp_path: Path) -> None:
    mine = tmp_path / "mine"
    out = subprocess.run([sys.executable, "-c", _SHOW],
                         env=_child_env(tmp_path, NUMBA_CACHE_DIR=str(mine)),
                         capture_output=True, text=True, check=True).stdout.split()
    assert out == [str(mine), str(mine)]
    out = subprocess.run([sys.executable, "-c", _SHOW],
                         env=_child_env(tmp_path, SIMLAB_NUMBA_CACHE="source"),
                         capture_output=True, text=True, check=True).stdout.split()
    assert out[0] == "None" and not (tmp_path / "cache").exists()
