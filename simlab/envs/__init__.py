"""Gymnasium environment registration.

Entry points are strings so that ``import simlab`` stays cheap: PyBullet, numba
kernels and the like load only when ``gymnasium.make`` builds an environment.
"""

from __future__ import annotations

import gymnasium as gym

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
    """Register every simlab environment with Gymnasium (idempotent)."""
    for env_id, entry_point in ENV_ENTRY_POINTS.items():
        if env_id not in gym.registry:
            limit, kwargs = ENV_LIMITS.get(env_id, (None, {}))
            gym.register(id=env_id, entry_point=entry_point, max_episode_steps=limit,
                         kwargs=dict(kwargs))
