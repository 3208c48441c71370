"""``simlab pipeline``: the whole physics half, end to end, as one command.

Stages (each the library call of a subcommand of its own), built by the physics chain
(:class:`simlab.orchestration.stages.PhysicsChain`):

1. ``map``      explore the arena at random and build an occupancy map  (``simlab map``)
2. ``states``   Voronoi states on the map                          (``simlab discretize``)
3. ``dataset``  the 10-hour-equivalent epsilon = 1 random walk        (``simlab collect``)
4. ``mdp``      the empirical P(s, a, s'), entropy per action, Fig. 4.8 (``simlab estimate``)
5. ``train``    value-iteration softmax for each goal, Figs. 4.9, 4.3    (``simlab train``)
6. ``replay``   the learned policy driven in physics for 3 hours with goal switching,
                against a random policy and the MDP-predicted rate, Figs. 4.10, 4.11
                                                                      (``simlab replay``)

then ``report.md`` with the key numbers beside the thesis's and every figure.

Layout of ``out``: the stages live in ``stages/physics/<stage>-<key>/`` where ``key``
hashes the stage's settings and those of the stages it depends on; ``map``, ``states``,
``dataset``, ``mdp``, ``qtables`` and ``replay`` are links to the current ones;
``pipeline.json`` records the settings, the seed and each stage's numbers and wall time.
``resume=True`` reuses every stage whose settings did not change (an interrupted run
continues where it stopped; changing, say, the replay hours redoes only the replay).
"""

from __future__ import annotations

import os
import shutil
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

from simlab.base import validation
from simlab.base.errors import ConfigError
from simlab.base.io import atomic_write_bytes, atomic_write_json, exclusive_directory
from simlab.base.options import CommandConfig, command, option
from simlab.localization.sources import POSE_SOURCES
from simlab.orchestration.report import train_ratios
from simlab.orchestration.stages import PhysicsChain, PhysicsSettings, Stage
from simlab.physics.rate import MIN_HZ

#: Pipeline stage -> the link to its folder in the output folder.
STAGES: dict[str, str] = {"map": "map", "states": "states", "dataset": "dataset", "mdp": "mdp",
                          "train": "qtables", "replay": "replay"}

_D = PhysicsSettings  # its class attributes are the chain's defaults, spelled once there


@dataclass(frozen=True, kw_only=True)
class PipelineConfig(CommandConfig):
    """Every option of ``simlab pipeline`` (the physics settings are
    :class:`~simlab.orchestration.stages.PhysicsSettings`'s, with its defaults)."""

    COMMAND = "pipeline"
    ARGUMENTS = ("arena", "out")
    arena: str = option(_D.arena, "built-in arena name or .toml path")
    out: Path = option(help="output directory (new or empty, or --resume)")
    resume: bool = option(False, "continue a run in --out, reusing every stage whose settings "
                                 "match")
    seed: int = option(0, "root seed of every stage")
    map_minutes: float = option(_D.map_minutes, "robot minutes of mapping exploration")
    map_resolution: float = option(_D.map_resolution, "occupancy map cell size, metres",
                                   cli=False)
    states: int = option(_D.states, "Voronoi states")
    hours: float = option(_D.hours, "simulated hours of random walk")
    workers: int = option(_D.workers, "collection processes")
    agent: str = option(_D.agent, "agent trained per goal")
    episodes: int = option(_D.episodes, "training episodes per goal")
    runs: int = option(_D.runs, "independent training runs per goal")
    horizon: int = option(_D.horizon, "training episode length, decisions", cli=False)
    replay_hours: float = option(_D.replay_hours, "simulated hours of closed-loop replay")
    pose_source: str = option(_D.pose_source, "the replay's pose source",
                              choices=POSE_SOURCES)
    # the pipeline writes the replay video unless told not to (the chain's default is off)
    video: bool = option(True, "the replay GIF (--no-video skips it)")
    seeds: int = option(_D.seeds, "replay seeds", cli=False)
    primitives: str = option(_D.primitives, "[primitives] of the dataset walk, e.g. simlab "
                             "calibrate's primitives.toml (default: built-in; replay uses "
                             "the dataset's)", metavar="FILE.toml")
    physics_hz: float = option(_D.physics_hz, "physics steps per simulated second of the map, "
                               f"the walk and the replay (at least {MIN_HZ:g}: the "
                               "primitives' control rate)", metavar="HZ")
    progress: bool = option(True, "progress bars (--no-progress hides them)")

    def validate(self) -> None:
        validation.whole(self.seed, "seed")

    def physics_settings(self) -> PhysicsSettings:
        """The chain's settings, validated (names and sizes checked before any work)."""
        names = {f.name for f in fields(PhysicsSettings)}
        return PhysicsSettings.create(**{k: v for k, v in self.to_dict().items() if k in names})


@dataclass
class PipelineResult:
    """Where everything went and the key numbers (also in ``pipeline.json``)."""

    out: Path
    settings: PhysicsSettings
    seed: int
    stages: dict[str, dict[str, Any]] = field(default_factory=dict)
    report: Path | None = None
    wall_seconds: float = 0.0


def _check_out(out: Path, resume: bool) -> None:
    if (out / "pipeline.json").exists():
        if not resume:
            raise ConfigError("a pipeline run already exists here", path=out,
                              fix="pass --resume to continue it, or choose another --out")
    elif out.exists() and any(out.iterdir()):
        raise ConfigError("output directory is not empty", path=out,
                          fix="choose a new or empty --out")


def _read_state(out: Path) -> dict[str, Any]:
    """``pipeline.json`` of a run being resumed (DataError naming it if damaged)."""
    import json

    from simlab.base.errors import DataError

    path = out / "pipeline.json"
    try:
        state = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DataError(f"{path}: not valid JSON ({exc}); delete it to start over") from None
    if not isinstance(state, dict) or not isinstance(state.get("stages", {}), dict):
        raise DataError(f"{path}: stages: expected an object; delete it to start over")
    return state


def _link(link: Path, target: Path) -> None:
    """Point ``link`` at ``target`` (relative symlink), replacing only a link of ours."""
    if link.exists() and not link.is_symlink():
        raise ConfigError("exists and is not a link made by simlab pipeline", path=link,
                          fix="move it away or choose another --out")
    tmp = link.with_name(f".{link.name}.link")
    tmp.unlink(missing_ok=True)
    os.symlink(os.path.relpath(target, link.parent), tmp)
    os.replace(tmp, link)


@command(PipelineConfig, extras=("log",))
def pipeline(cfg: PipelineConfig, log: Callable[[str], None] | None = print) -> PipelineResult:
    """Run the physics pipeline on ``cfg.arena`` into ``cfg.out`` (see the module docstring).

    Takes a :class:`PipelineConfig` or its fields (``pipeline("table", "runs/x", hours=1.0)``
    for a quick run; the defaults are the thesis's); ``seed`` is the root seed of every
    stage; ``log`` receives one line per stage (None: silent).
    """
    s = cfg.physics_settings()
    seed, resume, progress = cfg.seed, cfg.resume, cfg.progress
    out = cfg.out
    if out.exists() and not out.is_dir():
        raise ConfigError("exists and is not a directory", path=out, fix="choose another --out")
    created = not out.exists()
    with exclusive_directory(out, what="pipeline output directory"):
        _check_out(out, resume)
        try:
            return _run_pipeline(out, s, seed, progress, log)
        except BaseException:
            if created and not _any_stage_done(out):
                # a run that failed before finishing any stage leaves nothing: the fresh
                # rerun and --resume both work
                shutil.rmtree(out, ignore_errors=True)
            raise


def _any_stage_done(out: Path) -> bool:
    from simlab.orchestration.stages import MARKER

    return any((out / "stages").glob(f"physics/*/{MARKER}"))


def _run_pipeline(out: Path, s: PhysicsSettings, seed: int, progress: bool,
                  log: Callable[[str], None] | None) -> PipelineResult:
    """The stages and the report of :func:`pipeline` (``out`` is locked and checked)."""
    say = log or (lambda _line: None)
    t_start = time.perf_counter()
    chain = PhysicsChain(out / "stages", s, seed, progress=progress)
    from simlab.orchestration.warmup import start_warmup

    # numba compiles the training and MCL kernels in a spare process while the map and the
    # walk run in physics; training then loads them from numba's cache, and the warmed
    # process is lent to the training and the replay as their second core
    with start_warmup(agent=s.agent, mcl=s.pose_source == "mcl") as warm:
        return _run_stages(out, chain, s, seed, say, warm, t_start)


def _run_stages(out: Path, chain: PhysicsChain, s: PhysicsSettings, seed: int,
                say: Callable[[str], None], warm: Any, t_start: float) -> PipelineResult:
    """The stages, one after the other, then the report (``warm``: the warm-up handle)."""
    build: dict[str, Callable[[], Stage]] = {  # chain seed 0: the pipeline is one chain
        "map": chain.map, "states": chain.states, "dataset": lambda: chain.dataset(0),
        "mdp": lambda: chain.mdp(0), "train": lambda: chain.qtables(0),
        "replay": lambda: chain.replay(0),
    }
    state: dict[str, Any] = {"settings": asdict(s), "seed": seed, "stages": {}}
    if (out / "pipeline.json").exists():  # --resume: keep the stages recorded so far
        state["stages"] = _read_state(out).get("stages", {})
    atomic_write_json(out / "pipeline.json", state)  # first: an interrupted run is resumable
    n = len(STAGES) + 1
    visits = None
    for k, (name, link) in enumerate(STAGES.items(), start=1):
        say(f"[{k}/{n}] {name} ...")
        if name == "train":
            _await_warmup(warm, state, say)
            chain.worker = warm.worker
            if chain.worker is not None:
                # the report's visits figure needs only the walk: the lent worker draws it
                # first (the training takes back the goals it cannot start meanwhile), so
                # that it is idle again when the replay counts the idle cores
                visits = chain.worker.submit(_visits_figure, out)
        stage = build[name]()
        _link(out / link, stage.path)
        record = {**stage.summary, "folder": link, "built": stage.built,
                  "wall_seconds": round(stage.wall_seconds, 2)}
        state["stages"][name] = record
        atomic_write_json(out / "pipeline.json", state)
        done = f"built in {stage.wall_seconds:.0f} s" if stage.built else "reused"
        say(f"[{k}/{n}] {name}: {_headline(name, record, s)} ({done})")
    say(f"[{n}/{n}] report ...")
    if visits is None or visits.exception() is not None:
        _visits_figure(out)  # no worker, or it failed: draw it here
    from simlab.orchestration.report import write_report

    report = write_report(out, s, seed, state)
    say(f"[{n}/{n}] report: {report}")
    return PipelineResult(out=out, settings=s, seed=seed, stages=state["stages"], report=report,
                          wall_seconds=time.perf_counter() - t_start)


def _await_warmup(warm: Any, state: dict[str, Any], say: Callable[[str], None]) -> None:
    """Wait for the numba warm-up before training and record the wait in ``state``
    (``warmup``: its seconds, outside every stage's wall time; long only on the first run
    of a simlab version, whose kernels are compiled then)."""
    t = time.perf_counter()
    warm.wait()
    waited = time.perf_counter() - t
    state["warmup"] = {"wait_seconds": round(waited, 2), "ok": warm.ok,
                       "worker_seconds": round(warm.future.result(), 2) if warm.ok else None}
    if waited >= 1.0:
        say(f"waited {waited:.0f} s for numba to compile the training kernels (first run "
            "of this simlab version; later runs load them from the cache)")


def _visits_figure(out: Path) -> None:
    """``figures/states_visits.png``: the states coloured by the random walk's visits
    (a module-level function: the pipeline's lent worker runs it)."""
    from discretize.mapio import read_map
    from discretize.plot import render_states_png, visits_from_dataset
    from discretize.voronoi import Discretizer

    disc = Discretizer.load(out / "states" / "states.json")
    visits = visits_from_dataset(out / "dataset" / "data", disc.n_states)
    png = render_states_png(read_map(out / "map" / "map.yaml"), disc, visits,
                            title=f"{disc.n_states} states, visits of the random walk")
    atomic_write_bytes(out / "figures" / "states_visits.png", png)


def _headline(name: str, r: dict[str, Any], s: PhysicsSettings) -> str:
    if name == "map":
        return f"walls {r['wall_correct']:.1%}, free space {r['free_correct']:.1%} correct"
    if name == "states":
        return f"{r['n_states']} states"
    if name == "dataset":
        return f"{r['transitions']} transitions, {r['simulated_hours']:.1f} simulated h"
    if name == "mdp":
        return (f"{r['fraction_visited']:.1%} of (s,a) visited; mean entropy slow "
                f"{r['entropy_slow']:.2f} / fast {r['entropy_fast']:.2f} bits")
    if name == "train":
        worst, _ = train_ratios(r)
        return (f"{s.agent} on {len(r['goals'])} goals, worst goal at {worst:.0%} of optimal"
                if worst is not None else s.agent)
    keys = ("reward_rate_per_hour", "random_rate_per_hour", "predicted_rate_per_hour")
    if all(r.get(k) is not None for k in keys):
        return (f"{r[keys[0]]:.1f} goals/h vs random {r[keys[1]]:.1f}, MDP-predicted "
                f"{r[keys[2]]:.1f}")
    return "done"
