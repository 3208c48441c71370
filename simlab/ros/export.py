"""``simlab export-bag``: a collection dataset or a replay as a ROS 2 bag (MCAP).

Sources (the directory decides):

* a **dataset** (``_manifest.json``, written by ``simlab collect`` or an importer): every
  worker's walk, one after the other in bag time (walk k starts a whole number of seconds,
  at least one, after walk k-1 ends; ``simlab.walks`` in the bag's ``custom_data`` records
  each walk's worker and time offset, and the odometry restarts at rest), or only
  ``worker``'s. Samples at each transition's start ``t`` (pose
  before, state ``s``) and end ``t + duration`` (pose after, ``s_next``; dropped when it
  coincides with the next start); ``/simlab/action`` carries ``a`` at each start. The
  map-frame pose (``/amcl_pose``, ``map -> base_footprint``) is the pose source's, as a
  robot's localizer publishes it, with the truth on ``/simlab/true_pose`` (``mcl``); an
  ``odometry`` dataset has the truth there and its odometry on ``/odom``; otherwise
  ``/odom`` equals the map pose (``map -> odom`` identity).
* a **replay** (``replay.json`` and ``transitions.parquet``, written by ``simlab replay``):
  the true poses, believed states, actions and the goal per sample (``/simlab/goal``);
  odometry at the transitions' ends only, so ``/odom`` equals the map pose.

``/scan`` is **cast again** at every sample's true pose in the source's arena (noise-free, the
LIDAR of :mod:`simlab.physics.lidar`): neither source stores scans. ``/map`` is the arena
rasterized at ``resolution`` (0 free, 100 occupied), or a map_server map given as ``map``.

Each decision's ``blocked`` flag and ``duration`` (the motion, without the decision
latency) go on ``/simlab/blocked`` and ``/simlab/duration`` at its start, and the action
set, the dataset's pose source and the time origin in the bag's ``custom_data``, so that
``simlab import-bag`` gives the dataset back column for column, every worker; the arena
record (``simlab.arena``, with the TOML file's path when the arena came from one) goes
along, so the imported dataset exports again without ``--arena``. The states' Voronoi cells
and the arena's goal areas are ``MarkerArray`` topics (``/simlab/cells``,
``/simlab/goals``), the ``tf_static`` transforms are the robot URDF's joints,
``/robot_description`` its text (so that RViz draws the robot from the bag alone), and beams
that face a surface nearer than ``range_min`` read ``-inf`` (REP-117).

Safety: the output is checked before any work (an existing path is replaced only with
``overwrite`` and only if it is a bag that simlab wrote; an output that equals, contains or
lies inside an input is refused), and the bag appears whole or not at all
(:func:`simlab.ros.bag.write_bag`).

The options are the fields of :class:`ExportBagConfig`.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base import validation
from simlab.base.errors import ConfigError, DataError
from simlab.base.options import CommandConfig, command, option


@dataclass(frozen=True)
class ExportBagResult:
    """The bag written, its number of pose samples and the source kind."""

    out: Path
    samples: int
    source: str


def _samples(t: np.ndarray, dur: np.ndarray, before: np.ndarray, after: np.ndarray,
             s: np.ndarray, s_next: np.ndarray) -> tuple[np.ndarray, ...]:
    """Interleave starts and ends: ``(t, pose, state, index of the transition)``. An end
    that coincides with the next start is dropped (the next start's sample stands for it)."""
    n = len(t)
    t_end = t + dur
    keep_end = np.ones(n, dtype=bool)
    keep_end[:-1] = t_end[:-1] < t[1:]
    tt = np.concatenate([t, t_end[keep_end]])
    pose = np.concatenate([before, after[keep_end]])
    state = np.concatenate([s, s_next[keep_end]])
    idx = np.concatenate([np.arange(n), np.flatnonzero(keep_end)])
    order = np.argsort(tt, kind="stable")
    return tt[order], pose[order], state[order], idx[order]


def _cols(table: Any, names: list[str]) -> np.ndarray:
    return np.column_stack([table.column(c).to_numpy() for c in names]).astype(np.float64)


#: Seconds between one worker's walk and the next in a bag of several (whole seconds, so
#: adding the offset to a walk's times and taking it away again is exact to the nanosecond).
WALK_GAP = 1.0


def _walk(tab: Any, pose_source: str | None) -> dict[str, Any]:
    """One worker's rows as bag samples and decisions (times from the walk's own origin)."""
    has_truth = "x_true" in tab.column_names
    t, dur = tab.column("t").to_numpy(), tab.column("duration").to_numpy()
    zeros = np.zeros(len(t))

    def poses(before: list[str], after: list[str]) -> np.ndarray:
        return _samples(t, dur, _cols(tab, before), _cols(tab, after), zeros, zeros)[1]

    source = poses(["x", "y", "yaw"], ["x_next", "y_next", "yaw_next"])
    true = poses(["x_true", "y_true", "yaw_true"],
                 ["x_next_true", "y_next_true", "yaw_next_true"]) if has_truth else None
    tt, _, state, _ = _samples(t, dur, _cols(tab, ["x", "y", "yaw"]),
                               _cols(tab, ["x_next", "y_next", "yaw_next"]),
                               tab.column("s").to_numpy(), tab.column("s_next").to_numpy())
    # the map pose: the localizer's estimate (mcl) with the truth beside it, or the truth
    # with the wheel odometry in the odom frame (odometry), or the pose source itself
    pose: np.ndarray = source
    odom: np.ndarray | None = None
    truth: np.ndarray | None = None
    if true is not None and pose_source == "odometry":
        pose, odom = true, source
    elif true is not None:
        truth = true
    return {"t": tt, "pose": pose, "odom": odom, "truth": truth, "state": state,
            "actions": tab.column("a").to_numpy().astype(np.int64), "action_t": t,
            "blocked": tab.column("blocked").to_numpy().astype(bool), "duration": dur}


def _laid_end_to_end(walks: list[dict[str, Any]]) -> tuple[dict[str, Any], list[float]]:
    """The walks one after the other in bag time: walk k starts ``WALK_GAP`` (whole
    seconds) after walk k-1's last sample. Returns the joined arrays (``walk_starts``: the
    sample index where each walk begins; ``t_ns``, ``action_t_ns``: the bag times in whole
    nanoseconds) and each walk's time offset (s)."""
    from simlab.ros.bag import nanoseconds

    offsets, end = [], None
    for w in walks:
        off = 0.0 if end is None else float(math.ceil(end - w["t"][0]) + WALK_GAP)
        offsets.append(off)
        end = off + float(w["t"][-1])
    joined: dict[str, Any] = {}
    for key in ("pose", "odom", "truth", "state", "actions", "blocked", "duration"):
        parts = [w[key] for w in walks]
        joined[key] = None if parts[0] is None else np.concatenate(parts)
    joined["t"] = np.concatenate([w["t"] + off for w, off in zip(walks, offsets, strict=True)])
    joined["action_t"] = np.concatenate([w["action_t"] + off
                                         for w, off in zip(walks, offsets, strict=True)])
    # the stamps in integers: a walk's own nanoseconds plus its whole seconds, so that
    # import-bag takes the offset away again without a float64 rounding (bag.nanoseconds)
    for key in ("t", "action_t"):
        joined[f"{key}_ns"] = np.concatenate([
            nanoseconds(w[key]) + nanoseconds(off)
            for w, off in zip(walks, offsets, strict=True)])
    joined["walk_starts"] = np.cumsum([0] + [len(w["t"]) for w in walks[:-1]]).astype(np.int64)
    return joined, offsets


def _from_dataset(path: Path, worker: int | None) -> dict[str, Any]:
    """The dataset's walks (every worker's, or only ``worker``'s) as one bag trajectory."""
    from simlab.data.dataset import open_dataset

    ds = open_dataset(path, validate=True)
    tab = ds.table
    w = tab.column("worker").to_numpy()
    workers = sorted(set(w.tolist()))
    if worker is not None:
        if worker not in workers:
            raise ConfigError(f"no transitions of worker {worker} (workers: {workers})",
                              path=path, key="worker", fix="choose one of the workers listed")
        workers = [worker]
    pose_source = ds.manifest.get("pose_source")
    rec, offsets = _laid_end_to_end([_walk(tab.filter(w == k), pose_source)
                                     for k in workers])
    centres = (ds.manifest.get("discretizer") or {}).get("centres")
    walks = [{"worker": int(k), "offset": off} for k, off in zip(workers, offsets, strict=True)]
    record = ds.manifest["arena"]
    rec.update(
        goal=None, action_set=None if ds.action_set is None else ds.action_set.to_json(),
        pose_source=pose_source,
        centres=None if centres is None else np.asarray(centres, dtype=np.float64),
        custom={"simlab.part_size": str((ds.manifest.get("parameters") or {}).get(
            "part_size", "")), "simlab.walks": json.dumps(walks),
            "simlab.arena": json.dumps(record)},
        arena=_recorded_arena(record))
    return rec


def _arena_record(arena: Any, used: Any, recorded: dict[str, Any] | None) -> dict[str, Any]:
    """The manifest's arena record of the arena a bag shows: the source's own ``recorded``
    one, or (an arena given instead) its name, bounds and goals; with ``file`` (absolute)
    when it came from a TOML file, so that a dataset imported from the bag exports again."""
    from simlab.base.assets import is_path

    record = dict(recorded) if recorded is not None else {
        "name": arena.name, "bounds": [float(v) for v in arena.bounds],
        "goals": [{"name": g.name, "x": float(g.x), "y": float(g.y), "radius": float(g.radius)}
                  for g in arena.goals]}
    if isinstance(used, str | os.PathLike) and is_path(used, ".toml"):
        record["file"] = str(Path(used).resolve())
    return record


def _recorded_arena(record: dict[str, Any]) -> Any:
    """The arena a dataset's manifest records, as :func:`load_arena` takes it: its file
    when that is still there, else its name when it is a built-in arena; None when neither
    (a robot's data, imported from a log or a bag of its own: ``--arena`` is needed)."""
    from simlab.base.assets import available

    file = record.get("file")
    if isinstance(file, str) and Path(file).is_file():
        return file
    name = record.get("name")
    if isinstance(name, str) and name in available("arenas", ".toml"):
        return name
    return None


def _from_replay(path: Path) -> dict[str, Any]:
    import pyarrow.parquet as pq  # type: ignore[import-untyped]

    try:
        summary = json.loads((path / "replay.json").read_text(encoding="utf-8"))
        tab = pq.read_table(path / "transitions.parquet")
    except (ValueError, OSError) as exc:  # JSON, Arrow and Parquet errors are ValueErrors
        raise DataError(f"{path}: not a readable replay ({exc})") from None
    before = _cols(tab, ["x_true", "y_true", "yaw_true"])
    after = _cols(tab, ["x_true_next", "y_true_next", "yaw_true_next"])
    t, dur = tab.column("t").to_numpy(), tab.column("duration").to_numpy()
    tt, pose, state, idx = _samples(t, dur, before, after, tab.column("s").to_numpy(),
                                    tab.column("s_next").to_numpy())
    goals = np.asarray(tab.column("goal").to_pylist(), dtype=str)
    blocked = (tab.column("blocked").to_numpy().astype(bool) if "blocked" in tab.column_names
               else None)
    return {"t": tt, "pose": pose, "odom": None, "truth": None, "state": state,
            "goal": goals[idx],
            "actions": tab.column("a").to_numpy().astype(np.int64), "action_t": t,
            "blocked": blocked, "duration": dur, "action_set": summary.get("action_set"),
            "pose_source": "truth", "centres": _replay_centres(summary), "custom": None,
            "arena": summary["arena"], "walk_starts": None, "t_ns": None,
            "action_t_ns": None}


def _replay_centres(summary: dict[str, Any]) -> np.ndarray | None:
    """The replay's state centres, when its states file is still where it was."""
    record = summary.get("states")
    src = record.get("file") if isinstance(record, dict) else None
    if not isinstance(src, str) or not Path(src).is_file():
        return None
    from discretize.voronoi import load_states

    try:
        return np.asarray(load_states(src).centres, dtype=np.float64)
    except (ValueError, OSError):
        return None


def _scans(arena: Any, pose: np.ndarray) -> tuple[np.ndarray, Any]:
    """Noise-free scans ``(n, B)`` float32 at each pose; a beam that would hit a surface
    nearer than ``range_min`` reads ``-inf`` (REP-117 "too close"), one that hits nothing
    within ``range_max`` ``+inf``.

    simlab's LIDAR starts its rays at ``range_min`` (it cannot see nearer, like the real
    sensor), so it reads +inf there; a second, short cast from the sensor centre to
    ``range_min`` tells "too close" from "nothing". The robot is placed upright at rest on
    the floor (:meth:`World.set_pose`), so its ``base_footprint`` frame, in which the
    LIDAR's mount is given, is ``(x, y, 0)`` rotated by yaw.
    """
    from simlab.physics.lidar import Lidar, LidarSpec
    from simlab.physics.world import World
    from simlab.ros.bag import ScanGeometry

    with World(arena) as world:
        spec = world.lidar_spec
        near = Lidar(world.client, world.body, tuple(world.lidar.offset),
                     LidarSpec(n_beams=spec.n_beams, range_min=0.0, range_max=spec.range_min,
                               noise_sigma=0.0))
        out = np.empty((len(pose), spec.n_beams), dtype=np.float32)
        for i, p in enumerate(pose):
            world.set_pose(p)
            ranges = world.scan(None).ranges
            c, s = math.cos(float(p[2])), math.sin(float(p[2]))
            rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
            close = near.scan(np.array([float(p[0]), float(p[1]), 0.0]), rot, p, None)
            too_close = (np.isinf(ranges) & np.isfinite(close.ranges)
                         & (close.hit_ids != world.body))
            ranges = np.where(too_close, -np.inf, ranges)
            out[i] = ranges.astype(np.float32)
    geom = ScanGeometry(0.0, 2 * np.pi / spec.n_beams, spec.range_min, spec.range_max,
                        1.0 / spec.rate_hz)
    return out, geom


def arena_map(arena: Any, resolution: float = 0.02, margin: float = 0.1) -> Any:
    """The arena rasterized as an :class:`~discretize.gridmap.OccupancyMap` (0 / 100)
    covering its bounds plus ``margin`` (m) at ``resolution`` (m/pixel)."""
    from discretize.gridmap import OccupancyMap

    x0, y0, x1, y1 = arena.bounds
    origin = (x0 - margin, y0 - margin)
    shape = (int(np.ceil((y1 - y0 + 2 * margin) / resolution)),
             int(np.ceil((x1 - x0 + 2 * margin) / resolution)))
    occ = np.where(arena.rasterize(resolution, origin, shape), 100, 0).astype(np.int8)
    return OccupancyMap(occupancy=occ, resolution=resolution, origin=(*origin, 0.0))


def _overlaps(a: Path, b: Path) -> bool:
    """``a`` equals ``b`` or one lies inside the other (resolved: links and ``..``)."""
    a, b = a.resolve(), b.resolve()
    return a == b or a in b.parents or b in a.parents


def _refuse_overlap(out: Path, inputs: list[tuple[str, Path]]) -> None:
    """An output equal to, containing or inside an input would destroy the input (or
    write into it): refused before any work."""
    for what, src in inputs:
        if _overlaps(out, src):
            raise ConfigError(f"the output overlaps the {what} {src} (the same path, or one "
                              f"inside the other): writing the bag would destroy or change "
                              f"it", path=out, key="out",
                              fix="choose an --out outside the inputs")


@dataclass(frozen=True, kw_only=True)
class ExportBagConfig(CommandConfig):
    """Options of ``simlab export-bag`` / :func:`export_bag`."""

    COMMAND = "export-bag"
    ARGUMENTS = ("source", "out")

    source: Path = option(help="dataset directory (simlab collect / import-log) or replay "
                          "directory (simlab replay)", positional=True)
    out: Path = option(help="bag directory to write")
    worker: int | None = option(None, "dataset: export only this worker's walk (default: "
                                "every worker's, one after the other in bag time)")
    arena: Any | None = option(None, "arena (name or TOML) for the scans and the map "
                               "(default: the source's)")
    map: Any | None = option(None, "map_server map to publish on /map (default: the arena "
                             "rasterized)", metavar="YAML")
    resolution: float = option(0.02, "pixel size of the rasterized arena map", metavar="M")
    scans: bool = option(True, "/scan cast at every sample pose (--no-scans leaves it out)")
    start_time: float = option(0.0, "ROS time of the source's t = 0 (s since the epoch, "
                               "e.g. 1700000000)", metavar="S")
    overwrite: bool = option(False, "replace a bag that simlab export-bag wrote in --out")

    def validate(self) -> None:
        if self.arena is not None:
            from simlab.physics.arena import check_arena_option

            check_arena_option(self.arena)
        if self.worker is not None:
            validation.whole(self.worker, "worker")
        validation.positive(self.resolution, "resolution")
        validation.positive(self.start_time, "start_time", allow_zero=True)


@command(ExportBagConfig)
def export_bag(cfg: ExportBagConfig) -> ExportBagResult:
    """Write a dataset or replay directory ``source`` as the bag ``out`` (module docstring).

    Takes an :class:`ExportBagConfig` or its fields (``export_bag(source, out, scans=False)``):
    ``worker`` is the dataset worker whose walk is exported; ``arena`` overrides the
    source's arena (name or TOML) for the scans and the map; ``map`` is a map_server YAML to
    publish instead of the arena rasterized at ``resolution`` (m/pixel); ``scans=False``
    leaves out ``/scan``; ``start_time`` (s) is the stamp of the source's ``t = 0``;
    ``overwrite`` replaces a bag that this command wrote in ``out`` (nothing else).
    """
    from simlab.physics.arena import load_arena
    from simlab.physics.robot import load_robot_spec
    from simlab.ros.bag import BagTrajectory, ScanGeometry, check_bag_target, write_bag
    from simlab.ros.frames import robot_frames
    from simlab.ros.markers import SceneMarkers

    source, out = Path(cfg.source), Path(cfg.out)
    inputs = [("source", source)]
    for what, value in (("map", cfg.map), ("arena file", cfg.arena)):
        if isinstance(value, str | os.PathLike) and Path(value).exists():
            inputs.append((what, Path(value)))
    _refuse_overlap(out, inputs)
    check_bag_target(out, overwrite=cfg.overwrite)  # before the work, not after
    if (source / "_manifest.json").is_file():
        rec, kind = _from_dataset(source, cfg.worker), "dataset"
    elif (source / "replay.json").is_file() and (source / "transitions.parquet").is_file():
        rec, kind = _from_replay(source), "replay"
    elif not source.exists():
        raise ConfigError("source not found", path=source,
                          fix="give a dataset or replay directory")
    else:
        raise ConfigError("neither a dataset (_manifest.json) nor a replay (replay.json + "
                          "transitions.parquet)", path=source,
                          fix="give the directory that simlab collect, import-log, "
                              "import-bag or replay wrote")
    if cfg.arena is None and rec["arena"] is None:
        raise ConfigError(f"the dataset records no arena that is here (arena "
                          f"{json.loads(rec['custom']['simlab.arena']).get('name')!r}: neither "
                          f"a built-in name nor a file; data imported from a robot's log or "
                          f"bag has none)", path=source / "_manifest.json", key="arena",
                          fix="pass --arena NAME or --arena FILE.toml, the arena the robot "
                              "drove in")
    arena_cfg = load_arena(cfg.arena or rec["arena"])
    if kind == "dataset":  # the arena the bag shows, for import-bag's manifest
        rec["custom"]["simlab.arena"] = json.dumps(
            _arena_record(arena_cfg, cfg.arena or rec["arena"],
                          None if cfg.arena else json.loads(rec["custom"]["simlab.arena"])))
    if cfg.map is not None:
        from discretize.mapio import read_map

        grid = read_map(cfg.map)
    else:
        grid = arena_map(arena_cfg, cfg.resolution)
    # the URDF's frames (every fixed joint on tf_static, the wheels on tf and joint_states);
    # the scan and base offsets as the robot spec reads them (root frame base_footprint)
    robot = load_robot_spec()
    bx, by, bz = (float(v) for v in robot.base_link_offset)
    sx, sy, sz = (float(v) for v in robot.lidar_offset)
    where = rec["pose"] if rec["truth"] is None else rec["truth"]  # the robot's real place
    scan_arr, geom = _scans(arena_cfg, where) if cfg.scans else (None, None)
    goals = tuple((g.name, float(g.x), float(g.y), float(g.radius)) for g in arena_cfg.goals)
    x0, y0, x1, y1 = (float(v) for v in arena_cfg.bounds)
    scene = SceneMarkers(centres=rec["centres"], bounds=(x0, y0, x1, y1), goals=goals)
    traj = BagTrajectory(t=rec["t"], pose=rec["pose"], odom=rec["odom"], truth=rec["truth"],
                         scans=scan_arr,
                         scan_geometry=geom or ScanGeometry(), state=rec["state"],
                         goal=rec["goal"], actions=rec["actions"], action_t=rec["action_t"],
                         blocked=rec["blocked"], duration=rec["duration"],
                         action_set=rec["action_set"], pose_source=rec["pose_source"],
                         map=grid, scan_offset=(sx - bx, sy - by, sz - bz),
                         base_offset=(bx, by, bz),
                         scene=scene, custom=rec["custom"], walk_starts=rec["walk_starts"],
                         robot=robot_frames(robot.urdf_path), t_ns=rec["t_ns"],
                         action_t_ns=rec["action_t_ns"])
    path = write_bag(out, traj, t0=cfg.start_time, overwrite=cfg.overwrite)
    return ExportBagResult(out=path, samples=len(rec["t"]), source=kind)
