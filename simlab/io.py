"""Safe file output: write to a temporary name, then rename.

A crash or an exception never leaves a half-written file under the final name, and
existing outputs are not replaced unless the caller asks for it.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from simlab.errors import ConfigError

# The process umask, read once (os.umask can only be read by setting it). Temporary files
# from mkstemp are created 0600; outputs get the mode a plain open() would give them.
_UMASK = os.umask(0o022)
os.umask(_UMASK)


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike[str], mode: str = "wb") -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path``; rename it onto ``path`` on success.

    The temporary file lives in the same directory (so the rename is atomic on
    POSIX) and is removed if the block raises. The data is flushed and fsynced
    before the rename so that a power cut cannot leave an empty file behind.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    tmp = Path(tmp_name)
    try:
        os.fchmod(fd, 0o666 & ~_UMASK)
        encoding = None if "b" in mode else "utf-8"
        with os.fdopen(fd, mode, encoding=encoding) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_write(path, "w") as fh:
        fh.write(text)


def atomic_write_json(path: str | os.PathLike[str], obj: Any) -> None:
    """Write ``obj`` as indented JSON to ``path`` atomically."""
    atomic_write_text(path, json.dumps(obj, indent=2, sort_keys=False) + "\n")


def ensure_new(path: str | os.PathLike[str], *, overwrite: bool = False, what: str = "output") -> Path:
    """Refuse to replace an existing ``path`` unless ``overwrite`` is true.

    Returns the path. Raises :class:`ConfigError` naming the file and the fix.
    """
    path = Path(path)
    if path.exists() and not overwrite:
        raise ConfigError(
            f"{what} already exists",
            path=path,
            fix="choose another path or pass --overwrite",
        )
    return path


@contextlib.contextmanager
def exclusive_directory(path: str | os.PathLike[str], *, what: str = "output directory",
                        fix: str = "wait for the other run to finish, or choose another --out"
                        ) -> Iterator[Path]:
    """Create ``path`` if needed and hold an exclusive, non-blocking ``flock`` on it.

    Two runs writing into one directory (two ``simlab collect`` started on the same
    ``--out``) would interleave their parts and manifests; the second one stops with a
    :class:`ConfigError` instead. The lock lives on the directory itself (no lock file is
    left behind) and is released when the block ends or the process dies.
    """
    import fcntl  # POSIX only; imported here so that simlab.io itself imports anywhere

    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ConfigError(f"{what} exists and is not a directory", path=path,
                          fix="choose another --out")
    path.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_RDONLY | os.O_DIRECTORY)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise ConfigError(f"another process is writing to this {what}", path=path,
                              fix=fix) from None
        yield path
    finally:
        os.close(fd)  # closing the descriptor releases the lock
