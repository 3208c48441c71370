"""The replay's output files: ``transitions.parquet``, ``localization.parquet``,
``cumulative_reward.png`` and the video (each written atomically to the path given; the
command stages them in one output transaction)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from simlab.base.io import atomic_write
from simlab.replay.loop import ReplayLog, RunOutcome
from simlab.replay.summary import ReplaySummary

__all__ = ["encode_video", "plot_rewards", "write_localization", "write_transitions",
           "write_video"]

_AXES = ("x", "y", "yaw")


def _write_parquet(path: Path, cols: dict[str, Any]) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.table({k: pa.array(np.asarray(v) if not isinstance(v, np.ndarray) else v)
                      for k, v in cols.items()})
    with atomic_write(path, "wb") as fh:
        pq.write_table(table, fh)


def write_transitions(path: Path, log: ReplayLog, goal_names: tuple[str, ...]) -> None:
    """One row per transition (the columns of :class:`~simlab.replay.loop.ReplayLog`,
    poses split into ``x_<prefix>``, ``y_<prefix>``, ``yaw_<prefix>``, goals by name)."""
    cols: dict[str, Any] = {
        "t": log.t, "duration": log.duration, "s": log.s, "a": log.a, "s_next": log.s_next,
        "goal": np.asarray(goal_names, dtype=object)[log.goal] if log.n else np.array([], str),
        "reward": log.reward, "blocked": log.blocked, "s_true_next": log.s_true_next,
    }
    for prefix, arr in (("true", log.truth_before), ("true_next", log.truth_after),
                        ("est", log.est_before), ("est_next", log.est_after),
                        ("odom_next", log.odom_after)):
        for i, axis in enumerate(_AXES):
            cols[f"{axis}_{prefix}"] = arr[:, i]
    _write_parquet(path, cols)


def write_localization(path: Path, mcl_log: Any) -> None:
    """One row per filter update of the ``mcl`` pose source."""
    cols: dict[str, Any] = {"t": mcl_log.t}
    for prefix, arr in (("true", mcl_log.truth), ("est", mcl_log.estimate)):
        for i, axis in enumerate(_AXES):
            cols[f"{axis}_{prefix}"] = arr[:, i]
    cols["position_error"] = mcl_log.position_error
    cols["heading_error"] = mcl_log.heading_error
    cols["position_std"] = mcl_log.spread[:, 0]
    cols["heading_std"] = mcl_log.spread[:, 1]
    cols["fit"] = mcl_log.fit
    cols["injected"] = mcl_log.injected
    _write_parquet(path, {k: np.asarray(v) for k, v in cols.items()})


def plot_rewards(path: Path, run: RunOutcome, baseline: RunOutcome | None,
                 summary: ReplaySummary) -> None:
    """Cumulative reward of the run, the baseline and the MDP-predicted rates (Fig. 4.10)."""
    from simlab.replay.plots import RewardCurve, plot_cumulative_reward

    policy = summary.policy
    curves = [RewardCurve(f"{policy} policy ({summary.pose_source}): "
                          f"{summary.result.rate_per_hour:.1f} /h",
                          run.log.reward_times, run.robot_seconds)]
    if baseline is not None and summary.random_baseline is not None:
        curves.append(RewardCurve(f"random policy (physics): "
                                  f"{summary.random_baseline.rate_per_hour:.1f} /h",
                                  baseline.log.reward_times, baseline.robot_seconds))
    predicted = []
    pred = summary.prediction or {}
    for name in (policy, "random") if policy == "greedy" else (policy,):
        if name in pred:
            predicted.append((f"MDP-predicted, {name}: {pred[name]['rate_per_hour']:.1f} /h",
                              pred[name]["rate_per_hour"]))
    plot_cumulative_reward(path, curves, predicted, hours=summary.hours,
                           title=f"{summary.arena}: cumulative reward over "
                                 f"{summary.hours:g} h of robot time")


def write_video(files: dict[str, Path], run: RunOutcome, arena: Any, disc: Any, qt: Any,
                goal_names: tuple[str, ...], grid: Any, max_frames: int,
                valid: Any = None) -> None:
    """``replay.gif`` (and ``replay.mp4`` when in ``files``): at most ``max_frames`` frames
    of the map, the current goal's values (``qt``; ``valid`` its drawn mask), the robot
    and its trail."""
    from simlab.physics.robot import load_robot_spec
    from simlab.replay.video import ReplayCanvas
    from simlab.replay.video import write_video as write_frames

    canvas = ReplayCanvas(arena, load_robot_spec(), disc.centres, None if qt is None else qt.Q,
                          goal_names, grid, action_set=None if qt is None else qt.action_set,
                          valid=valid)
    trail = np.vstack([run.log.truth_before[:1], run.log.truth_after]) if run.log.n else \
        np.asarray(arena.start, dtype=np.float64)[None]
    records = run.frames
    if len(records) > max_frames:  # the stride was set from an estimate: thin evenly
        keep = np.unique(np.linspace(0, len(records) - 1, max_frames).round().astype(int))
        records = [records[i] for i in keep]
    frames = [canvas.render(f, trail) for f in records]
    if not frames:
        return
    write_frames(files["gif"], frames)
    if "mp4" in files:
        write_frames(files["mp4"], frames)


def encode_video(kinds: tuple[str, ...], run: RunOutcome, arena: Any, disc: Any, qt: Any,
                 goal_names: tuple[str, ...], grid: Any, max_frames: int,
                 valid: Any = None) -> dict[str, bytes]:
    """:func:`write_video` into a temporary folder, returning the files' bytes per kind
    (``"gif"``, ``"mp4"``; a kind without frames is absent): the job a worker process
    runs while the replay's own process writes its other outputs; the bytes
    are those :func:`write_video` writes."""
    import tempfile

    with tempfile.TemporaryDirectory(prefix="simlab-video-") as tmp:
        files = {k: Path(tmp) / f"replay.{k}" for k in kinds}
        write_video(files, run, arena, disc, qt, goal_names, grid, max_frames, valid=valid)
        return {k: p.read_bytes() for k, p in files.items() if p.exists()}
