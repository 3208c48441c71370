"""Safe file output: write to a temporary name, then rename.

A crash or an exception never leaves a half-written file under the final name, and
existing outputs are not replaced unless the caller asks for it.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from simlab.base.errors import ConfigError

#: The problem of a file whose parser ran out of stack: what a user can do about it.
NESTED_TOO_DEEPLY = ("nested too deeply to read (brackets or tables inside each other "
                     "thousands of levels deep)")

# The process umask, read once (os.umask can only be read by setting it). Temporary files
# from mkstemp are created 0600; outputs get the mode a plain open() would give them.
_UMASK = os.umask(0o022)
os.umask(_UMASK)


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike[str], mode: str = "wb", *,
                 tmp_dir: str | os.PathLike[str] | None = None) -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path``; rename it onto ``path`` on success.

    The temporary file lives in the same directory (so the rename is atomic on
    POSIX) and is removed if the block raises. The data is flushed and fsynced
    before the rename so that a power cut cannot leave an empty file behind.
    ``tmp_dir`` puts the temporary file in another directory of the same file system
    instead (still an atomic rename), e.g. to keep a directory that other programs
    list free of partial files.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    where = path.parent if tmp_dir is None else Path(tmp_dir)
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=where)
    except OSError as exc:  # a read-only or full file system: name the output, not the tmp
        raise _naming(exc, path, {str(exc.filename)}) from exc
    tmp = Path(tmp_name)
    try:
        os.fchmod(fd, 0o666 & ~_UMASK)
        encoding = None if "b" in mode else "utf-8"
        with os.fdopen(fd, mode, encoding=encoding) as fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except OSError as exc:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise _naming(exc, path, {str(tmp)}) from exc
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise


def _naming(exc: OSError, path: Path, ours: set[str]) -> OSError:
    """``exc`` naming ``path`` when it names no file (a full disk met by ``write`` or
    ``fsync``) or one of simlab's temporary names ``ours``: the user's message then says
    which output could not be written. Same class and errno; ``exc`` itself otherwise."""
    if exc.filename is not None and str(exc.filename) not in ours:
        return exc
    return type(exc)(exc.errno, exc.strerror or str(exc), str(path))


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_write(path, "w") as fh:
        fh.write(text)


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (e.g. a PNG rendered to bytes elsewhere)."""
    with atomic_write(path, "wb") as fh:
        fh.write(data)


def write_npy(fh: IO[bytes], array: Any) -> None:
    """``np.save(fh, array)`` (no pickle) through Python's file layer. NumPy writes an
    array to a real file with C stdio, and a full disk then surfaces as "N requested and M
    written" without an errno; written here, the OSError keeps ``ENOSPC`` and says "No
    space left on device"."""
    import io

    import numpy as np

    buf = io.BytesIO()
    np.save(buf, array, allow_pickle=False)
    fh.write(buf.getbuffer())


def atomic_write_json(path: str | os.PathLike[str], obj: Any) -> None:
    """Write ``obj`` as indented JSON to ``path`` atomically."""
    atomic_write_text(path, json.dumps(obj, indent=2, sort_keys=False) + "\n")


def read_toml(path: str | os.PathLike[str], *, what: str = "file",
              key: str | None = None) -> dict[str, Any]:
    """The tables of a TOML file; a missing or malformed file is a :class:`ConfigError`
    naming it (``what`` says which file it is: ``"primitives file"``)."""
    import tomllib

    path = Path(path)
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"{what} not found", path=path, key=key, fix="check the path") \
            from None
    except IsADirectoryError:
        raise ConfigError(f"expected a {what}, found a directory", path=path, key=key,
                          fix="give the TOML file inside it") from None
    except NotADirectoryError:
        raise ConfigError(f"{what} not found: a part of its path is a file", path=path,
                          key=key, fix="check the path") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"not valid TOML: {exc}", path=path) from None
    except RecursionError:
        raise ConfigError(NESTED_TOO_DEEPLY, path=path, key=key) from None


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

    Why ``flock`` here and filelock (simlab's lock library) everywhere else: filelock locks
    a file it opens read-write, so it cannot lock a directory (``FileLock(directory)``
    raises ``IsADirectoryError``, filelock 4.3), and the lock file it needs instead stays
    after release: one in or beside every ``--out`` the user names. The mechanism is the
    same (filelock is ``flock`` on POSIX).
    """
    import fcntl  # POSIX only; imported here so that simlab.base.io itself imports anywhere

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


class OutputTransaction:
    """The outputs of one command, staged in a hidden sibling directory until commit.

    Obtained from :func:`output_transaction`. ``txn.path(final)`` is where to write the file
    that must end up at ``final``; nothing appears under a final name before
    :meth:`commit` (called by the context manager when its block succeeds).
    """

    def __init__(self, out: Path, staging: Path, finals: tuple[Path, ...]) -> None:
        self.out = out
        self.staging = staging
        self.finals = finals
        self.retired: list[Path] = []

    def retire(self, final: str | os.PathLike[str]) -> None:
        """Remove ``final`` (a previous output of the same command that this run does not
        write again, e.g. the Q-table of a goal no longer trained) at :meth:`commit`, after
        the renames: a failed run removes nothing."""
        final = Path(final)
        # a path inside ``out`` as given (``out/q_NE.npz``, also when ``out`` is relative),
        # or a name relative to it, as :meth:`path` takes them
        target = final if _is_inside(final, self.out) else self.out / final
        if (final.is_absolute() and not _is_inside(final, self.out)) or \
                ".." in target.relative_to(self.out).parts:
            raise ValueError(f"{final} is not inside the output directory {self.out}")
        self.retired.append(target)

    def path(self, final: str | os.PathLike[str]) -> Path:
        """The staged path of ``final`` (a path inside ``out`` or a name relative to it)."""
        final = Path(final)
        rel = final.relative_to(self.out) if _is_inside(final, self.out) else final
        if rel.is_absolute() or ".." in rel.parts:
            raise ValueError(f"{final} is not inside the output directory {self.out}")
        staged = self.staging / rel
        staged.parent.mkdir(parents=True, exist_ok=True)
        return staged

    def commit(self) -> list[Path]:
        """Rename every staged file onto its final name; return the final paths written.

        Every file was written completely before the first rename, so an error while
        writing (a full disk, a kill) leaves the previous outputs untouched.
        """
        written = []
        for staged in sorted(p for p in self.staging.rglob("*") if not p.is_dir()):
            final = self.out / staged.relative_to(self.staging)
            final.parent.mkdir(parents=True, exist_ok=True)
            os.replace(staged, final)
            written.append(final)
        for old in self.retired:
            if old not in written:
                with contextlib.suppress(FileNotFoundError):
                    old.unlink()
        return written


def _is_inside(path: Path, directory: Path) -> bool:
    try:
        path.relative_to(directory)
    except ValueError:
        return False
    return True


def set_aside(target: Path, aside: Path) -> None:
    """Move the output ``target`` (a directory of the writer's own) to ``aside`` inside its
    staging folder, so that the new one can be renamed into place; it is deleted with the
    staging folder once the new one is there, and :func:`put_back` returns it if a Ctrl-C
    or a kill came in between (then it is the only copy)."""
    aside.parent.mkdir(parents=True, exist_ok=True)
    os.replace(target, aside)


def put_back(aside: Path, target: Path) -> None:
    """Return what :func:`set_aside` moved to ``aside`` when nothing took its place at
    ``target``; call it before the staging folder holding ``aside`` is removed."""
    if os.path.lexists(aside) and not os.path.lexists(target):
        target.parent.mkdir(parents=True, exist_ok=True)
        os.replace(aside, target)


#: Prefix of the staging directories of :func:`output_transaction` (left only by a kill;
#: removed by the next transaction on the same directory, which holds the lock).
STAGING_PREFIX = ".simlab-staging-"


@contextlib.contextmanager
def output_transaction(out: str | os.PathLike[str], finals: Any = (), *, overwrite: bool = False,
                       what: str = "output") -> Iterator[OutputTransaction]:
    """Lock the directory ``out``, stage the command's outputs, rename them all at the end.

    The ONE output mechanism of simlab commands that write several files (``train``,
    ``map``, ``estimate``, ``replay``, pipeline stages). Steps, in order:

    1. refuse ``out`` if it is an existing file, and every path of ``finals`` that exists
       unless ``overwrite`` (:func:`ensure_new`): before any work;
    2. take :func:`exclusive_directory` on ``out`` (a second writer stops at once);
    3. the caller writes to ``txn.path(final)`` inside a hidden staging directory
       ``out/.simlab-staging-*``;
    4. on success every staged file is renamed onto its final name; on any exception
       (including Ctrl-C) the staging directory is removed, and ``out`` too if this
       transaction created it and it is empty. A SIGKILL leaves only the staging directory,
       which the next transaction on ``out`` removes.
    """
    out = Path(out)
    finals = tuple(Path(f) for f in finals)
    if out.exists() and not out.is_dir():
        raise ConfigError(f"{what} directory exists and is not a directory", path=out,
                          fix="choose another --out, or remove the file in the way")
    for final in finals:
        if final.is_dir():
            raise ConfigError(f"{what} is a directory", path=final, fix="choose another path")
        ensure_new(final, overwrite=overwrite, what=what)
    created = not out.exists()
    try:
        with exclusive_directory(out, what=f"{what} directory"):
            for stale in out.glob(f"{STAGING_PREFIX}*"):  # left by a killed run; we hold the lock
                shutil.rmtree(stale, ignore_errors=True)
            staging = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=out))
            try:
                txn = OutputTransaction(out, staging, finals)
                yield txn
                written = txn.commit()
                logging.getLogger("simlab.base.io").info("%s: %d file(s) written", out, len(written))
            finally:
                shutil.rmtree(staging, ignore_errors=True)
    except BaseException as exc:
        if created:
            with contextlib.suppress(OSError):
                out.rmdir()  # only if empty: a failed first run must not block the rerun
        if isinstance(exc, OSError) and exc.filename is not None \
                and STAGING_PREFIX in str(exc.filename):
            raise unstaged_error(exc, out) from exc
        raise


def unstaged_error(exc: OSError, out: Path) -> OSError:
    """``exc`` naming the final output instead of its staged copy
    (``out/.simlab-staging-x/q_N.npz`` -> ``out/q_N.npz``): messages name the user's
    files, never simlab's hidden ones."""
    name = Path(str(exc.filename))
    parts = name.parts
    k = next(i for i, p in enumerate(parts) if p.startswith(STAGING_PREFIX))
    final = out.joinpath(*parts[k + 1:]) if k + 1 < len(parts) else out
    return type(exc)(exc.errno, exc.strerror or str(exc), str(final))


#: The first bytes of a zip archive (an ``.npz``) and of a single ``.npy`` array.
_ZIP_MAGIC, _NPY_MAGIC = b"PK\x03\x04", b"\x93NUMPY"


def npz_problem(path: str | os.PathLike[str], exc: BaseException) -> str:
    """What is wrong with ``path``, which ``np.load(path, allow_pickle=False)`` failed to
    read with ``exc``, in the user's terms: not an npz at all (a text file, other bytes),
    a damaged archive, or arrays of Python objects (which simlab never unpickles). NumPy
    says "contains pickled (object) data ... load it unsafely" for any file that is
    neither a zip nor an ``.npy``, advice that must not reach a user."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(512)
    except OSError as err:
        return f"cannot be read ({err.strerror or err})"
    if not head:
        return "the file is empty, not an npz archive"
    if not head.startswith((_ZIP_MAGIC, _NPY_MAGIC)):
        text = head.decode("utf-8", errors="replace")[:-2]  # a character cut at 512 bytes
        printable = all(c.isprintable() or c in "\r\n\t" for c in text) and "\ufffd" not in text
        kind = "a text file" if printable else "not a zip archive"
        return f"not an npz archive ({kind}; an .npz is a zip of .npy arrays)"
    if "pickle" in str(exc).lower() or "object" in str(exc).lower():
        return ("holds arrays of Python objects, which simlab never loads (unpickling runs "
                "code); only numeric and text arrays are read")
    return f"a damaged npz archive ({' '.join(str(exc).split())})"
