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

The options are the fields of :class:`ImportBagConfig`; the action numbering and the
thresholds are ``import-log``'s option groups
(:class:`~simlab.data.poselog.RobotActionOptions`,
:class:`~simlab.data.poselog.SegmentOptions`).
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from simlab.data.poselog import RobotActionOptions, SegmentOptions
from simlab.errors import ConfigError
from simlab.options import command, option


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


@dataclass(frozen=True, kw_only=True)
class ImportBagConfig(RobotActionOptions, SegmentOptions):
    """Options of ``simlab import-bag`` / :func:`import_bag`."""

    COMMAND = "import-bag"
    ARGUMENTS = ("bag",)

    bag: Path = option(help="ROS 2 bag directory (MCAP or sqlite3)", positional=True)
    states: Any = option(help="states: `simlab discretize` JSON or centres text (from Python "
                         "also a discretizer)")
    out: Path = option(help="dataset directory to write")
    pose_topic: str | None = option(None, "pose topic (default: /amcl_pose if present, else "
                                    "/odom)")
    action_topic: str | None = option(
        "/simlab/action", "std_msgs/Int32 action topic; absent from the bag -> the pose "
        "segmentation of import-log (from Python, None = --segment)")
    segment: bool = option(False, "ignore the action topic and segment the poses")
    overwrite: bool = option(False, "replace a dataset in --out")

    @property
    def actions_from(self) -> str | None:
        """The action topic to read, None when the poses are to be segmented."""
        return None if self.segment else self.action_topic


@command(ImportBagConfig)
def import_bag(cfg: ImportBagConfig) -> ImportBagResult:
    """Import a bag (module docstring). Takes an :class:`ImportBagConfig` or its fields
    (``import_bag(bag, states=..., out=...)``). ``states``: states file or discretizer;
    ``n_actions``/``convention``: the action set (as ``import-log``); ``move_speed``,
    ``turn_rate``, ``join_gap``, ``speed_split``: the
    :class:`~simlab.data.poselog.SegmentParams` thresholds; ``segment=True`` (or
    ``action_topic=None``) forces the segmentation even when the bag has an action topic."""
    from discretize.voronoi import load_states
    from simlab.data.poselog import decision_actions, segment_decisions
    from simlab.data.writer import DatasetInfo, TransitionArrays, write_dataset
    from simlab.ros.bag import read_bag

    bag, states, pose_topic = cfg.bag, cfg.states, cfg.pose_topic
    action_topic = cfg.actions_from
    aset = cfg.make_action_set()
    segment = cfg.segment_params()
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
    res = write_dataset(cfg.out, walk, info, overwrite=cfg.overwrite)
    return ImportBagResult(out=res.out, samples=len(t), decisions=len(start),
                           blocked=int(np.sum(blocked)), action_source=source)
