"""The exploration run: drive the robot at random in physics and build an occupancy map.

``simlab map --arena table --minutes M --seed S --out maps/table/`` composes the
physics layer (:mod:`simlab.physics`: world, LIDAR, the 16 motion primitives) with the
mapping layer (:mod:`discretize`, which knows nothing of PyBullet):

* the robot executes uniformly random primitives (as the thesis's exploration);
* every LIDAR scan taken while a primitive runs (5 Hz of simulated time, plus one at
  the start) is integrated into a log-odds grid at the sensor pose, i.e. the base
  pose composed with the LIDAR's mounting offset;
* the pose is the simulator's truth by default, a stand-in for the corrected pose
  of GMapping that the thesis mapped with; ``pose_source="odometry"`` maps with the
  wheel odometry instead, to show what drift does to a map;
* the run lasts ``minutes`` of robot time: simulated (stepped) time plus the decision
  latency the robot idles between primitives, the clock of the thesis's 73.1 min
  exploration and of the data collection's hours;
* beams without a return are ignored by default: the table is closed and smaller
  than the LIDAR range, so a no-return beam means an obstacle nearer than
  ``range_min`` (reported as ``inf`` too), not free space.

Outputs in ``out``: ``map.pgm`` + ``map.yaml`` (ROS map_server, trinary) and
``exploration.json`` (parameters, seeds, counts, and the map's accuracy against the
arena's own geometry); each is written atomically, the YAML last.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from simlab.base import validation as v
from simlab.base.errors import ConfigError
from simlab.base.io import atomic_write_json, output_transaction
from simlab.base.options import CommandConfig, command, option
from simlab.localization.sources import SCANLESS_POSE_SOURCES
from simlab.physics.rate import rate_option, resolve_rate, settings_for

if TYPE_CHECKING:  # the occupancy kernels load numba: only when a map is built, not for --help
    from discretize.gridmap import OccupancyMap
    from discretize.occupancy import MapAccuracy, OccupancyGrid

#: The pose sources the mapping run offers (those that need no LIDAR, the one list of
#: :mod:`simlab.localization.sources`; kept under this name for callers).
POSE_SOURCES = SCANLESS_POSE_SOURCES


@dataclass(frozen=True)
class MapRun:
    """What :func:`build_map` produced.

    Attributes:
        map: the trinary occupancy map written to ``yaml_path``.
        yaml_path, image_path, meta_path: the files written.
        n_scans: scans integrated; n_actions: primitives executed (n_blocked of them
            blocked by the obstacle detector).
        robot_seconds: robot time (stepped + idle), sim_seconds: stepped time (s).
        accuracy: the map compared with the arena geometry (see
            :func:`discretize.occupancy.map_accuracy`).
        final_drift: distance (m) between the odometry and the true pose at the end.
    """

    map: OccupancyMap
    yaml_path: Path
    image_path: Path
    meta_path: Path
    n_scans: int
    n_actions: int
    n_blocked: int
    robot_seconds: float
    sim_seconds: float
    accuracy: MapAccuracy
    final_drift: float


def sensor_pose(base_pose: np.ndarray, sensor_offset: np.ndarray) -> np.ndarray:
    """Sensor ``(x, y, yaw)`` in the map frame from the base pose ``(3,)`` and the
    sensor's ``(x, y)`` offset in the base frame (metres); the beams share the base's
    orientation."""
    x, y, yaw = (float(v) for v in base_pose)
    c, s = math.cos(yaw), math.sin(yaw)
    ox, oy = float(sensor_offset[0]), float(sensor_offset[1])
    return np.array([x + c * ox - s * oy, y + s * ox + c * oy, yaw])


@dataclass(frozen=True, kw_only=True)
class MapConfig(CommandConfig):
    """Options of ``simlab map`` / :func:`build_map` (lengths in m, times in minutes).

    The fields:

    * ``arena``: built-in arena name, ``.toml`` path or ``ArenaConfig``.
    * ``minutes``: robot time to explore (simulated driving + idle decision latency).
    * ``seed``: one integer; ``SeedSequence(seed)`` is split into the action and the
      LIDAR-noise streams. Same seed, same map.
    * ``out``: output directory (``map.pgm``, ``map.yaml``, ``exploration.json``);
      default ``maps/<arena name or file stem>``.
    * ``resolution``: map cell side (m).
    * ``pose_source``: ``"truth"`` (default) or ``"odometry"`` (drifts).
    * ``margin``: map extent beyond the arena's inner area on each side (m); must
      cover the walls.
    * ``inf_free_range``: how far a no-return beam marks free space (m); 0 ignores
      them (see the module docstring), None = up to the LIDAR's range_max.
    * ``log_odds``: inverse sensor model (default :class:`LogOddsParams`).
    * ``primitive_params``: :class:`simlab.physics.motion.PrimitiveParams` (default).
    * ``physics_hz``: the physics rate (default :data:`simlab.physics.rate.DEFAULT_HZ`),
      recorded in ``exploration.json``.
    * ``overwrite``: replace existing outputs; ``progress``: a bar over robot time.
    """

    COMMAND = "map"

    arena: Any = option("table", "built-in arena name or .toml path")
    minutes: float = option(10.0, "robot time to explore, driving + idle latency (the "
                            "thesis: 73.1)")
    seed: int = option(0, "random seed")
    out: Path | None = option(None, "output directory (default maps/<arena>)", metavar="DIR")
    resolution: float = option(0.01, "cell size in m", metavar="M")
    pose_source: str = option(
        "truth", "pose to map with: truth (stand-in for GMapping's corrected pose) or "
        "odometry (shows the drift)", choices=POSE_SOURCES)
    margin: float = option(0.25, "map extent beyond the arena's inner area on each side (m)",
                           cli=False)
    inf_free_range: float | None = option(
        0.0, "how far a no-return beam marks free space (m); None: range_max", cli=False)
    log_odds: Any | None = option(None, "LogOddsParams (default: built-in)", cli=False)
    primitive_params: Any | None = option(None, "PrimitiveParams (default: built-in)",
                                          cli=False)
    overwrite: bool = option(False, "replace existing outputs")
    progress: bool = option(True, "progress bar (--no-progress hides it)")
    physics_hz: float | None = rate_option()

    def validate(self) -> None:
        if not (math.isfinite(self.minutes) and self.minutes > 0):
            raise ConfigError(f"expected a duration > 0 minutes, got {self.minutes!r}",
                              key="minutes")
        v.number(self.resolution, "resolution", low=0.001, high=0.2)
        v.positive(self.margin, "margin", allow_zero=True)
        v.whole(self.seed, "seed")
        resolve_rate(self.physics_hz)
        if isinstance(self.log_odds, dict):  # a table of a --config file
            from discretize.occupancy import LogOddsParams

            object.__setattr__(self, "log_odds", v.table_of(LogOddsParams, self.log_odds,
                                                            "log_odds"))
        if isinstance(self.primitive_params, dict):
            from simlab.physics.motion import PrimitiveParams

            object.__setattr__(self, "primitive_params", PrimitiveParams.from_json(
                self.primitive_params, where="primitive_params"))
        if self.out is None:  # the command line's default, also for Python callers
            object.__setattr__(self, "out", Path("maps") / Path(str(self.arena)).stem)


@command(MapConfig)
def build_map(cfg: MapConfig) -> MapRun:
    """Explore ``arena`` at random for ``minutes`` of robot time and write its map.

    Takes a :class:`MapConfig` or its fields (``build_map("table", minutes=3, out=d)``);
    the fields are documented there.
    """
    from discretize.mapio import write_map
    from discretize.occupancy import OccupancyGrid, map_accuracy
    from simlab.physics.arena import ArenaConfig, load_arena
    from simlab.physics.motion import PrimitiveParams

    arena_cfg = cfg.arena if isinstance(cfg.arena, ArenaConfig) else load_arena(cfg.arena)
    if cfg.margin < arena_cfg.wall_thickness:
        raise ConfigError(
            f"margin {cfg.margin} m does not cover the walls ({arena_cfg.wall_thickness} m "
            "thick)", key="margin",
        )
    params = cfg.primitive_params if cfg.primitive_params is not None else PrimitiveParams()
    out = Path(cfg.out)
    yaml_path, image_path, meta_path = out / "map.yaml", out / "map.pgm", out / "exploration.json"
    # One transaction: refuse existing outputs and take the --out lock before exploring;
    # the three files appear together at the end, or not at all.
    with output_transaction(out, (yaml_path, image_path, meta_path), overwrite=cfg.overwrite,
                            what="map output") as txn:
        grid = OccupancyGrid.covering(arena_cfg.bounds, cfg.resolution, cfg.margin,
                                      cfg.log_odds)
        ex = _explore(cfg, arena_cfg, params, grid)
        occupancy_map = grid.to_map()
        truth = arena_cfg.rasterize(cfg.resolution, grid.origin_xy, grid.shape)
        accuracy = map_accuracy(occupancy_map, truth)
        meta = {
            "arena": arena_cfg.name,
            "arena_source": arena_cfg.source,
            "arena_sha256": arena_cfg.source_sha256,
            "minutes": float(cfg.minutes),
            "seed": int(cfg.seed),
            "pose_source": cfg.pose_source,
            "resolution": cfg.resolution,
            "margin": cfg.margin,
            "inf_free_range": cfg.inf_free_range,
            "log_odds": asdict(grid.params),
            "primitive_params": asdict(params),
            "physics": settings_for(resolve_rate(cfg.physics_hz)).to_json(),
            "n_scans": grid.n_scans,
            "n_actions": ex.n_actions,
            "n_blocked": ex.n_blocked,
            "robot_seconds": ex.robot_seconds,
            "sim_seconds": ex.sim_seconds,
            "final_odometry_drift_m": ex.drift,
            "accuracy": asdict(accuracy),
            "map_hash": occupancy_map.content_hash(),
        }
        # Provenance, then the image, then the YAML: a map.yaml exists only for a complete map.
        atomic_write_json(txn.path(meta_path), meta)
        write_map(txn.path(yaml_path), occupancy_map, image=image_path.name, overwrite=True)
    return MapRun(
        map=occupancy_map, yaml_path=yaml_path, image_path=image_path, meta_path=meta_path,
        n_scans=grid.n_scans, n_actions=ex.n_actions, n_blocked=ex.n_blocked,
        robot_seconds=ex.robot_seconds, sim_seconds=ex.sim_seconds, accuracy=accuracy,
        final_drift=ex.drift,
    )


@dataclass(frozen=True)
class _Exploration:
    """Counts and clocks of one exploration (s, m)."""

    n_actions: int
    n_blocked: int
    robot_seconds: float
    sim_seconds: float
    drift: float


def _explore(cfg: MapConfig, arena_cfg: Any, params: Any, grid: OccupancyGrid) -> _Exploration:
    """Drive uniformly random primitives until ``minutes`` of robot time, integrating every
    LIDAR scan into ``grid``.

    The decision step is the physics' :class:`~simlab.physics.driver.DecisionDriver`
    (choose a uniform primitive, execute it with the scan callback); it draws the random
    numbers in the order of the loop it replaced, so seeded maps are unchanged.
    """
    from tqdm import tqdm

    from simlab.physics.driver import DecisionDriver
    from simlab.physics.motion import N_ACTIONS
    from simlab.physics.world import World

    action_seq, noise_seq = np.random.SeedSequence(int(cfg.seed)).spawn(2)
    action_rng = np.random.default_rng(action_seq)
    noise_rng = np.random.default_rng(noise_seq)

    def integrate(scan, odom) -> None:
        base = scan.pose if cfg.pose_source == "truth" else odom
        grid.integrate(scan.ranges, scan.angles, sensor_pose(base, scan.sensor_offset),
                       scan.range_min, scan.range_max, cfg.inf_free_range)

    budget = float(cfg.minutes) * 60.0
    n_actions = n_blocked = 0
    with World(arena_cfg, physics_hz=resolve_rate(cfg.physics_hz)) as world:
        integrate(world.scan(noise_rng), world.odometry())
        driver = DecisionDriver(world, params, on_scan=integrate)

        def choose(_pose: Any, _state: Any) -> int:
            return int(action_rng.integers(0, N_ACTIONS))

        robot_time = 0.0
        with tqdm(total=round(budget), unit="s", desc="exploring",
                  disable=not cfg.progress) as bar:
            while robot_time < budget:
                step = driver.step(choose, noise_rng)
                n_actions += 1
                n_blocked += int(step.result.blocked)
                new_time = world.time + n_actions * params.decision_latency
                bar.update(min(round(new_time), round(budget)) - bar.n)
                robot_time = new_time
        sim_seconds = world.time
        drift = float(np.hypot(*(world.odometry()[:2] - world.pose()[:2])))
    return _Exploration(n_actions=n_actions, n_blocked=n_blocked, robot_seconds=robot_time,
                        sim_seconds=sim_seconds, drift=drift)
