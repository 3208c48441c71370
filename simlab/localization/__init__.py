"""LIDAR localization on an occupancy map: Monte Carlo localization (a particle filter).

Layers: :mod:`~simlab.localization.likelihood` (the likelihood-field sensor model),
:mod:`~simlab.localization.motion` (the odometry motion model),
:mod:`~simlab.localization.filter` (the particle filter with augmented-MCL recovery),
:mod:`~simlab.localization.tracker` (the physics scan callback, the error log and the
``mcl`` pose source), :mod:`~simlab.localization.maps` (maps to localize on and the check
that a map belongs to its arena). Nothing here imports PyBullet.
"""

from __future__ import annotations

from simlab.localization.filter import MCLParams, ParticleFilter
from simlab.localization.likelihood import LikelihoodField, SensorModelParams
from simlab.localization.maps import arena_map, check_map_matches_arena, load_map_for_arena
from simlab.localization.motion import OdometryMotionParams, sample_odometry_motion
from simlab.localization.tracker import LocalizationLog, MCLPoseSource, MCLTracker

__all__ = [
    "LikelihoodField",
    "LocalizationLog",
    "MCLParams",
    "MCLPoseSource",
    "MCLTracker",
    "OdometryMotionParams",
    "ParticleFilter",
    "SensorModelParams",
    "arena_map",
    "check_map_matches_arena",
    "load_map_for_arena",
    "sample_odometry_motion",
]
