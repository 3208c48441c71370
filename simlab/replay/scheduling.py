"""Where the replay's runs execute (issue 17): this process, a process for the random
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

__all__ = ["RunPlan", "idle_cores", "run_both", "schedule", "usable_cores"]


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
    (A measurement for callers and benchmarks; :func:`schedule` no longer reads it.)"""

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


def schedule(parallel: bool, baseline: bool, mcl: bool,
             cores: int | None = None) -> tuple[bool, bool]:
    """``(baseline in a process, mcl filter in a process)`` for a replay on ``cores``
    usable CPUs (None: :func:`usable_cores`).

    Decided from the core count, not the momentary load (issue 17): with ``parallel``
    and 2 cores the random baseline gets a process of its own, and the filter one when
    a third core is there for it (with no baseline: a second). The load does not enter
    because a load sample is a guess about the next minutes on a shared machine, and a
    wrong "busy" guess runs two independent worlds one after the other, doubling the
    stage's wall time; the baseline process talks to this one once (its outcome at the
    end), so on a busy machine it costs its start-up (~1 s) and otherwise takes the fair
    CPU share of a second runnable process. The filter process is fed scan by scan, so
    it needs a core of its own, and only gets one it can have. (The old rule, 1.5 idle
    cores sampled over 0.25 s, ran the two worlds sequentially whenever another job
    was running, e.g. in every pipeline whose warm-up was still compiling.) Results do not
    depend on the choice (bit-identical, tested).
    """
    n = usable_cores() if cores is None else int(cores)
    if not parallel or n < 2 or not (baseline or mcl):
        return False, False
    split_baseline = bool(baseline)
    split_mcl = bool(mcl) and n >= (3 if split_baseline else 2)
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


def _run_quiet(spec: RunSpec, seqs: list[np.random.SeedSequence]) -> RunOutcome:
    """:func:`~simlab.replay.loop.run` without a progress bar (the baseline process)."""
    return run(spec, seqs)


def run_both(plan: RunPlan, pool: Any = None) -> tuple[RunOutcome, RunOutcome | None]:
    """The main run (in this process) and the random baseline (None: none).

    With ``plan.split_baseline`` (see :func:`schedule`) the baseline runs in a ``spawn``
    process (no PyBullet client or lock of this process is inherited) while this one
    drives the main run: the two worlds share nothing and each draws from its own
    seed streams, so the outcome is the sequential one, bit for bit (tested); the
    replay's wall time becomes that of the longer run instead of their sum. ``pool``: the
    one-process pool to use (:func:`simlab.parallel.spawn_worker`, left open for the
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
        from simlab.parallel import spawn_worker

        with spawn_worker() as own:  # exits with us, like every simlab worker
            return run_both(plan, own)
    future = pool.submit(_run_quiet, plan.baseline, plan.baseline_seqs)
    with _bar(plan.hours, plan.label + "; random baseline in parallel)", plan.progress) as bar:
        main = run(plan.spec, plan.seqs, bar)
    return main, future.result()
