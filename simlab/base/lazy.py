"""Modules whose public names are imported only when first used (PEP 562).

Keeps ``import simlab.data`` or ``simlab --help`` cheap: PyBullet, numba kernels, pyarrow
and the like load when a name that needs them is touched.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any


def lazy_exports(
    module: str, targets: Mapping[str, str]
) -> tuple[list[str], Callable[[str], Any], Callable[[], list[str]]]:
    """``(__all__, __getattr__, __dir__)`` for ``module``.

    ``targets`` maps each public name to ``"package.module"`` (the same name is taken from
    it) or ``"package.module:attribute"``.
    """
    names = sorted(targets)

    def __getattr__(name: str) -> Any:
        try:
            target = targets[name]
        except KeyError:
            raise AttributeError(f"module {module!r} has no attribute {name!r}") from None
        source, _, attribute = target.partition(":")
        return getattr(importlib.import_module(source), attribute or name)

    def __dir__() -> list[str]:
        return names

    return names, __getattr__, __dir__
