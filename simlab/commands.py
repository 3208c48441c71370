"""Every ``simlab`` subcommand as a Python function.

``simlab.commands.drive(arena="table", steps=100, seed=0)`` does what
``simlab drive --arena table --steps 100 --seed 0`` does and returns its result
object instead of printing. Functions are imported lazily from the modules that
own them, so this module is cheap to import.
"""

from __future__ import annotations

import importlib
from typing import Any

#: Function name -> "module:attribute".
_FUNCTIONS: dict[str, str] = {
    "drive": "simlab.physics.drive:drive",
    "map": "simlab.mapping:build_map",
    "discretize": "discretize.voronoi:discretize_map",
    "collect": "simlab.data.collect:collect",
    "estimate": "simlab.data.estimate:estimate",
    "export_minari": "simlab.data.minari_export:export_minari",
    "train": "simlab.training.train:train",
    "replay": "simlab.replay.replay:replay",
    "pipeline": "simlab.pipeline:pipeline",
    "visitlab_train": "simlab.visitlab.training:train",
    "reproduce": "simlab.experiments.reproduce:reproduce",
}

__all__ = sorted(_FUNCTIONS)


def __getattr__(name: str) -> Any:
    try:
        target = _FUNCTIONS[name]
    except KeyError:
        raise AttributeError(f"module 'simlab.commands' has no attribute {name!r}") from None
    module_name, attr = target.split(":")
    return getattr(importlib.import_module(module_name), attr)


def __dir__() -> list[str]:
    return __all__
