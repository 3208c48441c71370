"""The one place simlab imports PyBullet, with its console chatter silenced.

PyBullet writes to the C-level stdout/stderr on import, on connect and when it merges URDF links;
that would garble CLI output and progress bars. Library modules import ``pybullet`` and
``BulletClient`` from here and wrap noisy calls in :func:`quiet_stdout`.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import sys
from collections.abc import Iterator

try:
    _libc = ctypes.CDLL(None)
except OSError:  # pragma: no cover - platforms without a loadable C library
    _libc = None


def _flush_c_stdio() -> None:
    # C printf output sits in stdio's buffer (fully buffered on pipes) and would be written
    # after the redirection ends; flush it while stdout still points at /dev/null.
    if _libc is not None:
        _libc.fflush(None)


@contextlib.contextmanager
def quiet_stdout() -> Iterator[None]:
    """Silence C-level writes to stdout and stderr for the duration of the block.

    PyBullet reports failures as Python exceptions, so nothing of value is lost; its
    console output is a build banner, ``argv[0]=`` and URDF parsing chatter.
    """
    fds = []
    for stream, default in ((sys.stdout, 1), (sys.stderr, 2)):
        try:
            fds.append(stream.fileno())
        except (AttributeError, OSError, ValueError):  # replaced streams (pytest capture)
            fds.append(default)
        stream.flush()
    saved = [os.dup(fd) for fd in fds]
    try:
        with open(os.devnull, "wb") as devnull:
            for fd in fds:
                os.dup2(devnull.fileno(), fd)
            try:
                yield
            finally:
                _flush_c_stdio()
    finally:
        for fd, keep in zip(fds, saved, strict=True):
            os.dup2(keep, fd)
            os.close(keep)


with quiet_stdout():
    import pybullet
    from pybullet_utils.bullet_client import BulletClient as _BulletClient


class BulletClient(_BulletClient):
    """pybullet_utils' client, safe to lose half-made.

    Its ``__init__`` stores the client id only once ``pybullet.connect`` returns, and its
    ``__del__`` reads that id: a Ctrl-C inside ``connect`` (e.g. while Minari builds the env
    of an export to read its spaces) left an object whose ``__del__`` fell through to
    ``getattr(pybullet, "_client")`` and printed an ignored ``AttributeError`` traceback
    after the command's one-line report. The class default ``-1`` (no connection) makes
    that ``__del__`` a no-op.
    """

    _client = -1

__all__ = ["BulletClient", "pybullet", "quiet_stdout"]
