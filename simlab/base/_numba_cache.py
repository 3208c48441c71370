"""One numba cache directory per version of simlab's source code.

Numba's on-disk cache (``@njit(cache=True)``) checks only the source file of the function
it caches. A kernel that inlines or calls kernels of *other* files (the fused training
loops of :mod:`simlab.visitlab.training` inline the agent core of
:mod:`simlab.agents.core`) is reloaded from the cache after those files changed: after
a ``git pull`` of an editable install it would silently run the old agent rules.

:func:`use_versioned_cache_dir` (called by ``import simlab`` and ``import discretize``,
before either imports numba) therefore points ``NUMBA_CACHE_DIR`` at
``$XDG_CACHE_HOME/simlab/numba/<fingerprint>`` (``~/.cache`` without it), where the
fingerprint (:func:`simlab.base.fingerprint.source_fingerprint` with ``stamps``) hashes the path, size
and modification time of every ``.py`` file of the ``simlab`` and ``discretize`` packages
(the stamps numba itself uses, for all files at once; 4-9 ms). Same code -> same directory, so compiled kernels are still reused across
runs and by worker processes (they inherit the variable). Older directories beyond the
newest :data:`KEEP` are deleted.

Decisions: a ``NUMBA_CACHE_DIR`` the user set is kept as it is (their choice, e.g. the
tests of :mod:`simlab.orchestration.warmup`); nothing happens if numba was imported
before simlab (its configuration is read at its import), if ``SIMLAB_NUMBA_CACHE=source``
asks for numba's default (``__pycache__`` beside the sources), or if the cache root
cannot be created (numba's default applies).
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

from simlab.base.fingerprint import source_fingerprint

#: Fingerprint directories kept (the newest by modification time).
KEEP = 8
_PACKAGES = ("simlab", "discretize")


def cache_root() -> Path:
    """``$XDG_CACHE_HOME/simlab/numba`` (``~/.cache/simlab/numba`` without it)."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "simlab" / "numba"


def _prune(root: Path, current: Path) -> None:
    dirs = sorted((p for p in root.iterdir() if p.is_dir() and p != current),
                  key=lambda p: p.stat().st_mtime, reverse=True)
    for old in dirs[KEEP - 1:]:
        shutil.rmtree(old, ignore_errors=True)


def use_versioned_cache_dir() -> Path | None:
    """Set ``NUMBA_CACHE_DIR`` to this source version's directory (module docstring);
    returns it, or None when left alone."""
    if (os.environ.get("NUMBA_CACHE_DIR") or "numba" in sys.modules
            or os.environ.get("SIMLAB_NUMBA_CACHE") == "source"):
        return None
    here = Path(__file__).resolve().parents[1]  # the simlab package folder
    roots = [p for p in (here.parent / name for name in _PACKAGES) if p.is_dir()]
    try:
        target = cache_root() / source_fingerprint(roots, (".py",), stamps=True)
        target.mkdir(parents=True, exist_ok=True)
        os.utime(target)
        _prune(target.parent, target)
    except OSError:
        return None
    os.environ["NUMBA_CACHE_DIR"] = str(target)
    return target
