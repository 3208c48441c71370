"""``simlab import-bag``: a robot's ROS 2 bag -> a simlab transition dataset.

* **Pose**: ``/amcl_pose`` (the localizer's map-frame pose) when the bag has it, else
  ``/odom``, or the topic given (``PoseWithCovarianceStamped``, ``PoseStamped`` or
  ``Odometry``). Samples are sorted by header stamp; times are seconds since the first.
* **Decisions without an action topic**: exactly the pose-log importer's
  (:func:`simlab.data.poselog.segment_decisions` and
  :func:`~simlab.data.poselog.decision_actions` on the same arrays), so a bag and a pose
  log of one trajectory give the same transitions.
* **Decisions with an action topic** (``std_msgs/Int32``, default ``/simlab/action``, the
  action index in the declared action set): decision k starts at the last pose sample at
  or before the k-th action message and ends at the last sample before the next one (the
  last sample for the final action). It is **blocked** when no interval of it is a
  ``move`` in the pose-log labelling (:func:`~simlab.data.poselog.interval_labels`): the
  robot did not translate.
* **Scans** (optional ``/scan``) are not needed for the transitions; their number is
  recorded in the provenance.
* **States**: nearest centre of the states file (the writer's rule). Written with
  :func:`simlab.data.writer.write_dataset`, pose source ``log``.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from simlab.errors import ConfigError


@dataclass(frozen=True)
class ImportBagResult:
    """What was imported: dataset directory, pose samples, decisions, blocked ones, and
    where the actions came from (``segmentation`` or the action topic)."""

    out: Path
    samples: int
    decisions: int
    blocked: int
    action_source: str


def _decisions_from_actions(t: np.ndarray, xy: np.ndarray, yaw: np.ndarray,
                            actions: np.ndarray, action_t: np.ndarray, segment: Any,
                            n_actions: int) -> tuple[np.ndarray, ...]:
    """``(start, end, blocked, actions)`` of the decisions announced by an action topic."""
    from simlab.data.poselog import interval_labels

    if np.any((actions < 0) | (actions >= n_actions)):
        raise ConfigError(f"action topic has indices outside 0..{n_actions - 1}", key="actions")
    keep = action_t >= t[0]
    actions, action_t = actions[keep], action_t[keep]
    start = np.searchsorted(t, action_t, side="right") - 1
    end = np.append(start[1:], len(t) - 1)
    ok = end > start  # two actions within one pose interval: the first has no motion
    start, end, actions = start[ok], end[ok], actions[ok]
    moving = interval_labels(t, xy, yaw, segment) == 2
    cum = np.concatenate([[0], np.cumsum(moving)])
    blocked = (cum[end] - cum[start]) == 0
    return start, end, blocked, actions


def import_bag(
    bag: str | os.PathLike[str],
    *,
    states: Any,
    out: str | os.PathLike[str],
    n_actions: int = 8,
    convention: str = "ccw-east",
    pose_topic: str | None = None,
    action_topic: str | None = "/simlab/action",
    segment: Any = None,
    overwrite: bool = False,
) -> ImportBagResult:
    """Import a bag (module docstring). ``states``: states file or discretizer;
    ``n_actions``/``convention``: the action set (as ``import-log``); ``segment``:
    :class:`~simlab.data.poselog.SegmentParams` thresholds; ``action_topic=None`` forces
    the segmentation even when the bag has an action topic."""
    from discretize.voronoi import load_states
    from simlab.actions import parse_action_set
    from simlab.data.poselog import SegmentParams, decision_actions, segment_decisions
    from simlab.data.writer import DatasetInfo, TransitionArrays, write_dataset
    from simlab.ros.bag import read_bag

    aset = parse_action_set(n_actions, convention)
    segment = SegmentParams() if segment is None else segment
    disc = load_states(states) if isinstance(states, str | os.PathLike) else states
    traj = read_bag(bag, pose_topic=pose_topic, action_topic=action_topic)
    t, xy, yaw = traj.t, traj.pose[:, :2], traj.pose[:, 2]
    if traj.actions is not None:
        start, end, blocked, actions = _decisions_from_actions(
            t, xy, yaw, traj.actions, traj.action_t, segment, aset.n_actions)
        source = f"action topic {action_topic}"
    else:
        dec = segment_decisions(t, xy, yaw, segment)
        start, end, blocked = dec.start, dec.end, dec.blocked
        actions = decision_actions(dec, aset, segment) if len(dec) else np.zeros(0, np.int64)
        source = "segmentation of the pose (as simlab import-log)"
    if len(start) == 0:
        raise ConfigError("no decision found in the bag (nothing turns or moves faster than "
                          "the thresholds, and no action messages)", path=bag)
    walk = TransitionArrays(t=t[start], a=actions, pose=traj.pose[start],
                            pose_next=traj.pose[end], blocked=blocked,
                            duration=t[end] - t[start])
    info = DatasetInfo(
        discretizer=disc, action_set=aset, pose_source="log",
        provenance={"importer": "simlab import-bag", "bag": str(bag),
                    "states": str(states) if isinstance(states, str | os.PathLike) else None,
                    "samples": len(t), "scans": 0 if traj.scans is None else len(traj.scans),
                    "pose_topic": pose_topic or "auto", "action_source": source,
                    "segmentation": asdict(segment)},
        arena={"name": Path(bag).name, "file": None, "bounds": None, "goals": []},
        parameters={"importer": "ros-bag"})
    res = write_dataset(out, walk, info, overwrite=overwrite)
    return ImportBagResult(out=res.out, samples=len(t), decisions=len(start),
                           blocked=int(np.sum(blocked)), action_source=source)
