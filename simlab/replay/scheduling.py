"""Where the replay's runs execute: this process, a process for the random
baseline, a process for the ``mcl`` filter; and the progress bars.

Results never depend on the choice: the worlds and seed streams are independent, so a
split run is the sequential one, bit for bit (tested).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from simlab.replay.loop import RunOutcome, RunSpec, run

__all__ = ["RunPlan", "idle_cores", "run_both", "schedule", "shares_per_session",
           "usable_cores"]


def usable_cores() -> int:
    """CPUs this process may run on (its affinity mask; ``os.cpu_count()`` elsewhere)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def idle_cores(window: float = 0.25) -> float:
    """CPUs idle right now, as seen by this process: ``usable_cores()`` times the idle
    share of ``/proc/stat`` over ``window`` seconds (this process sleeps meanwhile, so
    a quiet 2-core machine reads ~2). Without ``/proc/stat``: ``usable_cores()``.
    (:func:`schedule` reads it only where the CPUs are shared per session.)"""

    def sample() -> tuple[int, int]:
        with open("/proc/stat") as fh:
            values = [int(v) for v in fh.readline().split()[1:]]
        return values[3] + values[4], sum(values)  # idle + iowait, total

    try:
        idle0, total0 = sample()
        time.sleep(window)
        idle1, total1 = sample()
    except (OSError, ValueError, IndexError):  # pragma: no cover - not Linux
        return float(usable_cores())
    if total1 <= total0:
        return float(usable_cores())
    return usable_cores() * (idle1 - idle0) / (total1 - total0)


def shares_per_session() -> bool:
    """True when Linux shares the CPUs per session (``sched_autogroup_enabled``: each
    session's processes share one scheduling group, so a second process of this session
    gets no more CPU while other sessions keep the cores busy)."""
    try:
        with open("/proc/sys/kernel/sched_autogroup_enabled") as fh:
            return fh.read().strip() == "1"
    except OSError:  # not Linux, or no autogroup support: shares per process
        return False


def schedule(parallel: bool, baseline: bool, mcl: bool,
             cores: int | None = None) -> tuple[bool, bool]:
    """``(baseline in a process, mcl filter in a process)`` for a replay on ``cores``
    usable CPUs (None: :func:`usable_cores`).

    Decided from the core count wherever the scheduler shares the CPUs per
    process: with ``parallel`` and 2 cores the random baseline gets a process of its own
    (it talks to this one once, at the end, so on a busy machine it costs its start-up,
    ~1 s, and otherwise takes the CPU share of a second runnable process), and the filter
    one when a third core is there for it (with no baseline: a second; it is fed scan by
    scan, so it needs a core of its own).

    Where Linux shares the CPUs per *session* (:func:`shares_per_session`, autogroup, the
    default of desktop kernels and of this project's shared box) a second process of this
    session gains nothing while other sessions keep the cores busy: measured on 2 cores
    at load 4-5, the split replay took 18-26 s against 17-36 s in one process, its
    learned run twice as long. There the cores must be idle to be ours, and the rule is
    the count of idle cores (:func:`idle_cores`, 0.25 s sample; the replay's own earlier
    stages have ended by then): the baseline process from 1.5 idle cores, the filter's
    from another 1 (with no baseline: 1.5). Results do not depend on the choice
    (bit-identical, tested).
    """
    n = usable_cores() if cores is None else int(cores)
    if not parallel or n < 2 or not (baseline or mcl):
        return False, False
    free = idle_cores() if shares_per_session() else float(n)
    split_baseline = bool(baseline) and free >= 1.5
    split_mcl = bool(mcl) and free >= (2.5 if split_baseline else 1.5)
    return split_baseline, split_mcl


@dataclass(frozen=True)
class RunPlan:
    """The main run and the optional random baseline: their specs and seed streams, the
    hours shown by the progress bars, and whether the baseline gets a process."""

    spec: RunSpec
    seqs: list[np.random.SeedSequence]
    baseline: RunSpec | None
    baseline_seqs: list[np.random.SeedSequence]
    hours: float
    baseline_hours: float
    progress: bool
    split_baseline: bool

    @property
    def label(self) -> str:
        return f"replay {self.spec.policy} ({self.spec.pose_source}"


def _bar(total: float, desc: str, progress: bool) -> Any:
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=desc, unit="robot-h", disable=not progress,
                dynamic_ncols=True, bar_format="{l_bar}{bar}| {n:.2f}/{total:.2f} robot-h "
                                               "[{elapsed}<{remaining}{postfix}]")


def _run_quiet(spec: RunSpec, seqs: list[np.random.SeedSequence],
               warm_video: bool = False) -> RunOutcome:
    """:func:`~simlab.replay.loop.run` without a progress bar (the baseline process);
    ``warm_video``: then import the video's modules, while the main run is still going,
    for the video job that follows in this process."""
    outcome = run(spec, seqs)
    if warm_video:
        from PIL import GifImagePlugin, Image  # noqa: F401

        import simlab.replay.video
        import simlab.replay.writers  # noqa: F401
    return outcome


def run_both(plan: RunPlan, pool: Any = None) -> tuple[RunOutcome, RunOutcome | None]:
    """The main run (in this process) and the random baseline (None: none).

    With ``plan.split_baseline`` (see :func:`schedule`) the baseline runs in a ``spawn``
    process (no PyBullet client or lock of this process is inherited) while this one
    drives the main run: the two worlds share nothing and each draws from its own
    seed streams, so the outcome is the sequential one, bit for bit (tested); the
    replay's wall time becomes that of the longer run instead of their sum. ``pool``: the
    one-process pool to use (:func:`simlab.base.parallel.spawn_worker`, left open for the
    caller's later jobs, e.g. the video); None: one of its own, closed on return.
    """
    if plan.baseline is None or not plan.split_baseline:
        with _bar(plan.hours, plan.label + ")", plan.progress) as bar:
            main = run(plan.spec, plan.seqs, bar)
        if plan.baseline is None:
            return main, None
        with _bar(plan.baseline_hours, "replay random baseline", plan.progress) as bar:
            return main, run(plan.baseline, plan.baseline_seqs, bar)
    if pool is None:
        from simlab.base.parallel import spawn_worker

        with spawn_worker() as own:  # exits with us, like every simlab worker
            return run_both(plan, own)
    future = pool.submit(_run_quiet, plan.baseline, plan.baseline_seqs,
                         bool(plan.spec.frame_stride))
    with _bar(plan.hours, plan.label + "; random baseline in parallel)", plan.progress) as bar:
        main = run(plan.spec, plan.seqs, bar)
    return main, future.result()
