"""Gymnasium environments of the Visit-the-lab modules (thin wrappers over the kernels).

One env per file, each with a card docstring (Description, Actions, Observations,
Rewards, Termination, Variants): :mod:`.nav` (``simlab/VisitLab-Nav-v0``),
:mod:`.social` (``simlab/VisitLab-Social-v0``), :mod:`.gotohuman`
(``simlab/VisitLab-GoToHuman-v0``); :mod:`.base` holds what they share.

Each env keeps the world-state array of :mod:`simlab.visitlab.dynamics` and calls
the same numba kernels as the fused training loops, passing ``self.np_random``
(seeded by ``reset(seed=...)``), so an env and a kernel loop driven by the same
seed and actions produce the same trajectory. Render modes: ``"ansi"`` (text) and
``"rgb_array"``. ``variant="thesis"`` or ``"paper"`` sets the defaults listed in each
card; every default can be overridden by a keyword argument.
"""

from __future__ import annotations

from simlab.visitlab.envs.base import (
    PAPER_SOCIAL_GRID_SIZE,
    SOCIAL_GRID_SIZE,
    VARIANTS,
    GthKernelArgs,
    NavKernelArgs,
    SocialKernelArgs,
    decode_gth,
    decode_social,
    encode_social,
)
from simlab.visitlab.envs.gotohuman import GoToHumanEnv, StartPoses
from simlab.visitlab.envs.nav import NavEnv
from simlab.visitlab.envs.social import SocialEnv

__all__ = [
    "PAPER_SOCIAL_GRID_SIZE",
    "SOCIAL_GRID_SIZE",
    "VARIANTS",
    "GoToHumanEnv",
    "GthKernelArgs",
    "NavEnv",
    "NavKernelArgs",
    "SocialEnv",
    "SocialKernelArgs",
    "StartPoses",
    "decode_gth",
    "decode_social",
    "encode_social",
]
