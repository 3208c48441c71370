"""Gymnasium environment registration.

Entry points are strings so that ``import simlab`` stays cheap: PyBullet, numba
kernels and the like load only when ``gymnasium.make`` builds an environment.
"""

from __future__ import annotations

import gymnasium as gym

#: id -> "module:Class" entry point. One line per environment.
ENV_ENTRY_POINTS: dict[str, str] = {
    "simlab/TableArena-v0": "simlab.envs.table_arena:TableArenaEnv",
    "simlab/EmpiricalMDP-v0": "simlab.envs.empirical_mdp:EmpiricalMDPEnv",
    "simlab/VisitLab-Nav-v0": "simlab.visitlab.envs:NavEnv",
    "simlab/VisitLab-Social-v0": "simlab.visitlab.envs:SocialEnv",
    "simlab/VisitLab-GoToHuman-v0": "simlab.visitlab.envs:GoToHumanEnv",
}


def register_envs() -> None:
    """Register every simlab environment with Gymnasium (idempotent)."""
    for env_id, entry_point in ENV_ENTRY_POINTS.items():
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=entry_point)
