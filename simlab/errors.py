"""Errors meant for people.

Library code raises these; only the command-line interface turns them into a
one-line message and exit code 2 (see :mod:`simlab.cli`).
"""

from __future__ import annotations

from os import PathLike


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
