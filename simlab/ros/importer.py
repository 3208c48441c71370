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
* **A bag that simlab export-bag wrote** records more, and it is used: the action set
  (``n_actions``/``convention`` then default to it, and a different one given is refused),
  each decision's ``blocked`` flag and ``duration`` (the motion without the decision
  latency), the time origin and the pose source (``truth``: the map pose; ``odometry``:
  the ``/odom`` pose with the map pose as the truth; ``mcl``: the map pose with
  ``/simlab/true_pose`` as the truth), so that export then import gives the dataset back
  column for column: each walk of its ``simlab.walks`` record becomes its worker again
  (times from the walk's own offset), and its ``simlab.arena`` record is the manifest's
  arena.
* **Scans** (optional ``/scan``) are not needed for the transitions; their number is
  recorded in the provenance.
* **States**: nearest centre of the states file (the writer's rule). Written with
  :func:`simlab.data.writer.write_dataset` in the one output transaction
  (:func:`simlab.base.io.output_transaction`): a failure leaves ``out`` as it was; pose source
  ``log`` unless the bag records another.
* **Safety**: ``out`` is checked before the bag is read: an existing dataset is replaced
  only with ``overwrite`` and only if this command wrote it; ``out`` may not be, contain
  or lie inside the bag.

The options are the fields of :class:`ImportBagConfig`; the action numbering and the
thresholds are ``import-log``'s option groups
(:class:`~simlab.data.poselog.RobotActionOptions`,
:class:`~simlab.data.poselog.SegmentOptions`).
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base.actions import ActionSet, parse_action_set
from simlab.base.errors import ConfigError
from simlab.base.options import command, option
from simlab.data.poselog import RobotActionOptions, SegmentOptions

#: ``provenance.importer`` of the datasets this command writes: what ``--overwrite`` may
#: replace.
IMPORTER = "simlab import-bag"


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
                            n_actions: int, blocked: np.ndarray | None = None,
                            duration: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
    """``(start, end, blocked, actions, duration)`` of the decisions announced by an action
    topic (sample indices, bool, int, s).

    With the recorded ``duration`` (k,) s, a decision ends at the sample stamped ``start +
    duration`` (to 1 us; else at the next decision's start) and keeps that duration; with
    the recorded ``blocked`` (k,) that flag is kept. Without them the decision ends at the
    sample after its last motion (a ``move`` or ``turn`` interval of the pose-log
    labelling, the rule of :func:`~simlab.data.poselog.segment_decisions`: the idle wait
    for the next decision is not part of its duration; one sample when it has no motion),
    and is blocked when none of its intervals up to the next decision is a ``move``.
    """
    from simlab.data.poselog import interval_labels

    if np.any((actions < 0) | (actions >= n_actions)):
        sixteen = n_actions == 8 and actions.min() >= 0 and actions.max() < 16
        raise ConfigError(f"action topic has indices outside 0..{n_actions - 1} (min "
                          f"{actions.min()}, max {actions.max()})", key="actions",
                          fix="the robot has 16 actions: pass --n-actions 16 and its "
                              "--convention" if sixteen else
                              "check that --action-topic carries action indices")
    keep = action_t >= t[0]
    actions, action_t = actions[keep], action_t[keep]
    blocked = None if blocked is None else blocked[keep]
    duration = None if duration is None else duration[keep]
    start = np.searchsorted(t, action_t, side="right") - 1
    end = np.append(start[1:], len(t) - 1)
    if duration is not None:
        target = action_t + duration
        at = np.clip(np.searchsorted(t, target), 0, len(t) - 1)
        before = np.clip(at - 1, 0, len(t) - 1)
        nearest = np.where(np.abs(t[before] - target) < np.abs(t[at] - target), before, at)
        found = np.abs(t[nearest] - target) < 1e-6
        end = np.where(found & (nearest >= start), nearest, end)
    # two actions within one pose interval: the first has no motion (unless it is recorded
    # as a motionless decision of zero duration)
    ok = end > start if duration is None else (end > start) | (duration == 0)
    start, end, actions = start[ok], end[ok], actions[ok]
    labels = interval_labels(t, xy, yaw, segment)
    if blocked is None:
        cum = np.concatenate([[0], np.cumsum(labels == 2)])
        blocked = (cum[end] - cum[start]) == 0
    else:
        blocked = blocked[ok]
    if duration is None:
        active = np.flatnonzero(labels != 0)  # interval i joins samples i and i + 1
        pos = np.searchsorted(active, end, side="left") - 1
        last = np.where(pos >= 0, active[np.clip(pos, 0, None)] if len(active) else -1, -1)
        end = np.where(last >= start, last + 1, np.minimum(start + 1, end))
        duration = t[end] - t[start]
    else:
        duration = duration[ok]
    return start, end, blocked, actions, duration


@dataclass(frozen=True, kw_only=True)
class ImportBagConfig(RobotActionOptions, SegmentOptions):
    """Options of ``simlab import-bag`` / :func:`import_bag`."""

    COMMAND = "import-bag"
    ARGUMENTS = ("bag",)

    bag: Path = option(help="ROS 2 bag directory (MCAP or sqlite3)", positional=True)
    states: Any = option(help="states: `simlab discretize` JSON or centres text (from Python "
                         "also a discretizer)")
    out: Path = option(help="dataset directory to write")
    # None = not given: the bag's recorded action set then applies
    n_actions: int | None = option(  # type: ignore[assignment]
        None, "number of actions of the robot (default: the bag's recorded action set, "
        "else 8)", choices=(8, 16))
    convention: str | None = option(  # type: ignore[assignment]
        None, "direction numbering: simlab, ccw-east (the ISIR robot's) or 8 comma-separated "
        "numbers (default: the bag's, else ccw-east)")
    pose_topic: str | None = option(None, "pose topic (default: /amcl_pose if present, else "
                                    "/odom)")
    action_topic: str | None = option(
        "/simlab/action", "std_msgs/Int32 action topic; absent from the bag -> the pose "
        "segmentation of import-log (from Python, None = --segment)")
    segment: bool = option(False, "ignore the action topic and segment the poses")
    overwrite: bool = option(False, "replace a dataset that import-bag wrote in --out")

    @property
    def actions_from(self) -> str | None:
        """The action topic to read, None when the poses are to be segmented."""
        return None if self.segment else self.action_topic

    def make_action_set(self, recorded: Any = None) -> ActionSet:
        """The action set: the fields given, else the bag's ``recorded`` record (the
        :meth:`ActionSet.to_json` of the bag's ``simlab.action_set``), else 8 actions
        ``ccw-east`` (the ISIR robot's). Fields that contradict the recorded set are
        refused: the bag's action indices mean what its writer said."""
        found = None if recorded is None else ActionSet.from_json(
            recorded, where=f"{self.bag}/metadata.yaml: custom_data: simlab.action_set")
        if self.n_actions is None and self.convention is None:
            return found or parse_action_set(8, "ccw-east")
        base = found or parse_action_set(8, "ccw-east")
        given = parse_action_set(self.n_actions or base.n_actions,
                                 self.convention or base.convention)
        if found is not None and (given.n_actions, given.directions) != (
                found.n_actions, found.directions):
            raise ConfigError(f"the bag records its actions as {found.n_actions} actions, "
                              f"convention {found.convention}; --n-actions/--convention say "
                              f"{given.n_actions}, {given.convention}", path=self.bag,
                              key="n_actions", fix="leave out --n-actions and --convention")
        return given if found is None else found


def _check_out(out: Path, bag: Path, overwrite: bool) -> None:
    """Refuse ``out`` before any work: a file, a directory that overlaps the bag, or one
    that holds anything but a dataset this command wrote (that one only with
    ``overwrite``)."""
    from simlab.base.errors import DataError
    from simlab.data.manifest import read_manifest
    from simlab.data.schema import PARTS_DIR, parse_part_name

    a, b = out.resolve(), bag.resolve()
    if a == b or a in b.parents or b in a.parents:
        raise ConfigError(f"the output overlaps the bag {bag} (the same path, or one inside "
                          f"the other)", path=out, key="out",
                          fix="choose an --out outside the bag")
    for parent in out.parents:
        if parent.exists() and not parent.is_dir():
            raise ConfigError("a parent of this path is a file, not a directory", path=parent,
                              fix="choose another --out")
    if not out.exists():
        return
    if not out.is_dir():
        raise ConfigError("exists and is not a directory", path=out, fix="choose another --out")
    entries = [p for p in out.iterdir() if not p.name.startswith(".")]
    if not entries:
        return
    try:
        manifest = read_manifest(out)
    except DataError:
        manifest = None
    ours = (isinstance(manifest, dict)
            and (manifest.get("provenance") or {}).get("importer") == IMPORTER)
    parts = out / PARTS_DIR
    foreign = [p.name for p in entries if p.name not in ("_manifest.json", PARTS_DIR)]
    if parts.is_dir():
        foreign += [f"{PARTS_DIR}/{p.name}" for p in parts.iterdir()
                    if parse_part_name(p.name) is None and not p.name.startswith(".")]
    elif parts.exists():
        foreign.append(PARTS_DIR)
    if not ours or foreign:
        what = (f"holds {foreign[0]}, which is not a dataset's" if foreign else
                "holds a dataset that simlab import-bag did not write")
        raise ConfigError(f"output directory {what}; it is never replaced, even with "
                          f"--overwrite", path=out, fix="choose another --out")
    if not overwrite:
        raise ConfigError("output directory holds a dataset", path=out,
                          fix="choose another --out, or pass --overwrite to replace it")


def _write(out: Path, walk: Any, workers: list[int], info: Any, overwrite: bool,
           part_size: int | None) -> None:
    """``write_dataset`` into the staging directory of one output transaction, renamed
    into ``out`` at the end; then the old dataset's parts that the new one does not list
    are removed. OS errors name ``out``, not the staging directory."""
    from simlab.base.io import output_transaction
    from simlab.data.schema import PARTS_DIR
    from simlab.data.writer import DEFAULT_PART_SIZE, write_dataset

    try:
        with output_transaction(out, overwrite=overwrite, what="dataset") as txn:
            result = write_dataset(txn.staging, walk, info,
                                   part_size=part_size or DEFAULT_PART_SIZE, workers=workers)
        listed = {Path(str(e.get("file", ""))).name for e in result.manifest.get("parts", [])}
        if (out / PARTS_DIR).is_dir():
            for old in (out / PARTS_DIR).iterdir():
                if old.name not in listed and not old.name.startswith("."):
                    with contextlib.suppress(FileNotFoundError):
                        old.unlink()
    except OSError as exc:
        raise OSError(exc.errno or errno.EIO, exc.strerror or str(exc), str(out)) from None


@command(ImportBagConfig)
def import_bag(cfg: ImportBagConfig) -> ImportBagResult:
    """Import a bag (module docstring). Takes an :class:`ImportBagConfig` or its fields
    (``import_bag(bag, states=..., out=...)``). ``states``: states file or discretizer;
    ``n_actions``/``convention``: the action set (as ``import-log``; default the bag's
    recorded one); ``move_speed``, ``turn_rate``, ``join_gap``, ``speed_split``: the
    :class:`~simlab.data.poselog.SegmentParams` thresholds; ``segment=True`` (or
    ``action_topic=None``) forces the segmentation even when the bag has an action topic."""
    from discretize.voronoi import load_states
    from simlab.data.writer import DatasetInfo
    from simlab.ros.bag import read_bag

    bag, states, pose_topic, out = Path(cfg.bag), cfg.states, cfg.pose_topic, Path(cfg.out)
    _check_out(out, bag, cfg.overwrite)
    action_topic = cfg.actions_from
    segment = cfg.segment_params()
    disc = load_states(states) if isinstance(states, str | os.PathLike) else states
    traj = read_bag(bag, pose_topic=pose_topic, action_topic=action_topic)
    aset = cfg.make_action_set(traj.action_set)
    walks, workers, source = [], [], ""
    for lo, hi, offset, worker in _walk_spans(traj, bag):  # one per worker of a simlab dataset
        walk, source = _walk_transitions(traj, lo, hi, offset, cfg, aset, action_topic,
                                         pose_topic)
        walks.append(walk)
        workers.append(worker)
    pose_source = _pose_source(traj, pose_topic)
    info = DatasetInfo(
        discretizer=disc, action_set=aset, pose_source=pose_source,
        provenance={"importer": IMPORTER, "bag": str(bag),
                    "states": str(states) if isinstance(states, str | os.PathLike) else None,
                    "samples": len(traj.t), "scans": 0 if traj.scans is None else len(traj.scans),
                    "pose_topic": pose_topic or "auto", "action_source": source,
                    "action_set": "recorded in the bag" if traj.action_set is not None
                    and cfg.n_actions is None and cfg.convention is None else "given",
                    "segmentation": json.loads(json.dumps(asdict(segment)))},
        arena=_arena_record(traj.custom, bag), parameters={"importer": "ros-bag"})
    part_size = (traj.custom or {}).get("simlab.part_size", "")
    _write(out, walks, workers, info, cfg.overwrite,
           int(part_size) if part_size.isdigit() and int(part_size) > 0 else None)
    return ImportBagResult(out=out, samples=len(traj.t), decisions=sum(len(w) for w in walks),
                           blocked=int(sum(np.sum(w.blocked) for w in walks)),
                           action_source=source)


def _walk_spans(traj: Any, bag: Path) -> list[tuple[float, float, float, int]]:
    """``(start, end, offset, worker)`` (s, bag time) of each walk in the bag: one per
    worker when simlab export-bag laid walks one after the other (its ``simlab.walks``
    record: each walk's worker and whole-second time offset; a bag of ``--worker 1`` holds
    worker 1's walk, imported as worker 1), else the whole bag as worker 0; a walk's own
    times are bag times minus its offset."""
    record = (traj.custom or {}).get("simlab.walks")
    if record is None:
        return [(-np.inf, np.inf, 0.0, 0)]
    try:
        walks = json.loads(record)
        offsets = [float(w["offset"]) for w in walks]
        workers = [int(w.get("worker", k)) for k, w in enumerate(walks)]
    except (TypeError, ValueError, KeyError, AttributeError):
        offsets, workers = [], []
    if (not offsets or sorted(offsets) != offsets or not np.all(np.isfinite(offsets))
            or len(set(workers)) != len(workers) or not all(0 <= w <= 999 for w in workers)):
        raise ConfigError("custom_data: simlab.walks is not a list of walks with increasing "
                          "offsets and distinct workers 0..999", path=bag / "metadata.yaml",
                          key="simlab.walks",
                          fix="export the dataset again with simlab export-bag")
    ends = [*offsets[1:], np.inf]
    return [(lo if k else -np.inf, hi, lo, w) for k, (lo, hi, w) in
            enumerate(zip(offsets, ends, workers, strict=True))]


def _walk_transitions(traj: Any, lo: float, hi: float, offset: float, cfg: ImportBagConfig,
                      aset: ActionSet, action_topic: str | None, pose_topic: str | None
                      ) -> tuple[Any, str]:
    """The transitions of the bag's samples and actions in ``[lo, hi)`` (s, bag time), with
    times from ``offset``; and where the actions came from."""
    from simlab.data.poselog import decision_actions, segment_decisions
    from simlab.data.writer import TransitionArrays
    from simlab.ros.bag import nanoseconds, seconds

    segment = cfg.segment_params()
    keep = (traj.t >= lo) & (traj.t < hi)
    # the walk's own times from the stamps' whole nanoseconds (exact; bag.seconds)
    offset_ns = int(nanoseconds(offset))

    def walk_time(t: Any, t_ns: Any, rows: Any) -> Any:
        return t[rows] - offset if t_ns is None else seconds(t_ns[rows] - offset_ns)

    t = walk_time(traj.t, traj.t_ns, keep)
    xy, yaw = traj.pose[keep, :2], traj.pose[keep, 2]
    if traj.actions is not None and traj.action_t is not None:
        k = (traj.action_t >= lo) & (traj.action_t < hi)
        start, end, blocked, actions, duration = _decisions_from_actions(
            t, xy, yaw, traj.actions[k], walk_time(traj.action_t, traj.action_t_ns, k),
            segment, aset.n_actions,
            None if traj.blocked is None else traj.blocked[k],
            None if traj.duration is None else traj.duration[k])
        source = f"action topic {action_topic}"
    else:
        dec = segment_decisions(t, xy, yaw, segment)
        start, end, blocked = dec.start, dec.end, dec.blocked
        duration = t[end] - t[start]
        actions = decision_actions(dec, aset, segment) if len(dec) else np.zeros(0, np.int64)
        source = "segmentation of the pose (as simlab import-log)"
    if len(start) == 0:
        raise ConfigError("no decision found in the bag (nothing turns or moves faster than "
                          "the thresholds, and no action messages)", path=cfg.bag,
                          fix="lower --move-speed/--turn-rate, or check --pose-topic")
    pose_source = _pose_source(traj, pose_topic)
    pose, truth = traj.pose[keep], None
    if pose_source == "odometry":
        pose, truth = traj.odom[keep], traj.pose[keep]
    elif pose_source == "mcl":
        truth = traj.truth[keep]
    walk = TransitionArrays(t=t[start], a=actions, pose=pose[start], pose_next=pose[end],
                            blocked=blocked, duration=duration,
                            truth=None if truth is None else truth[start],
                            truth_next=None if truth is None else truth[end])
    return walk, source


def _pose_source(traj: Any, pose_topic: str | None) -> str:
    """The bag's own pose source when simlab wrote it and the pose topic is the default
    (``truth``: the map pose; ``odometry``: /odom, the map pose the truth; ``mcl``: the map
    pose, /simlab/true_pose the truth), else ``log``."""
    if pose_topic is None and traj.pose_source == "truth":
        return "truth"
    if pose_topic is None and traj.pose_source == "odometry" and traj.odom is not None:
        return "odometry"
    if pose_topic is None and traj.pose_source == "mcl" and traj.truth is not None:
        return "mcl"
    return "log"


def _arena_record(custom: dict[str, str] | None, bag: Path) -> dict[str, Any]:
    """The manifest's arena record: the one simlab export-bag recorded (so the dataset
    exports again without ``--arena``), else the bag's name without a file."""
    record = (custom or {}).get("simlab.arena")
    with contextlib.suppress(TypeError, ValueError):
        parsed = json.loads(record) if record is not None else None
        if isinstance(parsed, dict) and isinstance(parsed.get("name"), str):
            return parsed
    return {"name": bag.name, "file": None, "bounds": None, "goals": []}
