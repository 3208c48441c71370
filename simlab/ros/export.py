"""``simlab export-bag``: a collection dataset or a replay as a ROS 2 bag (MCAP).

Sources (the directory decides):

* a **dataset** (``_manifest.json``, written by ``simlab collect`` or an importer): one
  worker's walk (``worker``, default 0). Samples at each transition's start ``t`` (pose
  before, state ``s``) and end ``t + duration`` (pose after, ``s_next``; dropped when it
  coincides with the next start); ``/simlab/action`` carries ``a`` at each start. The
  map-frame pose (``/amcl_pose``, ``map -> base_footprint``) is the ground truth when the
  dataset has ``*_true`` columns, else the pose source; ``/odom`` is the pose source for
  ``odometry`` datasets, else equal to the map pose (``map -> odom`` identity).
* a **replay** (``replay.json`` and ``transitions.parquet``, written by ``simlab replay``):
  the true poses, believed states, actions and the goal per sample (``/simlab/goal``);
  odometry at the transitions' ends only, so ``/odom`` equals the map pose.

``/scan`` is **cast again** at every sample pose in the source's arena (noise-free, the
LIDAR of :mod:`simlab.physics.lidar`): neither source stores scans. ``/map`` is the arena
rasterized at ``resolution`` (0 free, 100 occupied), or a map_server map given as ``map``.

The options are the fields of :class:`ExportBagConfig`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from simlab import validation
from simlab.errors import ConfigError
from simlab.options import CommandConfig, command, option


@dataclass(frozen=True)
class ExportBagResult:
    """The bag written, its number of pose samples and the source kind."""

    out: Path
    samples: int
    source: str


def _samples(t: np.ndarray, dur: np.ndarray, before: np.ndarray, after: np.ndarray,
             s: np.ndarray, s_next: np.ndarray) -> tuple[np.ndarray, ...]:
    """Interleave starts and ends: ``(t, pose, state, index of the transition, is_end)``."""
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


def _from_dataset(path: Path, worker: int) -> dict[str, Any]:
    from simlab.data.dataset import open_dataset

    ds = open_dataset(path, validate=True)
    tab = ds.table
    w = tab.column("worker").to_numpy()
    if not np.any(w == worker):
        raise ConfigError(f"no transitions of worker {worker} (workers: "
                          f"{sorted(set(w.tolist()))})", path=path, key="worker")
    tab = tab.filter(w == worker)
    names = tab.column_names
    truth = "x_true" in names
    before = _cols(tab, ["x_true", "y_true", "yaw_true"] if truth else ["x", "y", "yaw"])
    after = _cols(tab, ["x_next_true", "y_next_true", "yaw_next_true"] if truth
                  else ["x_next", "y_next", "yaw_next"])
    t, dur = tab.column("t").to_numpy(), tab.column("duration").to_numpy()
    tt, pose, state, _ = _samples(t, dur, before, after, tab.column("s").to_numpy(),
                                  tab.column("s_next").to_numpy())
    odom = None
    if ds.manifest.get("pose_source") == "odometry":
        src_b, src_a = _cols(tab, ["x", "y", "yaw"]), _cols(tab, ["x_next", "y_next", "yaw_next"])
        odom = _samples(t, dur, src_b, src_a, np.zeros(len(t)), np.zeros(len(t)))[1]
    return {"t": tt, "pose": pose, "odom": odom, "state": state, "goal": None,
            "actions": tab.column("a").to_numpy().astype(np.int64), "action_t": t,
            "arena": ds.manifest["arena"].get("file") or ds.manifest["arena"]["name"]}


def _from_replay(path: Path) -> dict[str, Any]:
    import pyarrow.parquet as pq

    summary = json.loads((path / "replay.json").read_text())
    tab = pq.read_table(path / "transitions.parquet")
    before = _cols(tab, ["x_true", "y_true", "yaw_true"])
    after = _cols(tab, ["x_true_next", "y_true_next", "yaw_true_next"])
    t, dur = tab.column("t").to_numpy(), tab.column("duration").to_numpy()
    tt, pose, state, idx = _samples(t, dur, before, after, tab.column("s").to_numpy(),
                                    tab.column("s_next").to_numpy())
    goals = np.asarray(tab.column("goal").to_pylist(), dtype=str)
    return {"t": tt, "pose": pose, "odom": None, "state": state, "goal": goals[idx],
            "actions": tab.column("a").to_numpy().astype(np.int64), "action_t": t,
            "arena": summary["arena"]}


def _scans(arena: Any, pose: np.ndarray) -> tuple[np.ndarray, Any, tuple[float, ...]]:
    from simlab.physics.world import World
    from simlab.ros.bag import ScanGeometry

    with World(arena) as world:
        spec = world.lidar_spec
        out = np.empty((len(pose), spec.n_beams), dtype=np.float32)
        for i, p in enumerate(pose):
            world.set_pose(p)
            out[i] = world.scan(None).ranges.astype(np.float32)
        offset = tuple(float(v) for v in world.lidar.offset)
    geom = ScanGeometry(0.0, 2 * np.pi / spec.n_beams, spec.range_min, spec.range_max,
                        1.0 / spec.rate_hz)
    return out, geom, offset


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


@dataclass(frozen=True, kw_only=True)
class ExportBagConfig(CommandConfig):
    """Options of ``simlab export-bag`` / :func:`export_bag`."""

    COMMAND = "export-bag"
    ARGUMENTS = ("source", "out")

    source: Path = option(help="dataset directory (simlab collect / import-log) or replay "
                          "directory (simlab replay)", positional=True)
    out: Path = option(help="bag directory to write")
    worker: int = option(0, "dataset: which worker's walk to export")
    arena: Any | None = option(None, "arena (name or TOML) for the scans and the map "
                               "(default: the source's)")
    map: Any | None = option(None, "map_server map to publish on /map (default: the arena "
                             "rasterized)", metavar="YAML")
    resolution: float = option(0.02, "pixel size of the rasterized arena map", metavar="M")
    scans: bool = option(True, "/scan cast at every sample pose (--no-scans leaves it out)")
    overwrite: bool = option(False, "replace a bag in --out")

    def validate(self) -> None:
        validation.whole(self.worker, "worker")
        validation.positive(self.resolution, "resolution")


@command(ExportBagConfig)
def export_bag(cfg: ExportBagConfig) -> ExportBagResult:
    """Write a dataset or replay directory ``source`` as the bag ``out`` (module docstring).

    Takes an :class:`ExportBagConfig` or its fields (``export_bag(source, out, scans=False)``):
    ``worker`` is the dataset worker whose walk is exported; ``arena`` overrides the
    source's arena (name or TOML) for the scans and the map; ``map`` is a map_server YAML to
    publish instead of the arena rasterized at ``resolution`` (m/pixel); ``scans=False``
    leaves out ``/scan``; ``overwrite`` replaces a bag in ``out``.
    """
    from simlab.physics.arena import load_arena
    from simlab.ros.bag import BagTrajectory, write_bag

    source = cfg.source
    if (source / "_manifest.json").is_file():
        rec, kind = _from_dataset(source, cfg.worker), "dataset"
    elif (source / "replay.json").is_file() and (source / "transitions.parquet").is_file():
        rec, kind = _from_replay(source), "replay"
    else:
        raise ConfigError("neither a dataset (_manifest.json) nor a replay (replay.json + "
                          "transitions.parquet)", path=source)
    arena_cfg = load_arena(cfg.arena or rec["arena"])
    if cfg.map is not None:
        from discretize.mapio import read_map

        grid = read_map(cfg.map)
    else:
        grid = arena_map(arena_cfg, cfg.resolution)
    scan_arr, geom, offset = (_scans(arena_cfg, rec["pose"]) if cfg.scans
                              else (None, None, (-0.032, 0.0, 0.182)))
    from simlab.ros.bag import ScanGeometry

    traj = BagTrajectory(t=rec["t"], pose=rec["pose"], odom=rec["odom"], scans=scan_arr,
                         scan_geometry=geom or ScanGeometry(), state=rec["state"],
                         goal=rec["goal"], actions=rec["actions"], action_t=rec["action_t"],
                         map=grid, scan_offset=offset)
    path = write_bag(cfg.out, traj, overwrite=cfg.overwrite)
    return ExportBagResult(out=path, samples=len(rec["t"]), source=kind)
