"""LIDAR localization on an occupancy map: Monte Carlo localization (a particle filter).

Layers: :mod:`~simlab.localization.likelihood` (the likelihood-field sensor model),
:mod:`~simlab.localization.motion` (the odometry motion model),
:mod:`~simlab.localization.filter` (the particle filter with augmented-MCL recovery),
:mod:`~simlab.localization.tracker` (the physics scan callback, the error log and the
``mcl`` pose source), :mod:`~simlab.localization.maps` (maps to localize on and the check
that a map belongs to its arena). Nothing here imports PyBullet.
"""

from __future__ import annotations

from simlab.base.lazy import lazy_exports

# Lazy (PEP 562): the pose-source names (:mod:`~simlab.localization.sources`) are read by
# the CLI's parsers, which must not pay for scipy and the filter at ``simlab --help``.
_LAZY = {
    "LikelihoodField": "simlab.localization.likelihood",
    "LocalizationLog": "simlab.localization.tracker",
    "MCLParams": "simlab.localization.filter",
    "MCLPoseSource": "simlab.localization.tracker",
    "MCLTracker": "simlab.localization.tracker",
    "OdometryMotionParams": "simlab.localization.motion",
    "ParticleFilter": "simlab.localization.filter",
    "SensorModelParams": "simlab.localization.likelihood",
    "arena_map": "simlab.localization.maps",
    "check_map_matches_arena": "simlab.localization.maps",
    "load_map_for_arena": "simlab.localization.maps",
    "sample_odometry_motion": "simlab.localization.motion",
}

__all__, __getattr__, __dir__ = lazy_exports(__name__, _LAZY)
