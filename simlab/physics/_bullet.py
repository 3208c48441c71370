"""The one place simlab imports PyBullet, with its console chatter silenced.

PyBullet writes to the C-level stdout on import, on connect and when it merges URDF links;
that would garble CLI output and progress bars. Library modules import ``pybullet`` and
``BulletClient`` from here and wrap noisy calls in :func:`quiet_stdout`.
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Iterator


@contextlib.contextmanager
def quiet_stdout() -> Iterator[None]:
    """Silence C-level writes to stdout for the duration of the block."""
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):  # stdout replaced (pytest capture, IDEs)
        fd = 1
    sys.stdout.flush()
    saved = os.dup(fd)
    try:
        with open(os.devnull, "wb") as devnull:
            os.dup2(devnull.fileno(), fd)
            yield
    finally:
        os.dup2(saved, fd)
        os.close(saved)


with quiet_stdout():
    import pybullet
    from pybullet_utils.bullet_client import BulletClient

__all__ = ["BulletClient", "pybullet", "quiet_stdout"]
