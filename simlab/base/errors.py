"""Errors meant for people.

Library code raises these; only the command-line interface turns them into a
one-line message and exit code 2 (see :mod:`simlab.cli`).
"""

from __future__ import annotations

from os import PathLike
from os import sep as _sep
from pathlib import Path as _Path
from typing import TextIO


class SimlabError(Exception):
    """Base class of every error simlab raises on purpose (bad input, bad files)."""


class ConfigError(SimlabError, ValueError):
    """A configuration value or input file is wrong.

    The message names the file (when there is one), the key or field, the problem
    and, where it helps, the fix: ``arenas/x.toml: [walls] height: expected a
    number > 0, got -1``.
    """

    def __init__(
        self,
        problem: str,
        *,
        path: str | PathLike[str] | None = None,
        key: str | None = None,
        fix: str | None = None,
    ) -> None:
        self.path = None if path is None else str(path)
        self.key = key
        self.problem = problem
        self.fix = fix
        parts = []
        if self.path is not None:
            parts.append(f"{self.path}:")
        if key is not None:
            parts.append(f"{key}:")
        parts.append(problem)
        message = " ".join(parts)
        if fix:
            message += f" ({fix})"
        super().__init__(message)


class DataError(SimlabError, ValueError):
    """A data file (dataset part, manifest, npz, map image) is missing or corrupt."""


#: Source folders whose frames :func:`warn` skips: simlab's and discretize's packages.
_OURS = tuple(str(_Path(__file__).parents[2] / pkg) + _sep
              for pkg in ("simlab", "discretize"))


def warn(message: str, category: type[Warning] = UserWarning) -> None:
    """``warnings.warn`` attributed to the first caller outside simlab and discretize.

    A warning is about the caller's input, so its location should be the caller's line,
    whatever the depth of simlab's own calls in between (the ``@command`` wrapper, stage
    helpers). Counting that depth by hand at every call (``stacklevel=3``) breaks when a
    call path changes. (Python 3.12's ``skip_file_prefixes`` does the same.) When every
    frame is simlab's (``python -m simlab``), the outermost one is used."""
    import sys
    import warnings

    frame, level = sys._getframe(1), 2
    while frame.f_back is not None and frame.f_code.co_filename.startswith(_OURS):
        frame, level = frame.f_back, level + 1
    warnings.warn(message, category, stacklevel=level)


#: The environment variable through which the command line's warning format reaches the
#: worker processes a command starts (they inherit its environment): the line prefix
#: (``simlab collect``), or empty when ``-q`` hides warnings. Unset outside the CLI.
WARNING_PREFIX_ENV = "SIMLAB_WARNING_PREFIX"

#: The environment variable naming the folder where the command line and its worker
#: processes mark the warnings they printed (one empty file per text; the first warning
#: makes the folder, the command line removes it at its end), so that a warning
#: about the command's input prints once, not once per process that meets it (every
#: worker of a calibration reads the same states and would repeat the driver's warning).
WARNINGS_SHOWN_ENV = "SIMLAB_WARNINGS_SHOWN"


def _first_time(text: str, shown: set[str]) -> bool:
    """Whether ``text`` is printed for the first time by this command: by this process
    (``shown``), and, under the command line, by any of its processes (a file per text in
    the folder of :data:`WARNINGS_SHOWN_ENV`, created exclusively: one process wins)."""
    import hashlib
    import os

    if text in shown:
        return False
    shown.add(text)
    folder = os.environ.get(WARNINGS_SHOWN_ENV)
    if not folder:
        return True
    name = hashlib.sha256(text.encode()).hexdigest()[:32]
    try:
        os.makedirs(folder, exist_ok=True)
        os.close(os.open(os.path.join(folder, name), os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except FileExistsError:
        return False
    except OSError:  # no folder can be made there: print rather than lose the warning
        return True
    return True


def show_warnings_as(prefix: str | None) -> None:
    """Print every Python warning of this process as one line ``<prefix>: warning: ...``
    on stderr (whitespace runs as single spaces, no source line), each text once per
    command (see :data:`WARNINGS_SHOWN_ENV`); None: print none."""
    import sys
    import warnings

    shown: set[str] = set()

    def show(message: Warning | str, category: type[Warning], filename: str, lineno: int,
             file: TextIO | None = None, line: str | None = None) -> None:
        if prefix is not None:
            text = " ".join(str(message).split())
            if _first_time(text, shown):
                print(f"{prefix}: warning: {text}", file=sys.stderr)

    warnings.showwarning = show
