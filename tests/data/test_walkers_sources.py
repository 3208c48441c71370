"""Pose-source names and the factory live in one place (simlab.localization.sources)."""

from __future__ import annotations

import pytest

from simlab.base.errors import ConfigError
from simlab.data import walkers
from simlab.localization import sources


def test_one_list_of_names_and_one_factory() -> None:
    assert sources.POSE_SOURCES == ("truth", "odometry", "mcl")
    assert set(sources.SCANLESS_POSE_SOURCES) < set(sources.POSE_SOURCES)
    # the walkers use the localization layer's objects, not a string registry
    assert walkers.POSE_SOURCES is sources.POSE_SOURCES
    assert walkers.make_pose_source is sources.make_pose_source
    assert isinstance(sources.make_pose_source("truth", None), sources.TruthPose)
    odo = sources.make_pose_source("odometry", None, {})
    assert isinstance(odo, sources.OdometryPose) and not odo.needs_scans


def test_unknown_and_unusable_pose_sources_are_refused() -> None:
    with pytest.raises(ConfigError, match="unknown pose source 'gps'"):
        sources.make_pose_source("gps", None)
    with pytest.raises(ConfigError, match="pose_source"):
        walkers.check_pose_source("gps", "physics")
    with pytest.raises(ConfigError, match="kinematic simulator has no LIDAR"):
        walkers.check_pose_source("mcl", "kinematic")
    walkers.check_pose_source("mcl", "physics")  # available: no error
    with pytest.raises(ConfigError, match="needs a LIDAR"):
        sources.check_pose_source_name("mcl", scanless=True)


def test_no_string_registry_left() -> None:
    import importlib.util

    assert importlib.util.find_spec("simlab.replay.localization") is None
