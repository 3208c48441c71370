"""Fingerprints of source trees (kept light: :mod:`simlab` imports it at start-up)."""

from __future__ import annotations

import hashlib
from collections.abc import Iterable
from pathlib import Path


def source_fingerprint(roots: Iterable[Path],
                       suffixes: tuple[str, ...] = (".py", ".urdf", ".toml"), *,
                       stamps: bool = False) -> str:
    """sha256 (16 hex digits) of the source under ``roots`` (files, or folders searched for
    files ending in one of ``suffixes``): names relative to each root's parent, and the
    bytes (``stamps``: size and modification time instead, numba's own cheap test, for a
    check at every import). A missing root is an error (a renamed module must not
    silently leave the key). Used by the stage cache
    (:mod:`simlab.orchestration.cache`) and the numba cache directory
    (:mod:`simlab.base._numba_cache`)."""
    h = hashlib.sha256()
    for root in roots:
        if not root.exists():
            raise FileNotFoundError(f"fingerprint source {root} does not exist")
        files = [root] if root.is_file() else sorted(
            p for suffix in suffixes for p in root.rglob(f"*{suffix}") if p.is_file())
        for f in files:
            h.update(f"{root.name}/{f.relative_to(root.parent).as_posix()}\0".encode())
            if stamps:
                st = f.stat()
                h.update(f"{st.st_size}\0{st.st_mtime_ns}\n".encode())
            else:
                h.update(f.read_bytes())
    return h.hexdigest()[:16]
