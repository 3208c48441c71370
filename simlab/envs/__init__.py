"""Gymnasium environment registration.

Entry points are strings so that ``import simlab`` stays cheap: PyBullet, numba
kernels and the like load only when ``gymnasium.make`` builds an environment.

Gymnasium itself (0.1-0.4 s to import) is not imported by ``import simlab`` either:
:func:`register_when_imported` registers the environments at once if
Gymnasium is already imported, and otherwise the moment it is (a one-shot import hook),
so ``import simlab; import gymnasium as gym; gym.make("simlab/...")`` works as before
while the pipeline's worker processes, which never make an environment, skip it.
"""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import sys
from typing import Any

#: id -> "module:Class" entry point. One line per environment.
ENV_ENTRY_POINTS: dict[str, str] = {
    "simlab/TableArena-v0": "simlab.envs.table_arena:TableArenaEnv",
    "simlab/TableArenaStates-v0": "simlab.envs.table_states:TableArenaStatesEnv",
    "simlab/EmpiricalMDP-v0": "simlab.envs.empirical_mdp:EmpiricalMDPEnv",
    "simlab/VisitLab-Nav-v0": "simlab.visitlab.envs:NavEnv",
    "simlab/VisitLab-Social-v0": "simlab.visitlab.envs:SocialEnv",
    "simlab/VisitLab-GoToHuman-v0": "simlab.visitlab.envs:GoToHumanEnv",
    "simlab/TableSocial-v0": "simlab.social.env:TableSocialEnv",
}

#: The ids whose env steps a PyBullet world: each takes ``physics_hz`` (Hz,
#: :mod:`simlab.physics.rate`; default the rate of ``collect`` and ``replay``).
PHYSICS_ENV_IDS = ("simlab/TableArena-v0", "simlab/TableArenaStates-v0",
                   "simlab/TableSocial-v0")

#: Episode limits registered with Gymnasium (``spec.max_episode_steps``; ``TimeLimit``
#: truncates, ``gym.make(id, max_episode_steps=N)`` overrides), and the keyword that turns
#: the env's own limit off so only the registered one applies. Thesis: 50-step trials.
#: The Visit-the-lab envs are registered with their thesis trial lengths (navigation 50,
#: social and go-to-human 40) and ``max_steps=None``; ``gym.make(id, variant="paper")``
#: therefore also gets these lengths unless ``max_episode_steps`` (or ``max_steps``)
#: is given.
ENV_LIMITS: dict[str, tuple[int, dict[str, None]]] = {
    "simlab/TableArena-v0": (50, {"max_steps": None}),
    "simlab/TableArenaStates-v0": (50, {"max_steps": None}),
    "simlab/EmpiricalMDP-v0": (50, {"horizon": None}),
    "simlab/VisitLab-Nav-v0": (50, {"max_steps": None}),
    "simlab/VisitLab-Social-v0": (40, {"max_steps": None}),
    "simlab/VisitLab-GoToHuman-v0": (40, {"max_steps": None}),
    "simlab/TableSocial-v0": (40, {"max_steps": None}),
}


def register_envs() -> None:
    """Register every simlab environment with Gymnasium (idempotent; imports Gymnasium)."""
    import gymnasium as gym

    for env_id, entry_point in ENV_ENTRY_POINTS.items():
        if env_id not in gym.registry:
            limit, kwargs = ENV_LIMITS.get(env_id, (None, {}))
            gym.register(id=env_id, entry_point=entry_point, max_episode_steps=limit,
                         kwargs=dict(kwargs))


class _RegisterOnLoad(importlib.abc.Loader):
    """Runs Gymnasium's own loader, then :func:`register_envs`."""

    def __init__(self, loader: Any) -> None:
        self._loader = loader

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> Any:
        return self._loader.create_module(spec)

    def exec_module(self, module: Any) -> None:
        self._loader.exec_module(module)
        register_envs()


class _GymnasiumHook(importlib.abc.MetaPathFinder):
    """One-shot finder: wraps the loader of the top-level ``gymnasium`` import."""

    def find_spec(self, name: str, path: Any = None, target: Any = None) -> Any:
        if name != "gymnasium":
            return None
        _remove_hook()
        spec = importlib.machinery.PathFinder.find_spec(name, path)
        if spec is None or spec.loader is None:
            return spec
        spec.loader = _RegisterOnLoad(spec.loader)
        return spec


def _remove_hook() -> None:
    sys.meta_path[:] = [f for f in sys.meta_path if not isinstance(f, _GymnasiumHook)]


def register_when_imported() -> None:
    """Register the environments now if Gymnasium is imported, else when it is."""
    if "gymnasium" in sys.modules:
        register_envs()
    elif not any(isinstance(f, _GymnasiumHook) for f in sys.meta_path):
        sys.meta_path.insert(0, _GymnasiumHook())
