"""Pose sources: the names and the one factory (what a robot believes its pose is).

A *pose source* turns the robot's sensing into the poses a dataset records or a replay
decides from:

* ``truth`` — the simulator's ground-truth pose of the wheel-axis centre;
* ``odometry`` — the wheel encoders (drift);
* ``mcl`` — the LIDAR particle filter (:class:`~simlab.localization.tracker.MCLPoseSource`)
  on the occupancy map.

:data:`POSE_SOURCES` is the one list of these names (argparse choices, config checks and
the factory read it); :data:`SCANLESS_POSE_SOURCES` those that need no LIDAR (the
kinematic simulator and the mapping run offer only these). :func:`make_pose_source` is
the one factory (no string registry: the classes are imported here directly).
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from simlab.base.errors import ConfigError

__all__ = ["POSE_SOURCES", "SCANLESS_POSE_SOURCES", "OdometryPose", "PoseSource", "TruthPose",
           "check_pose_source_name", "make_pose_source"]

#: Every pose source name, in the order the help texts list them.
POSE_SOURCES: tuple[str, ...] = ("truth", "odometry", "mcl")
#: The pose sources that need no LIDAR scans.
SCANLESS_POSE_SOURCES: tuple[str, ...] = ("truth", "odometry")


class PoseSource(Protocol):
    """Turns the robot's sensing into the poses a dataset records.

    ``needs_scans``: whether :meth:`on_scan` must be called during primitives (5 Hz of
    simulated time; it slows the walk down). ``reset`` is called after every world
    reset with the part's pose-source Generator; ``poses`` returns the (before, after)
    poses (3,) of one :class:`~simlab.physics.motion.PrimitiveResult`.
    """

    needs_scans: bool

    def reset(self, world: Any, rng: np.random.Generator) -> None: ...

    def on_scan(self, scan: Any, odom: NDArray[np.float64]) -> None: ...

    def poses(self, result: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...


class TruthPose:
    """The simulator's ground-truth pose of the wheel-axis centre."""

    needs_scans = False

    def __init__(self, world: Any = None) -> None:
        del world

    def reset(self, world: Any, rng: np.random.Generator) -> None:
        del world, rng

    def on_scan(self, scan: Any, odom: NDArray[np.float64]) -> None:
        del scan, odom

    def poses(self, result: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return np.asarray(result.pose_before), np.asarray(result.pose_after)


class OdometryPose(TruthPose):
    """Wheel-encoder odometry (drifts; restarts from the truth pose at each reset)."""

    def poses(self, result: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return np.asarray(result.odom_before), np.asarray(result.odom_after)


def check_pose_source_name(name: Any, *, scanless: bool = False) -> str:
    """``name`` if it is a pose source (one of :data:`SCANLESS_POSE_SOURCES` with
    ``scanless``); ConfigError (key ``pose_source``) otherwise."""
    allowed = SCANLESS_POSE_SOURCES if scanless else POSE_SOURCES
    if name not in allowed:
        raise ConfigError(f"unknown pose source {name!r}" if name not in POSE_SOURCES else
                          f"the pose source {name!r} needs a LIDAR, not available here",
                          key="pose_source", fix=f"choose one of {', '.join(allowed)}")
    return str(name)


def make_pose_source(name: str, world: Any, options: dict[str, Any] | None = None
                     ) -> PoseSource:
    """Build the pose source ``name`` for ``world``. ``options`` are the keyword arguments
    of the ``mcl`` source (``map``, ``initial_std`` and fields of
    :class:`~simlab.localization.filter.MCLParams`); ``truth``/``odometry`` take none."""
    check_pose_source_name(name)
    options = dict(options or {})
    if name == "mcl":
        from simlab.localization.tracker import MCLPoseSource

        return MCLPoseSource(world, **options)
    if options:
        raise ConfigError(f"the {name} pose source takes no options, got "
                          f"{', '.join(sorted(options))}", key="pose_source_options",
                          fix="drop them, or use the mcl pose source")
    return (TruthPose if name == "truth" else OdometryPose)(world, **options)
