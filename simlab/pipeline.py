"""``simlab pipeline``: the whole physics half, end to end, as one command.

Stages (each a library call that can also be run on its own; outputs under ``out``):

1. ``map``       explore the arena at random and build an occupancy map
                 (:func:`simlab.mapping.build_map`)              -> ``map/map.yaml``
2. ``states``    Voronoi states on the map (:func:`discretize.voronoi.discretize_map`)
                                                                 -> ``states/states.json``
3. ``dataset``   the 10-hour-equivalent epsilon = 1 random walk
                 (:func:`simlab.data.collect.collect`)           -> ``dataset/``
4. ``mdp``       the empirical P(s, a, s'), entropy per action (thesis Fig. 4.8)
                 (:func:`simlab.data.estimate.estimate`)         -> ``mdp/mdp.npz``
5. ``train``     value-iteration-softmax for each of the 9 goals (thesis Fig. 4.9, 4.3)
                 (:func:`simlab.training.train.train`)           -> ``qtables/``
6. ``replay``    the learned policy driven in physics for 3 hours with goal switching,
                 against a random policy and the MDP-predicted rate (thesis Fig. 4.10,
                 4.11) (:func:`simlab.replay.replay.replay`)      -> ``replay/``
7. ``report``    ``report.md``: the key numbers and every figure.

``pipeline.json`` records the configuration and, per finished stage, its wall time and
key numbers. ``resume=True`` skips the stages it lists as finished (same configuration
required), so a long run that was interrupted continues where it stopped.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

from simlab.errors import ConfigError
from simlab.io import atomic_write, atomic_write_json

STAGES = ("map", "states", "dataset", "mdp", "train", "replay", "report")


@dataclass(frozen=True)
class PipelineConfig:
    """Settings of a pipeline run. Defaults reproduce the thesis's physics experiment.

    Attributes:
        arena: built-in arena name or ``.toml`` path.
        seed: root seed; each stage gets its own stream derived from it.
        map_minutes: robot time of the mapping exploration (thesis: 73.1 min; 20 min
            already maps the table perfectly, see the report).
        map_resolution: occupancy cell size (m).
        states: number of Voronoi states (thesis: 41).
        hours: robot time of the random walk (thesis: about 10 h, 8,448 transitions).
        workers: parallel collection workers (one arena per process).
        agent: agent trained on the empirical MDP (thesis Fig. 4.9: value-iteration softmax).
        episodes, runs: training budget per goal (thesis: about 2,000 episodes).
        replay_hours: simulated hours of closed-loop replay (thesis Fig. 4.10: 3 h).
        pose_source: the replay's pose source: ``truth``, ``odometry`` or ``mcl``.
        video: write the top-down replay GIF (thesis Fig. 4.11).
    """

    arena: str = "table"
    seed: int = 0
    map_minutes: float = 20.0
    map_resolution: float = 0.01
    states: int = 41
    hours: float = 10.0
    workers: int = 2
    agent: str = "vi-softmax"
    episodes: int = 2000
    runs: int = 5
    replay_hours: float = 3.0
    pose_source: str = "mcl"
    video: bool = True

    def __post_init__(self) -> None:
        positive = ("map_minutes", "map_resolution", "hours", "replay_hours")
        for name in positive:
            value = getattr(self, name)
            if not isinstance(value, int | float) or not math.isfinite(value) or value <= 0:
                raise ConfigError(f"expected a number > 0, got {value!r}", key=name)
        for name in ("states", "workers", "episodes", "runs"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ConfigError(f"expected a whole number >= 1, got {value!r}", key=name)
        if self.pose_source not in ("truth", "odometry", "mcl"):
            raise ConfigError(f"expected truth, odometry or mcl, got {self.pose_source!r}",
                              key="pose_source")


@dataclass
class PipelineResult:
    """Where everything went and the key numbers (also in ``pipeline.json``)."""

    out: Path
    config: PipelineConfig
    stages: dict[str, dict[str, Any]] = field(default_factory=dict)
    report: Path | None = None
    wall_seconds: float = 0.0


class _Paths:
    def __init__(self, out: Path) -> None:
        self.out = out
        self.map_dir = out / "map"
        self.map_yaml = self.map_dir / "map.yaml"
        self.states = out / "states" / "states.json"
        self.states_png = out / "states" / "states.png"
        self.visits_png = out / "states" / "states_visits.png"
        self.dataset = out / "dataset"
        self.mdp = out / "mdp" / "mdp.npz"
        self.qtables = out / "qtables"
        self.replay = out / "replay"
        self.state_file = out / "pipeline.json"
        self.report = out / "report.md"


def _load_state(paths: _Paths, config: PipelineConfig, resume: bool) -> dict[str, Any]:
    if paths.state_file.exists():
        if not resume:
            raise ConfigError(
                "a pipeline run already exists here", path=paths.out,
                fix="pass --resume to continue it, or choose another --out",
            )
        try:
            state = json.loads(paths.state_file.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise ConfigError(f"unreadable pipeline state: {exc}", path=paths.state_file) from None
        saved = state.get("config", {})
        mismatch = [f.name for f in fields(config) if saved.get(f.name) != getattr(config, f.name)]
        if mismatch:
            raise ConfigError(
                f"settings differ from the run being resumed: {', '.join(mismatch)}",
                path=paths.state_file, fix="resume with the same settings or use a new --out",
            )
        return state
    if paths.out.exists() and any(paths.out.iterdir()):
        raise ConfigError("output directory is not empty", path=paths.out,
                          fix="choose a new or empty --out")
    return {"config": asdict(config), "stages": {}}


def pipeline(
    arena: str = "table",
    out: str | Path = "runs/table",
    *,
    config: PipelineConfig | None = None,
    resume: bool = False,
    progress: bool = True,
    log: Callable[[str], None] | None = print,
    **overrides: Any,
) -> PipelineResult:
    """Run the physics pipeline on ``arena`` into ``out`` (see the module docstring).

    ``overrides`` are :class:`PipelineConfig` fields (``hours=1.0`` for a quick run).
    ``log`` receives one line per stage (None: silent).
    """
    base = config or PipelineConfig(arena=arena)
    try:
        cfg = PipelineConfig(**{**asdict(base), "arena": arena, **overrides})
    except TypeError as exc:
        raise ConfigError(str(exc), key="pipeline settings") from None
    out = Path(out)
    paths = _Paths(out)
    state = _load_state(paths, cfg, resume)
    out.mkdir(parents=True, exist_ok=True)
    say = log or (lambda _line: None)
    t_start = time.perf_counter()

    runners: dict[str, Callable[[], dict[str, Any]]] = {
        "map": lambda: _stage_map(cfg, paths, progress),
        "states": lambda: _stage_states(cfg, paths, progress),
        "dataset": lambda: _stage_dataset(cfg, paths, progress),
        "mdp": lambda: _stage_mdp(cfg, paths),
        "train": lambda: _stage_train(cfg, paths, progress),
        "replay": lambda: _stage_replay(cfg, paths, progress),
        "report": lambda: _stage_report(cfg, paths, state),
    }
    for i, name in enumerate(STAGES, start=1):
        if name in state["stages"]:
            say(f"[{i}/{len(STAGES)}] {name}: done earlier, skipped")
            continue
        say(f"[{i}/{len(STAGES)}] {name} ...")
        t0 = time.perf_counter()
        numbers = runners[name]()
        numbers["wall_seconds"] = round(time.perf_counter() - t0, 2)
        state["stages"][name] = numbers
        atomic_write_json(paths.state_file, state)
        say(f"[{i}/{len(STAGES)}] {name}: {_headline(name, numbers)}")
    wall = time.perf_counter() - t_start
    return PipelineResult(out=out, config=cfg, stages=state["stages"], report=paths.report,
                          wall_seconds=wall)


# ----------------------------------------------------------------------------- stages


def _stage_map(cfg: PipelineConfig, p: _Paths, progress: bool) -> dict[str, Any]:
    from simlab.mapping import build_map

    run = build_map(cfg.arena, minutes=cfg.map_minutes, seed=cfg.seed, out=p.map_dir,
                    resolution=cfg.map_resolution, progress=progress)
    acc = run.accuracy
    return {"scans": run.n_scans, "actions": run.n_actions, "robot_minutes": run.robot_seconds / 60,
            "wall_correct": acc.wall_correct, "free_correct": acc.free_correct,
            "wall_coverage": acc.wall_coverage, "final_odometry_drift_m": run.final_drift}


def _stage_states(cfg: PipelineConfig, p: _Paths, progress: bool) -> dict[str, Any]:
    from discretize.voronoi import discretize_map

    res = discretize_map(p.map_yaml, p.states, states=cfg.states, png=p.states_png,
                         progress=progress)
    return {"states": res.discretizer.n_states, "hash": res.discretizer.content_hash()}


def _stage_dataset(cfg: PipelineConfig, p: _Paths, progress: bool) -> dict[str, Any]:
    from simlab.data.collect import collect

    res = collect(cfg.arena, p.states, out=p.dataset, hours=cfg.hours, seed=cfg.seed,
                  workers=cfg.workers, resume=p.dataset.exists(), progress=progress)
    return {"transitions": res.transitions, "simulated_hours": res.simulated_seconds / 3600,
            "collect_wall_seconds": res.wall_seconds,
            "peak_worker_rss_mb": res.peak_worker_rss_mb}


def _stage_mdp(cfg: PipelineConfig, p: _Paths) -> dict[str, Any]:
    from simlab.data.estimate import estimate

    res = estimate(p.dataset, p.mdp, overwrite=True)
    s = res.summary
    _visits_figure(p)
    ent = s["entropy_bits"]
    cov = s["coverage"]
    return {"fraction_visited": cov["fraction_visited"], "unvisited": cov["n_unvisited"],
            "entropy_slow": ent["slow_mean"], "entropy_fast": ent["fast_mean"],
            "entropy_per_action": ent["per_action"]}


def _visits_figure(p: _Paths) -> None:
    from discretize.mapio import read_map
    from discretize.plot import render_states_png, visits_from_dataset
    from discretize.voronoi import Discretizer

    disc = Discretizer.load(p.states)
    visits = visits_from_dataset(p.dataset, disc.n_states)
    png = render_states_png(read_map(p.map_yaml), disc, visits,
                            title=f"{disc.n_states} states, visits of the random walk")
    with atomic_write(p.visits_png, "wb") as fh:
        fh.write(png)


def _stage_train(cfg: PipelineConfig, p: _Paths, progress: bool) -> dict[str, Any]:
    from simlab.training.train import train

    s = train(p.mdp, agent=cfg.agent, goals="all", episodes=cfg.episodes, runs=cfg.runs,
              seed=cfg.seed, out=p.qtables, arena=cfg.arena, occupancy_map=p.map_yaml,
              overwrite=True, progress=progress)
    goals = {g.goal: asdict(g) for g in s.goals}
    ratios = [g.ratio for g in s.goals if g.ratio is not None]
    greedy = [g.greedy_ratio for g in s.goals if g.greedy_ratio is not None]
    return {"agent": s.agent, "goals": goals, "train_seconds": s.seconds,
            "min_ratio_to_optimal": min(ratios) if ratios else None,
            "min_greedy_ratio": min(greedy) if greedy else None}


def _stage_replay(cfg: PipelineConfig, p: _Paths, progress: bool) -> dict[str, Any]:
    from simlab.replay.replay import replay

    res = replay(cfg.arena, p.states, p.qtables, hours=cfg.replay_hours,
                 pose_source=cfg.pose_source, map=p.map_yaml, seed=cfg.seed, out=p.replay,
                 video=cfg.video, progress=progress)
    return dict(res.summary)


def _stage_report(cfg: PipelineConfig, p: _Paths, state: dict[str, Any]) -> dict[str, Any]:
    from simlab.pipeline_report import write_report

    write_report(p, cfg, state)
    return {"report": str(p.report)}


def _headline(name: str, n: dict[str, Any]) -> str:
    w = f"{n['wall_seconds']:.0f} s"
    if name == "map":
        return (f"walls {n['wall_correct']:.1%}, free {n['free_correct']:.1%} correct "
                f"({n['robot_minutes']:.0f} robot-min, {w})")
    if name == "states":
        return f"{n['states']} states ({w})"
    if name == "dataset":
        return (f"{n['transitions']} transitions, {n['simulated_hours']:.1f} simulated h "
                f"({w})")
    if name == "mdp":
        return (f"{n['fraction_visited']:.1%} of (s,a) visited; mean entropy slow "
                f"{n['entropy_slow']:.2f} / fast {n['entropy_fast']:.2f} bits ({w})")
    if name == "train":
        r = n.get("min_ratio_to_optimal")
        return (f"{n['agent']} on {len(n['goals'])} goals, worst goal at "
                f"{r:.0%} of optimal ({w})" if r else f"{n['agent']} ({w})")
    if name == "replay":
        keys = ("reward_rate_per_hour", "random_rate_per_hour", "predicted_rate_per_hour")
        if all(k in n for k in keys):
            return (f"{n[keys[0]]:.1f} goals/h vs random {n[keys[1]]:.1f}, MDP-predicted "
                    f"{n[keys[2]]:.1f} ({w})")
        return w
    return w
