"""The stages of the physics half, built once per settings and shared: the physics chain.

``simlab pipeline`` and the physics experiments of ``simlab reproduce`` (Figs. 4.8-4.10)
need the same intermediate products: an occupancy map, Voronoi states, a random-walk
dataset, the empirical MDP, the Q-tables trained on it and a closed-loop replay.
:class:`PhysicsChain` builds each of them with the library function that owns the stage
(:func:`simlab.orchestration.mapping.build_map`, :func:`discretize.command.discretize_command`,
:func:`simlab.data.collect.collect`, :func:`simlab.data.estimate.estimate`,
:func:`simlab.training.train.train`, :func:`simlab.replay.replay.replay`) into
``<cache>/physics/<stage>-<key>/`` where ``key`` hashes the stage's settings, its parent
stage's key, the root seed and the simlab version. So Fig. 4.9 reuses the 10-hour dataset
Fig. 4.8 collected when their settings agree (the three TOMLs keep them equal; a test
checks it), a second ``simlab reproduce`` into the same folder reuses the whole chain, and
``simlab pipeline --resume`` continues where an interrupted run stopped.

The stages live in a :class:`~simlab.orchestration.cache.StageCache` of scope
``"physics"`` (the one cache of simlab, shared with the Visit-the-lab runs): its key also
holds a fingerprint of the source of every package the chain runs and of the robot and
arena files, so after a change to that code a stage is rebuilt, never silently reused;
a folder is complete when its marker exists, interrupted or failed builds are removed
and a lock per stage keeps two processes from building it at once (see that module).

Seeds: stage ``k`` of chain seed ``i`` uses the integer
``SeedSequence(root_seed, spawn_key=(PHYSICS_SPAWN_KEY, k, i)).generate_state(1)[0]``:
independent streams for the map, the walks, the training and the replays, the same for
every experiment of a reproduction (so they share), different for another ``--seed``.

Settings (``[params]`` of the TOML, overridden by the budget table; every key is
optional and defaults to the thesis's setting):

==================  =========================================================  ========
key                 meaning                                                    default
==================  =========================================================  ========
``arena``           built-in arena name or ``.toml`` path                      table
``map_minutes``     robot minutes of the random mapping exploration            20
``map_resolution``  occupancy cell size (m)                                    0.01
``states``          Voronoi states (thesis 4.5: 41)                            41
``hours``           robot hours of each random walk (thesis: ~10 h)            10
``workers``         parallel walks per dataset (part of the dataset's seed)    2
``agent``           agent trained on the empirical MDP (thesis: VI softmax)    vi-softmax
``episodes``        training episodes per goal (thesis: ~2000)                 2000
``runs``            independent training runs per goal (averaged Q)            10
``horizon``         steps per training episode                                 50
``replay_hours``    robot hours of each closed-loop replay (thesis: 3 h)       3
``pose_source``     the replay's pose source: truth, odometry or mcl           mcl
``video``           write the replay GIF of chain seed 0 (thesis Fig. 4.11)    false
``seeds``           independent chains: datasets (with their MDP, training     1
                    and replay) from one map and one set of states
``physics_hz``      physics rate of the map, the walks and the replays (Hz,    50
                    at least :data:`simlab.physics.rate.MIN_HZ`)
==================  =========================================================  ========
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base import validation
from simlab.base.errors import ConfigError
from simlab.localization.sources import POSE_SOURCES
from simlab.orchestration.cache import MARKER, Stage, StageCache
from simlab.physics.rate import DEFAULT_HZ, check_rate

__all__ = ["MARKER", "PHYSICS_SPAWN_KEY", "STAGE_INDEX", "PhysicsChain", "PhysicsSettings",
           "Stage", "chain_seed"]

#: First element of every physics spawn key ("PHYS" in ASCII).
PHYSICS_SPAWN_KEY = 0x50485953
STAGE_INDEX = {"map": 0, "dataset": 1, "train": 2, "replay": 3, "baseline": 4}


@dataclass(frozen=True)
class PhysicsSettings:
    """The physics chain's settings (see the module docstring's table)."""

    arena: str = "table"
    map_minutes: float = 20.0
    map_resolution: float = 0.01
    states: int = 41
    hours: float = 10.0
    workers: int = 2
    agent: str = "vi-softmax"
    episodes: int = 2000
    runs: int = 10
    horizon: int = 50
    replay_hours: float = 3.0
    pose_source: str = "mcl"
    video: bool = False
    seeds: int = 1
    #: ``[primitives]`` TOML of the dataset walk (e.g. ``simlab calibrate``'s
    #: ``primitives.toml``); "" = the built-in primitives. Replay takes the dataset's.
    primitives: str = ""
    #: Physics rate (Hz) of every physics stage; the stages' cache keys hold it.
    physics_hz: float = DEFAULT_HZ

    def primitive_params(self) -> Any:
        """The walk's :class:`~simlab.physics.motion.PrimitiveParams` (None: built-in)."""
        if not self.primitives:
            return None
        from simlab.physics.motion import PrimitiveParams

        return PrimitiveParams.from_toml(self.primitives)

    @classmethod
    def from_tables(cls, params: Mapping[str, Any], budget: Mapping[str, Any]
                    ) -> PhysicsSettings:
        """Merge ``[params]`` and the budget table (the budget wins) and validate, naming
        the table and key of a bad value (``budget.hours``)."""
        names = {f.name: f for f in dataclasses.fields(cls)}
        values: dict[str, Any] = {}
        where: dict[str, str] = {}
        for table, src in (("params", params), ("budget", budget)):
            for k, v in src.items():
                if k not in names:
                    raise ConfigError(f"unknown physics setting {k!r}", key=f"{table}.{k}",
                                      fix=f"known: {', '.join(names)}")
                values[k] = v
                where[k] = f"{table}.{k}"
        return cls._validated(values, where)

    @classmethod
    def create(cls, **values: Any) -> PhysicsSettings:
        """Settings from keyword values (defaults for the rest), validated like a TOML's;
        errors name the setting (``hours: expected a finite number > 0``)."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = set(values) - names
        if unknown:
            raise ConfigError(f"unknown physics setting(s) {sorted(unknown)}",
                              key="settings", fix=f"known: {', '.join(sorted(names))}")
        return cls._validated(dict(values), {})

    @classmethod
    def _validated(cls, values: dict[str, Any], where: dict[str, str]) -> PhysicsSettings:
        names = {f.name: f for f in dataclasses.fields(cls)}
        defaults = cls()
        for name in names:
            v = values.get(name, getattr(defaults, name))
            key = where.get(name, name)
            kind = type(getattr(defaults, name))
            if kind is bool:
                v = validation.boolean(v, key)
            elif kind is int:
                v = validation.whole(v, key, minimum=1)
            elif kind is float:
                v = validation.positive(v, key)
            elif not isinstance(v, str) or (not v and name != "primitives"):
                raise ConfigError(f"expected a non-empty string, got {v!r}", key=key)
            values[name] = v
        validation.choice(values["pose_source"], POSE_SOURCES,
                          where.get("pose_source", "pose_source"))
        check_rate(values["physics_hz"], where.get("physics_hz", "physics_hz"))
        settings = cls(**{k: values[k] for k in names})
        settings.check_references(where)
        return settings

    def check_references(self, where: Mapping[str, str] | None = None) -> None:
        """Validate the settings that name things (the agent, the arena) and the sizes,
        before any work: ``pipeline --agent nosuch`` must not fail after the mapping."""
        from simlab.agents.registry import agent_config
        from simlab.base.guards import array_bytes, check_memory
        from simlab.physics.arena import ArenaConfig, load_arena

        where = where or {}
        self.primitive_params()  # a bad [primitives] file is refused before any work
        try:
            agent_config(self.agent, None)
        except ConfigError as exc:
            raise ConfigError(exc.problem, key=where.get("agent", "agent"), fix=exc.fix) from None
        arena = load_arena(self.arena)
        assert isinstance(arena, ArenaConfig)
        x0, y0, x1, y1 = arena.bounds
        cells = ((x1 - x0) / self.map_resolution + 50) * ((y1 - y0) / self.map_resolution + 50)
        check_memory(array_bytes((cells,), 25), key=where.get("map_resolution", "map_resolution"),
                     what=f"the occupancy map of arena {arena.name!r}",
                     fix="a smaller arena or a coarser map_resolution")
        # Every state needs a free pixel of its own: the floor's pixels bound the count
        # before the mapping (the exact free count, after erosion, is known only after it).
        floor = int((x1 - x0) / self.map_resolution) * int((y1 - y0) / self.map_resolution)
        if self.states > floor:
            raise ConfigError(f"{self.states} states requested but the floor of arena "
                              f"{arena.name!r} has only {floor} pixels of "
                              f"{self.map_resolution:g} m", key=where.get("states", "states"),
                              fix="ask for fewer states (the thesis: 41) or a finer "
                              "map_resolution")


def chain_seed(root_seed: int, stage: str, i: int) -> int:
    """The integer seed of ``stage`` for chain seed ``i`` (module docstring)."""
    seq = np.random.SeedSequence(int(root_seed),
                                 spawn_key=(PHYSICS_SPAWN_KEY, STAGE_INDEX[stage], int(i)))
    return int(seq.generate_state(1, np.uint32)[0])


class PhysicsChain:
    """Builds (or finds in ``cache``) the stages of the physics chain for ``settings``.

    ``root_seed`` is the reproduction's seed; ``backend`` / ``address`` are passed to
    :func:`~simlab.data.collect.collect` (its walks run as local processes or Ray tasks);
    ``log`` receives one line per stage. ``worker``: a one-process executor the caller
    lends to the training and the replay as their second core (the pipeline's warmed
    process, :mod:`simlab.orchestration.warmup`); None: they start their own. It changes
    no result.
    """

    def __init__(self, cache: Path, settings: PhysicsSettings, root_seed: int, *,
                 backend: str = "local", progress: bool = False,
                 log: Callable[[str], None] | None = None) -> None:
        self.root = Path(cache) / "physics"
        self.s = settings
        self.root_seed = int(root_seed)
        self.backend = backend
        self.progress = progress
        self.cache = StageCache(self.root, "physics", log=log)
        self.worker: Any = None

    # ------------------------------------------------------------------ machinery

    def cached_stage(self, stage: str, key: Mapping[str, Any],
                     build: Callable[[Path], dict[str, Any]]) -> Stage:
        """The folder of ``stage`` for ``key``: found complete in the cache, or made by
        ``build(folder) -> summary`` (JSON-ready numbers recorded in the marker)."""
        return self.cache.get(stage, key, build)

    @property
    def stages(self) -> list[Stage]:
        """The stages this chain object built or found, in the order first needed."""
        return self.cache.stages

    # ------------------------------------------------------------------ stages

    def map(self) -> Stage:
        """The occupancy map (``map.yaml``) of a random exploration."""
        s = self.s
        seed = chain_seed(self.root_seed, "map", 0)

        def build(d: Path) -> dict[str, Any]:
            from simlab.orchestration.mapping import build_map

            run = build_map(s.arena, minutes=s.map_minutes, seed=seed, out=d,
                            resolution=s.map_resolution, progress=self.progress,
                            physics_hz=s.physics_hz)
            return {"wall_correct": run.accuracy.wall_correct,
                    "free_correct": run.accuracy.free_correct, "scans": run.n_scans}

        return self.cached_stage("map", {"arena": s.arena, "minutes": s.map_minutes,
                                         "resolution": s.map_resolution, "seed": seed,
                                         "physics_hz": s.physics_hz}, build)

    def states(self) -> Stage:
        """Voronoi states on the map (``states.json``, ``states.png``)."""
        parent = self.map()

        def build(d: Path) -> dict[str, Any]:
            from discretize.command import discretize_command

            try:
                res = discretize_command(parent.path / "map.yaml", d / "states.json",
                                         states=self.s.states, png=d / "states.png",
                                         progress=self.progress)
            except ConfigError as exc:
                if exc.key != "states":
                    raise
                # the map is this pipeline's own file: say it of the option the user gave
                raise ConfigError(f"{exc.problem}, on the map the pipeline built", key="states",
                                  fix="ask for fewer states or a finer map_resolution") from None
            return {"n_states": int(res.discretizer.n_states),
                    "hash": res.discretizer.content_hash()}

        return self.cached_stage("states", {"parent": parent.key, "states": self.s.states}, build)

    def dataset(self, i: int) -> Stage:
        """Chain seed ``i``'s random-walk dataset (``data/``)."""
        s = self.s
        parent = self.states()
        seed = chain_seed(self.root_seed, "dataset", i)

        def build(d: Path) -> dict[str, Any]:
            from simlab.data.collect import collect

            res = collect(s.arena, parent.path / "states.json", out=d / "data", hours=s.hours,
                          seed=seed, workers=s.workers, backend=self.backend,
                          progress=self.progress, params=s.primitive_params(),
                          physics_hz=s.physics_hz)
            return {"transitions": res.transitions, "simulated_hours": res.simulated_hours,
                    "collect_wall_seconds": res.wall_seconds}

        key = {"parent": parent.key, "hours": s.hours, "workers": s.workers, "seed": seed,
               "physics_hz": s.physics_hz}
        params = s.primitive_params()
        if params is not None:  # absent for the built-in primitives: old cache keys still hold
            key["primitives"] = params.to_json()
        return self.cached_stage("dataset", key, build)

    def mdp(self, i: int) -> Stage:
        """Chain seed ``i``'s empirical MDP (``mdp.npz``, ``mdp.json``, entropy plot)."""
        parent = self.dataset(i)

        def build(d: Path) -> dict[str, Any]:
            from simlab.data.estimate import estimate

            res = estimate(parent.path / "data", d / "mdp.npz")
            e = res.summary["entropy_bits"]
            return {"entropy_slow": e["slow_mean"], "entropy_fast": e["fast_mean"],
                    "fraction_visited": res.summary["coverage"]["fraction_visited"],
                    "transitions": res.summary["transitions"]}

        return self.cached_stage("mdp", {"parent": parent.key}, build)

    def qtables(self, i: int) -> Stage:
        """Chain seed ``i``'s Q-tables: the ``simlab train`` folder (``q_<goal>.npz``,
        ``summary.json``, ``curves.png``, ``heatmaps.png``) for every goal."""
        s = self.s
        parent = self.mdp(i)
        occupancy = self.map().path / "map.yaml"
        seed = chain_seed(self.root_seed, "train", i)

        def build(d: Path) -> dict[str, Any]:
            from simlab.training.train import train

            res = train(parent.path / "mdp.npz", agent=s.agent, goals="all",
                        episodes=s.episodes, runs=s.runs, seed=seed, out=d, horizon=s.horizon,
                        arena=s.arena, occupancy_map=occupancy, overwrite=True,
                        progress=self.progress, pool=self.worker)
            return {"goals": {g.goal: g.as_dict() for g in res.goals},
                    "train_seconds": res.seconds}

        return self.cached_stage("train", {"parent": parent.key, "agent": s.agent,
                                           "episodes": s.episodes, "runs": s.runs,
                                           "horizon": s.horizon, "seed": seed}, build)

    def replay(self, i: int) -> Stage:
        """Chain seed ``i``'s closed-loop replay of its Q-tables in physics, with the random
        policy as baseline (``replay.json``, ``cumulative_reward.png``, ``replay.gif`` when
        ``video``; see :func:`simlab.replay.replay.replay`)."""
        s = self.s
        q, mdp, states = self.qtables(i), self.mdp(i), self.states()
        map_yaml = self.map().path / "map.yaml"
        seed = chain_seed(self.root_seed, "replay", i)

        def build(d: Path) -> dict[str, Any]:
            from simlab.replay.replay import replay

            res = replay(s.arena, states.path / "states.json", q.path, hours=s.replay_hours,
                         pose_source=s.pose_source, seed=seed, out=d, map=map_yaml,
                         video=s.video, progress=self.progress, overwrite=True,
                         mdp=mdp.path / "mdp.npz", pool=self.worker,
                         physics_hz=s.physics_hz)
            keys = ("reward_rate_per_hour", "random_rate_per_hour", "predicted_rate_per_hour",
                    "position_error_mean_m")
            return {k: getattr(res.summary, k) for k in keys
                    if getattr(res.summary, k) is not None}

        return self.cached_stage("replay", {"parent": q.key, "mdp": mdp.key, "seed": seed,
                                            "hours": s.replay_hours,
                                            "pose_source": s.pose_source, "video": s.video,
                                            "physics_hz": s.physics_hz},
                                 build)
