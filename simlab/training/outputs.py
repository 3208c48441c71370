"""The files of ``simlab train``: which it writes (:func:`output_files`), which a previous
run wrote that ``--overwrite`` retires (:func:`previous_outputs`), and the writing of the
Q-tables, curves, figures and ``summary.json`` (:func:`write_outputs`); their contents are
listed in :mod:`simlab.training.train`'s module docstring.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np

from simlab.base.io import atomic_write_bytes, atomic_write_json
from simlab.training.config import TrainTask
from simlab.training.loop import TrainJob, TrainResults, heatmap_scene

__all__ = ["output_files", "previous_outputs", "run_metadata", "write_outputs"]


#: Names of the files a train run writes per goal or per figure (see :func:`output_files`):
#: only files of these names, listed by the previous run's summary.json, are retired.
_OWN_PATTERNS = ("q_*.npz", "heatmap_*.png", "heatmaps.png", "curves.png")


def previous_outputs(out: Path, now: Any) -> list[Path]:
    """Files the previous ``train`` into ``out`` wrote (its ``summary.json`` lists them) that
    this run does not write again: the Q-tables and heat maps of goals no longer trained.
    ``--overwrite`` replaces them too, so that ``replay`` of ``out`` (every ``q_*.npz``)
    never picks up a stale goal. Files ``train`` did not write are never touched."""
    import json

    try:
        listed = json.loads((out / "summary.json").read_text(encoding="utf-8"))["files"]
        names = {Path(str(v)).name for v in listed.values()}
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return []  # no summary of ours: nothing is known to be ours
    keep = {Path(p).name for p in now}
    return [out / n for n in sorted(names - keep)
            if any(Path(n).match(pat) for pat in _OWN_PATTERNS) and (out / n).is_file()]


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name)


def output_files(out: Any, names: list[str], plots: bool, centres: bool) -> dict[str, Path]:
    """Every file :func:`simlab.training.train.train` writes into ``out``, by role."""
    out = Path(out)
    files = {f"q_{g}": out / f"q_{_slug(g)}.npz" for g in names}
    files["curves"] = out / "curves.npz"
    files["summary"] = out / "summary.json"
    if plots:
        files["curves_png"] = out / "curves.png"
        if centres:
            files["heatmaps"] = out / "heatmaps.png"
            for g in names:
                files[f"heatmap_{g}"] = out / f"heatmap_{_slug(g)}.png"
    return files


def run_metadata(job: TrainJob) -> dict[str, Any]:
    """What every output records of the run: budget, seed, start, states fingerprint, gamma
    and the task (:func:`_task_meta`)."""
    cfg = job.cfg
    return dict(seed=cfg.seed, episodes=cfg.episodes, runs=cfg.runs, horizon=cfg.horizon,
                start=_start_meta(job.start), states_hash=job.states_hash, gamma=job.gamma,
                **_task_meta(job.m, cfg.task, job.valid))


def _start_meta(start: Any) -> int | None:
    """The fixed start state for the metadata (start states are in ``task``)."""
    return int(start) if isinstance(start, int | np.integer) else None


def _task_meta(m: Any, task: TrainTask, valid: np.ndarray | None) -> dict[str, Any]:
    """The task metadata of every Q-table: action set, unvisited rule, task."""
    return {
        "action_set": None if m.action_set is None else m.action_set.to_json(),
        "unvisited": m.unvisited,
        "masked_pairs": 0 if valid is None else int((~valid).sum()),
        "task": task.as_dict(),
    }


def write_outputs(job: TrainJob, res: TrainResults, files: dict[str, Path],
                   run_meta: dict[str, Any]) -> None:
    """Write the Q-tables, curves, figures and summary to ``files`` (staged paths)."""
    import simlab
    from simlab.agents.storage import save_q_table

    m, names, agent = job.m, job.names, job.cfg.agent
    source = None if m.source is None else str(m.source)
    for g in names:
        runs = res.runs[g]
        arrays = {"Q_runs": runs.Q_runs, "Q_star": res.evaluations[g].Q_star,
                  "goal_mask": m.goal_mask(g)}  # fmt: skip
        arrays.update(runs.extra)
        if m.valid is not None:
            arrays["valid"] = m.valid
        meta = {"agent": agent, "config": res.config, "goal": g, "goal_index": m.goal_index(g),
                "mdp": source, "mdp_resolved": None if source is None
                else str(Path(source).resolve()), "Q": "mean over runs of the final Q-tables",
                "simlab_version": simlab.__version__, **run_meta}  # fmt: skip
        save_q_table(files[f"q_{g}"], res.Qs[g], metadata=meta, arrays=arrays, overwrite=True)

    import json

    from simlab.base.io import atomic_write

    curve_rows = res.curve_rows
    with atomic_write(files["curves"], "wb") as fh:
        np.savez_compressed(
            fh, rewards=res.rewards, goal_names=np.array(names), curve_x=curve_rows[0][0],
            curve_mean=np.stack([r[1] for r in curve_rows]),
            curve_std=np.stack([r[2] for r in curve_rows]),
            optimal_return=np.array([s.optimal_return for s in res.summaries]),
            meta_json=np.array(json.dumps({"agent": agent, "config": res.config,
                                           **run_meta})),
        )  # fmt: skip
    if job.cfg.plots:
        _write_figures(job, res, files, run_meta["runs"])
    summary = {
        "agent": agent,
        "config": res.config,
        "mdp": source,
        **run_meta,
        "goals": {s.goal: s.as_dict() for s in res.summaries},
        "files": {k: str(v) for k, v in job.files.items()},
    }
    atomic_write_json(files["summary"], summary)


def _write_figures(job: TrainJob, res: TrainResults, files: dict[str, Path], runs: int) -> None:
    """The learning curves and, with centres, the Q heat maps.

    With ``job.pool`` the pool draws the curves (unless it has not started them when this
    process is done with the grid) while this process draws the grid; the per-goal heat
    maps come ready from :func:`train_goals_shared` (``res.pngs``).
    """
    from simlab.training.curves import render_learning_curves, save_learning_curves

    m, agent = job.m, job.cfg.agent
    panels = [(f"{s.goal}: final {s.final_mean_reward:.1f} / optimal {s.optimal_return:.1f}",
               {agent: res.runs[s.goal].rewards}, s.optimal_return) for s in res.summaries]  # fmt: skip
    suptitle = f"{agent}, {runs} runs, mean and std per block"
    curves = None
    if job.pool is None:
        save_learning_curves(files["curves_png"], panels, suptitle=suptitle)
    else:
        curves = job.pool.submit(render_learning_curves, panels, suptitle=suptitle)
    if m.centres is not None:
        _write_heatmaps(job, res, files)
    if curves is not None and curves.cancel():  # the pool is busy elsewhere: draw it here
        save_learning_curves(files["curves_png"], panels, suptitle=suptitle)
    elif curves is not None:
        atomic_write_bytes(files["curves_png"], curves.result())


def _write_heatmaps(job: TrainJob, res: TrainResults, files: dict[str, Path]) -> None:
    """The per-goal heat maps (drawn here unless ``res.pngs`` has them) and the grid."""
    from simlab.training.heatmap import save_heatmap_grid, save_q_heatmap

    m, names, agent = job.m, job.names, job.cfg.agent
    scene = heatmap_scene(job)
    masks = [m.goal_mask(g) for g in names]
    for g, mask in zip(names, masks, strict=True):
        if g in res.pngs:
            atomic_write_bytes(files[f"heatmap_{g}"], res.pngs[g])
            continue
        save_q_heatmap(files[f"heatmap_{g}"], scene, res.Qs[g], mask,
                       title=f"{agent}: goal {g}")
    save_heatmap_grid(files["heatmaps"], scene, [res.Qs[g] for g in names], masks, names,
                      suptitle=f"max_a Q(s, a) and argmax arrows, {agent}")
