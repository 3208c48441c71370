"""``simlab replay``: the learned policy driven in closed loop in physics (thesis 4.5,
Fig. 4.10).

The question of the physics half: does a policy planned on the empirical matrix work
when the robot drives it? The replay does what the thesis's TurtleBot did for three
hours (Fig. 4.10):

1. the robot starts at the arena's start pose; the first goal is drawn uniformly among
   the arena's goals;
2. at each decision it reads its pose from the **pose source** (``truth``: the
   simulator; ``odometry``: the wheel encoders, which drift; ``mcl``: the LIDAR particle
   filter of :mod:`simlab.localization` on the occupancy map, started at the known start
   pose), turns it into a Markov state with the discretizer, and picks
   ``argmax_a Q_goal(s, a)`` over the **valid** actions (ties broken at random;
   ``policy="random"`` picks uniformly among all the robot's actions);
3. it executes the motion primitive of that action, ``action_set.to_primitive(a)`` (the
   Q-tables' :class:`~simlab.base.actions.ActionSet`: 16 simlab primitives, or e.g. a real
   robot's 8 actions numbered counter-clockwise from East), in physics; the obstacle
   detector is part of the primitive (a blocked primitive rotates but does not translate);
4. the robot clock advances by the primitive's stepped duration plus the decision latency
   (idle, not stepped);
5. if the state reached (from the pose source, as the real robot only knows its
   estimate) lies in the current goal (goal masks of the arena and discretizer, the
   estimator's rule), the reward is +1 and the goal switches to one of the other goals
   drawn uniformly; with ``return_to_start`` the robot first drives back to the start
   pose (the thesis's ``go_back_initial_pose`` node: turn, straight line, turn; no
   obstacle check; its time counts, it earns nothing).

Decisions where the thesis is silent:

* **blocked retries** (``retry_blocked``, default on): the simulated robot is
  deterministic, so a greedy action the detector refused would be refused again from the
  same pose forever. After a blocked primitive the refused action is excluded at that
  pose; the robot takes the best remaining one; the exclusions clear once the robot has
  moved. (The empirical MDP models a blocked action as a chance of staying; the physics
  makes it a certainty at a given pose. This is part of the sim-to-model gap.)
* **loop watchdog** (``escape_radius``, default 0.03 m): the simulator has no motion
  noise, so a greedy policy can fall into an exact limit cycle (UP fast into a cell whose
  greedy action is DOWN fast, back to the same pose, and so on for hours) that the
  empirical MDP, estimated over all positions within the cells, sees as a rare transient.
  The real robot's wheel slip and localization noise break such loops. Here, when the
  greedy choice is an action already taken in the current goal episode from a pose
  (of the pose source) within ``escape_radius``, the physics would repeat itself, so the
  robot takes a uniformly random other action instead (counted as ``escapes``). Repeats
  from other positions (a robot crossing a large cell in several moves) are not
  touched. ``epsilon`` > 0 gives an epsilon-greedy policy instead or in addition
  (modelled exactly by the prediction, unlike the watchdog).
* **heading control**: the primitives steer by the true heading (the stand-in for the
  localized heading, see :class:`~simlab.physics.motion.PrimitiveParams`), except with the
  ``odometry`` pose source, where the robot has nothing but its encoders and steers by
  the odometry heading.
* **random baseline**: for ``policy="greedy"`` a random-policy replay of
  ``baseline_hours`` (default: the same duration) runs in a second world with its own
  seed stream and the truth pose source (a random policy ignores the pose; only the
  bookkeeping of rewards uses it).
* **masked actions**: the Q-tables' saved ``valid`` mask (or, for Q-tables
  without one and not trained with the ``self-loop`` rule, the MDP's) is never violated by
  the greedy choice, the blocked-retry fallback or the loop watchdog; only ``epsilon``
  exploration and the random baseline draw among all actions (as the prediction models).
  Q-tables whose action set differs from the MDP's are refused.
* **primitive parameters**: the robot must drive the primitives the model was estimated
  from, so by default the replay uses those recorded in the MDP's dataset manifest
  (found through ``mdp.json``); explicit ``params`` that differ raise ConfigError.
* **predicted rate**: :mod:`simlab.replay.prediction`, at the dataset's pace (its robot
  seconds per transition) and at the replay's own measured pace.
* **scheduling** (``parallel=True`` on 2 or more usable cores, decided from the
  core count, :func:`schedule`): the random baseline runs in a ``spawn`` process while this
  one drives the learned policy (and then encodes the video); on 3 or more cores the
  ``mcl`` filter runs in a third process fed scan by scan
  (:class:`~simlab.localization.remote.RemoteTracker`; the robot waits for it only at
  decisions and video frames). The worlds and seed streams are independent, so the
  results are bit-identical to ``parallel=False``; the replay's wall time becomes that
  of its longest part instead of the sum.

Outputs in ``out``: ``replay.json`` (summary; the headline numbers also flat at its top
level: ``reward_rate_per_hour``, ``random_rate_per_hour``, ``predicted_rate_per_hour``,
``position_error_mean_m`` of a non-truth pose source), ``cumulative_reward.png`` (Fig. 4.10:
learned policy, random policy, MDP-predicted rates), ``transitions.parquet`` (one row per
transition), ``localization.parquet`` (one row per filter update, ``mcl`` only),
``replay.gif`` (and ``replay.mp4`` if imageio-ffmpeg is installed) with ``video=True``.
Every output path is checked before the robot moves; each file is written atomically.

Modules: :mod:`~simlab.replay.config` (:class:`ReplayConfig`, every option once),
:mod:`~simlab.replay.loop` (one run: the decision loop on
:class:`~simlab.physics.driver.DecisionDriver`, its recorder and log),
:mod:`~simlab.replay.policy` (the action choice), :mod:`~simlab.replay.scheduling`
(processes), :mod:`~simlab.replay.summary` (the typed summary, ``replay.json``),
:mod:`~simlab.replay.writers` (the files); this module loads and checks the inputs and
runs them in order.

Seeding: ``SeedSequence(seed).spawn(5)`` -> (policy ties / random actions, LIDAR noise,
localization, goal draws, random baseline); same seed, same replay.
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simlab.base.errors import ConfigError
from simlab.base.io import atomic_write, atomic_write_json, ensure_new, output_transaction
from simlab.base.options import command
from simlab.localization.sources import POSE_SOURCES
from simlab.physics.rate import settings_for
from simlab.replay.config import POLICIES, ReplayConfig
from simlab.replay.loop import FRAME_PARTICLES, ReplayLog, RunOutcome, RunSpec, drive_to_pose
from simlab.replay.policy import greedy_action
from simlab.replay.scheduling import RunPlan, run_both, schedule, usable_cores
from simlab.replay.summary import (
    BaselineStats,
    ReplaySummary,
    Schedule,
    comparison,
    localization_summary,
    run_stats,
)

__all__ = ["FRAME_PARTICLES", "POLICIES", "POSE_SOURCES", "ReplayConfig", "ReplayLog",
           "ReplayResult", "ReplaySummary", "RunOutcome", "drive_to_pose", "greedy_action",
           "replay", "schedule", "usable_cores"]


@dataclass(frozen=True)
class ReplayResult:
    """What :func:`replay` did: the summary (``replay.json``), the runs and the files."""

    summary: ReplaySummary
    run: RunOutcome
    baseline: RunOutcome | None
    files: dict[str, Path]

    @property
    def rate_per_hour(self) -> float:
        return float(self.summary.result.rate_per_hour)

    @property
    def summary_dict(self) -> dict[str, Any]:
        """The summary as the replay.json dict."""
        return self.summary.to_json()


@dataclass(frozen=True)
class _Inputs:
    """The replay's inputs, loaded and checked against each other."""

    arena: Any
    disc: Any
    states_src: str | None
    goal_names: tuple[str, ...]
    goal_masks: NDArray[np.bool_]
    qt: Any
    model: Any
    action_set: Any
    valid: NDArray[np.bool_] | None
    grid: Any
    map_check: Any
    params: Any
    params_source: str
    mcl_params: Any
    mcl_field: Any
    physics_hz: float
    physics_source: str


def _placed_start(arena: Any) -> Any:
    """``arena`` with its start where the robot fits (:func:`simlab.base.statecheck.put_down`,
    warned when moved): the start the replay begins at, drives back to and localizes from.
    An arena's own check asks a disc of ``[start] clearance`` m free, which a lowered
    clearance lets the Burger's 0.10 m tail overlap a box."""
    from simlab.base.statecheck import placed_pose
    from simlab.physics.robot import load_robot_spec

    start = placed_pose(arena.start, arena, load_robot_spec().footprint,
                        what=f"the start pose of arena {arena.name!r}")
    if tuple(start) == tuple(arena.start):
        return arena
    return replace(arena, start=tuple(float(v) for v in start))


def _load_inputs(cfg: ReplayConfig) -> _Inputs:
    """Arena, states, goals, Q-tables, MDP, map and primitive parameters, all checked
    before anything runs (ConfigError naming the file)."""
    from simlab.base.statecheck import check_centres_in_arena
    from simlab.data.goals import goal_state_masks, select_goals
    from simlab.localization.filter import MCLParams
    from simlab.localization.likelihood import LikelihoodField
    from simlab.localization.maps import load_map_for_arena
    from simlab.physics.inputs import load_arena_config, load_discretizer
    from simlab.replay.inputs import (
        discover_mdp,
        load_model,
        load_qtables,
        physics_rate_for,
        primitive_params_for,
    )

    arena_cfg = _placed_start(load_arena_config(cfg.arena))
    disc = load_discretizer(cfg.states)
    states_src = str(cfg.states) if isinstance(cfg.states, str | os.PathLike) else None
    check_centres_in_arena(disc.centres, arena_cfg, source=states_src)
    goal_names, goal_masks = select_goals(goal_state_masks(arena_cfg, disc.centres), cfg.goals,
                                          disc.n_states)
    goal_names = tuple(str(g) for g in goal_names)
    qt = None if cfg.qtables is None else load_qtables(cfg.qtables, goal_names, disc.n_states,
                                                       states_src, action_set=cfg.action_set)
    _check_hashes(disc, qt, None, states_src)  # the Q-tables first: the user's own input
    mdp_source = cfg.mdp if cfg.mdp is not None else (None if qt is None else discover_mdp(qt))
    model = None if mdp_source is None else load_model(
        mdp_source, disc, goal_names, goal_masks,
        action_set=None if qt is None else qt.action_set)
    _check_hashes(disc, None, mdp_source, states_src)
    action_set, valid = _actions_and_mask(qt, model)
    grid, map_check = load_map_for_arena(cfg.map, arena_cfg)
    params, params_source = primitive_params_for(model, cfg.params)
    physics_hz, physics_source = physics_rate_for(model, cfg.physics_hz)
    if cfg.pose_source == "odometry" and params.heading_source != "odometry":
        params = replace(params, heading_source="odometry")
    mcl_params = cfg.mcl_params if cfg.mcl_params is not None else MCLParams()
    field_ = LikelihoodField(grid, mcl_params.sensor) if cfg.pose_source == "mcl" else None
    return _Inputs(arena=arena_cfg, disc=disc, states_src=states_src, goal_names=goal_names,
                   goal_masks=goal_masks, qt=qt, model=model, action_set=action_set,
                   valid=valid, grid=grid, map_check=map_check, params=params,
                   params_source=params_source, mcl_params=mcl_params, mcl_field=field_,
                   physics_hz=physics_hz, physics_source=physics_source)


def _check_hashes(disc: Any, qt: Any, mdp_source: Any, states_src: str | None) -> None:
    """The Q-tables and the MDP file were built on these states."""
    from simlab.base.statecheck import check_states_hash, npz_states_hash

    states_hash = disc.content_hash()
    for i, meta in enumerate(() if qt is None else qt.metadata):
        check_states_hash(meta.get("states_hash"), states_hash, what="the Q-table",
                          path=qt.files[i] or qt.source, against=states_src or "the states")
    if isinstance(mdp_source, str | os.PathLike):
        check_states_hash(npz_states_hash(mdp_source), states_hash, what="the MDP",
                          path=mdp_source, against=states_src or "the states")


def _output_files(cfg: ReplayConfig) -> dict[str, Path]:
    """The output paths, checked (new, or ``overwrite``) before the robot moves."""
    out = Path(cfg.out)
    files = {"summary": out / "replay.json", "plot": out / "cumulative_reward.png",
             "transitions": out / "transitions.parquet"}
    if cfg.pose_source == "mcl":
        files["localization"] = out / "localization.parquet"
    if cfg.video:
        from simlab.replay.video import mp4_available

        files["gif"] = out / "replay.gif"
        if mp4_available():
            files["mp4"] = out / "replay.mp4"
    if out.exists() and not out.is_dir():
        raise ConfigError("output exists and is not a directory", path=out,
                          fix="choose another --out")
    for p in files.values():
        ensure_new(p, overwrite=cfg.overwrite, what="replay output")
    return files


def _plan(cfg: ReplayConfig, inp: _Inputs) -> RunPlan:
    """The run specs and seed streams (``SeedSequence(seed).spawn(5)``) and the schedule."""
    seqs = np.random.SeedSequence(int(cfg.seed)).spawn(5)
    budget = cfg.hours * 3600.0
    params = inp.params
    expected_transitions = budget / (params.decision_latency + 1.5)
    stride = max(1, math.ceil(expected_transitions / cfg.max_frames)) if cfg.video else 0
    baseline_hours = cfg.baseline
    split_baseline, split_mcl = schedule(cfg.parallel, baseline_hours > 0,
                                         cfg.pose_source == "mcl")
    spec = RunSpec(arena=inp.arena, discretizer=inp.disc, goal_masks=inp.goal_masks,
                   Q=None if inp.qt is None else inp.qt.Q, policy=cfg.policy,
                   pose_source=cfg.pose_source, budget=budget, params=params,
                   mcl_field=inp.mcl_field, mcl_params=inp.mcl_params,
                   return_to_start=cfg.return_to_start, retry_blocked=cfg.retry_blocked,
                   escape_radius=cfg.escape_radius, epsilon=cfg.epsilon, frame_stride=stride,
                   primitives=inp.action_set.primitives(), valid=inp.valid,
                   remote_mcl=split_mcl, physics_hz=inp.physics_hz)
    bspec = None
    if baseline_hours > 0:
        bspec = replace(spec, policy="random", pose_source="truth", mcl_field=None,
                        budget=baseline_hours * 3600.0, return_to_start=False, frame_stride=0,
                        params=params if cfg.pose_source != "odometry"
                        else replace(params, heading_source="truth"))
    return RunPlan(spec=spec, seqs=seqs[:4], baseline=bspec, baseline_seqs=seqs[4].spawn(4),
                   hours=cfg.hours, baseline_hours=baseline_hours, progress=cfg.progress,
                   split_baseline=split_baseline)


def _prediction(cfg: ReplayConfig, inp: _Inputs, result: Any) -> dict[str, Any] | None:
    """The MDP's reward rate per policy (:mod:`simlab.replay.prediction`) at the dataset's
    pace (else the replay's), and at the replay's measured pace; None without an MDP."""
    from simlab.replay.prediction import (
        greedy_policy_matrix,
        predict_reward_rate,
        uniform_policy_matrix,
    )

    model, qt, valid = inp.model, inp.qt, inp.valid
    if model is None:
        return None
    if cfg.return_to_start:
        # The chain continues from the state where a goal was reached; driving back to the
        # start (the episodic task, thesis go_back_initial_pose) restarts it elsewhere and
        # spends robot time without transitions: no rate is predicted rather than a wrong one.
        return {"mdp": model.source, "not_predicted": "the MDP's goal-switching chain does "
                "not model the drive back to the start (--return-to-start)"}
    start_state = int(inp.disc.state_of(np.asarray(inp.arena.start[:2])))
    G, S = inp.goal_masks.shape
    measured_pace = result.seconds_per_transition
    pace = model.dataset_seconds_per_transition or measured_pace
    prediction: dict[str, Any] = {
        "mdp": model.source, "start_state": start_state,
        "pace_source": "dataset" if model.dataset_seconds_per_transition
        else "replay (the dataset's pace is unknown)"}
    pols = {"random": np.repeat(uniform_policy_matrix(S, inp.action_set.n_actions)[None], G,
                                axis=0)}
    if qt is not None:
        from simlab.training.heatmap import masked_q

        greedy = np.stack([greedy_policy_matrix(masked_q(q, None if valid is None else valid[i]))
                           for i, q in enumerate(qt.Q)])
        pols["greedy"] = (1.0 - cfg.epsilon) * greedy + cfg.epsilon * pols["random"]
    for name, pol in pols.items():
        if pace is None:
            continue
        horizon = result.transitions if name == cfg.policy else None
        pred = predict_reward_rate(model.T, inp.goal_masks, pol, start_state, pace,
                                   horizon=horizon).as_dict()
        if measured_pace:
            pred["rate_per_hour_at_replay_pace"] = (
                3600.0 * pred["reward_per_transition"] / measured_pace)
        prediction[name] = pred
    return prediction


def _summarize(cfg: ReplayConfig, inp: _Inputs, plan: RunPlan, run: RunOutcome,
               baseline: RunOutcome | None, files: dict[str, Path]) -> ReplaySummary:
    """The typed summary of the runs (see :class:`~simlab.replay.summary.ReplaySummary`)."""
    result = run_stats(run, inp.goal_names)
    base = None if baseline is None else BaselineStats(
        source="physics replay, random policy, truth poses", hours=plan.baseline_hours,
        stats=run_stats(baseline, inp.goal_names))
    prediction = _prediction(cfg, inp, result)
    qt = inp.qt
    return ReplaySummary(
        arena=inp.arena.name, arena_sha256=getattr(inp.arena, "source_sha256", None),
        states={"file": inp.states_src, "n_states": int(inp.disc.n_states),
                "hash": inp.disc.content_hash()},
        qtables=None if qt is None else {"source": qt.source,
                                         "files": [f for f in qt.files if f]},
        mdp=None if inp.model is None else inp.model.source,
        dataset=None if inp.model is None else inp.model.dataset,
        map={"file": None if cfg.map is None else str(cfg.map),
             "kind": "arena geometry (1 cm raster)" if cfg.map is None else "map file",
             "check": None if inp.map_check is None else inp.map_check.as_dict()},
        goal_names=inp.goal_names,
        goal_states={g: [int(s) for s in np.flatnonzero(m)]
                     for g, m in zip(inp.goal_names, inp.goal_masks, strict=True)},
        action_set=inp.action_set.to_json(),
        masked_pairs=None if inp.valid is None else int((~inp.valid).sum()),
        policy=cfg.policy, pose_source=cfg.pose_source, seed=int(cfg.seed), hours=cfg.hours,
        return_to_start=bool(cfg.return_to_start), retry_blocked=bool(cfg.retry_blocked),
        escape_radius=float(cfg.escape_radius), epsilon=float(cfg.epsilon),
        primitive_params=asdict(inp.params), primitive_params_source=inp.params_source,
        primitives_file=None if cfg.primitives is None else str(cfg.primitives),
        physics={**settings_for(inp.physics_hz).to_json(), "source": inp.physics_source},
        mcl_params=asdict(inp.mcl_params) if cfg.pose_source == "mcl" else None,
        schedule=Schedule(plan.split_baseline, plan.spec.remote_mcl),
        result=result, localization=localization_summary(run), random_baseline=base,
        prediction=prediction,
        comparison=comparison(result, base, (prediction or {}).get(cfg.policy)),
        files={k: str(v) for k, v in files.items()},
    )


def _write(cfg: ReplayConfig, inp: _Inputs, files: dict[str, Path], run: RunOutcome,
           baseline: RunOutcome | None, summary: ReplaySummary, video: Any = None) -> None:
    """Every output file, or none (one output transaction). ``video``: the future of the
    video's bytes rendered by a worker (:func:`_start_video`); None: rendered here."""
    from simlab.replay.writers import (
        plot_rewards,
        write_localization,
        write_transitions,
        write_video,
    )

    with output_transaction(Path(cfg.out), files.values(), overwrite=cfg.overwrite,
                            what="replay output") as txn:
        staged = {k: txn.path(v) for k, v in files.items()}
        write_transitions(staged["transitions"], run.log, inp.goal_names)
        if "localization" in staged:
            write_localization(staged["localization"], run.mcl_log)
        plot_rewards(staged["plot"], run, baseline, summary)
        if video is not None:
            for kind, data in video.result().items():
                with atomic_write(staged[kind], "wb") as fh:
                    fh.write(data)
        elif cfg.video:
            write_video(staged, run, inp.arena, inp.disc, inp.qt, inp.goal_names, inp.grid,
                        cfg.max_frames, valid=None if inp.qt is None else _qt_valid(inp.qt))
        atomic_write_json(staged["summary"], summary.to_json())


def _start_video(cfg: ReplayConfig, inp: _Inputs, files: dict[str, Path], run: RunOutcome,
                 pool: Any) -> Any:
    """The video rendered and encoded in ``pool``'s worker (the baseline's, idle once the
    baseline is in) while this process computes the prediction and writes the other files
    at the same time: a future of ``{kind: bytes}``, or None (no video, or no worker: :func:`_write`
    renders it here). Same frames, same bytes (tested)."""
    if not cfg.video or pool is None:
        return None
    from simlab.replay.writers import encode_video

    kinds = tuple(k for k in ("gif", "mp4") if k in files)
    return pool.submit(encode_video, kinds, replace(run, mcl_log=None), inp.arena, inp.disc,
                       inp.qt, inp.goal_names, inp.grid, cfg.max_frames,
                       valid=None if inp.qt is None else _qt_valid(inp.qt))


def _worker(plan: RunPlan, lent: Any = None) -> Any:
    """The baseline's worker process (a context manager of the pool): the caller's
    ``lent`` one (left open), else a fresh one; a null context when the baseline runs
    here."""
    import contextlib

    if not plan.split_baseline or plan.baseline is None:
        return contextlib.nullcontext(None)
    if lent is not None:
        return contextlib.nullcontext(lent)
    from simlab.base.parallel import spawn_worker

    return spawn_worker()  # exits with us, like every simlab worker


@command(ReplayConfig)
def replay(cfg: ReplayConfig) -> ReplayResult:
    """Replay the Q-tables in physics for ``cfg.hours`` of robot time (see the module doc
    and :class:`~simlab.replay.config.ReplayConfig` for every option).

    Takes a :class:`ReplayConfig` or its fields as arguments (``replay("table", states,
    qtables, hours=1.0, ...)``, positional in the config's field order: arena, states,
    qtables, hours, pose_source, seed, out, policy, map, ...).

    Returns:
        :class:`ReplayResult`. Raises :class:`ConfigError` for bad input (naming the file):
        Q-tables of the wrong shape, a goal without a Q-table, an MDP or map of another
        arena or discretizer, missing files, outputs that exist.
    """
    inputs = _load_inputs(cfg)
    files = _output_files(cfg)
    plan = _plan(cfg, inputs)
    with _worker(plan, cfg.pool) as pool:
        run, baseline = run_both(plan, pool)
        video = _start_video(cfg, inputs, files, run, pool)
        summary = _summarize(cfg, inputs, plan, run, baseline, files)
        _write(cfg, inputs, files, run, baseline, summary, video=video)
    return ReplayResult(summary=summary, run=run, baseline=baseline, files=files)


def _qt_valid(qt: Any) -> NDArray[np.bool_] | None:
    return qt.valid if not _trained_self_loop(qt) else None


def _trained_self_loop(qt: Any) -> bool:
    return any(m.get("unvisited") == "self-loop" for m in qt.metadata)


def _actions_and_mask(qt: Any, model: Any) -> tuple[Any, NDArray[np.bool_] | None]:
    """The action set of the replay and the ``(G, S, A)`` mask of its greedy choices.

    The Q-tables' set (else the MDP's, else simlab's 16). The mask: the Q-tables' saved
    ``valid``; for Q-tables without one (older files) the MDP's ``valid`` repeated per
    goal; none for Q-tables trained under the ``self-loop`` rule.
    """
    from simlab.base.actions import SIMLAB16

    if qt is not None:
        action_set = qt.action_set
    else:
        action_set = SIMLAB16 if model is None else model.action_set
    if qt is None or _trained_self_loop(qt):
        return action_set, None
    if qt.valid is not None:
        return action_set, qt.valid
    if model is not None and model.valid is not None:
        return action_set, np.repeat(model.valid[None], qt.Q.shape[0], axis=0)
    return action_set, None
