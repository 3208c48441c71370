"""The runner registry: ``"group.name"`` -> a function ``run(params, budget, ctx)``.

Runners register themselves with :func:`runner` when their module is imported; the
module of a group is imported lazily from :data:`RUNNER_MODULES` the first time a key of
that group is looked up (so ``simlab reproduce --help`` imports no runner and no numpy).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from simlab.base.errors import ConfigError

if TYPE_CHECKING:
    from simlab.experiments.context import RunContext, RunResult

    RunnerFn = Callable[[dict[str, Any], dict[str, Any], RunContext], RunResult]
else:
    RunnerFn = Callable[..., Any]

#: Group (the part of a key before the first dot) -> module defining its runners.
RUNNER_MODULES: dict[str, str] = {
    "example": "simlab.experiments.example",
    "physics": "simlab.experiments.physics",
    "social": "simlab.experiments.social",
    "visitlab": "simlab.experiments.visitlab",
    "online": "simlab.online.experiments",
}

_REGISTRY: dict[str, RunnerFn] = {}


def runner(key: str) -> Callable[[RunnerFn], RunnerFn]:
    """Decorator registering a module-level function as the runner ``key``.

    ``key`` must start with a group of :data:`RUNNER_MODULES` (``"physics.entropy"``).
    Registering the same key twice with different functions raises ``ValueError``.
    """
    group = key.split(".", 1)[0]
    if "." not in key or group not in RUNNER_MODULES:
        raise ValueError(f"runner key {key!r} must be '<group>.<name>' with a group of "
                         f"{sorted(RUNNER_MODULES)}")

    def register(fn: RunnerFn) -> RunnerFn:
        old = _REGISTRY.get(key)
        if old is not None and (old.__module__, old.__qualname__) != (fn.__module__,
                                                                       fn.__qualname__):
            raise ValueError(f"runner {key!r} is already registered by "
                             f"{old.__module__}.{old.__qualname__}")
        _REGISTRY[key] = fn
        return fn

    return register


def get_runner(key: str) -> RunnerFn:
    """The runner registered as ``key``, importing its group's module if needed.

    Raises :class:`ConfigError` for an unknown group, a group module that does not exist
    (yet), or a key its module does not define.
    """
    if key in _REGISTRY:
        return _REGISTRY[key]
    group = key.split(".", 1)[0]
    module = RUNNER_MODULES.get(group)
    if module is None:
        raise ConfigError(f"unknown runner {key!r}: no runner group {group!r}",
                          fix=f"groups: {', '.join(sorted(RUNNER_MODULES))}")
    try:
        importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name is not None and module.startswith(exc.name):
            raise ConfigError(f"unknown runner {key!r}: its module {module} does not exist",
                              fix="is that part of simlab installed?") from None
        raise
    if key not in _REGISTRY:
        known = sorted(k for k in _REGISTRY if k.startswith(group + "."))
        raise ConfigError(f"unknown runner {key!r}",
                          fix=f"{module} defines: {', '.join(known) or 'none'}")
    return _REGISTRY[key]


def registered() -> dict[str, RunnerFn]:
    """A copy of the runners registered so far (modules already imported)."""
    return dict(_REGISTRY)
