"""The ``mcl`` pose source as registered by :mod:`simlab.data.walkers`
(``"mcl": "simlab.replay.localization:make_pose_source"``); it lives in
:mod:`simlab.localization.tracker`."""

from __future__ import annotations

from simlab.localization.tracker import MCLPoseSource, make_pose_source

__all__ = ["MCLPoseSource", "make_pose_source"]
