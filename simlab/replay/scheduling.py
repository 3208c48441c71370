"""Where the replay's runs execute: this process, a process for the random
baseline, a process for the ``mcl`` filter; and the progress bars.

Results never depend on the choice: the worlds and seed streams are independent, so a
split run is the sequential one, bit for bit (tested).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from simlab.replay.loop import RunOutcome, RunSpec, run

__all__ = ["RunPlan", "run_both", "schedule", "usable_cores"]


def usable_cores() -> int:
    """CPUs this process may run on (its affinity mask; ``os.cpu_count()`` elsewhere)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def schedule(parallel: bool, baseline: bool, mcl: bool,
             cores: int | None = None) -> tuple[bool, bool]:
    """``(baseline in a process, mcl filter in a process)`` for a replay on ``cores``
    usable CPUs (None: :func:`usable_cores`).

    Decided from the core count, as the dataset's walks are: with ``parallel`` and 2 or more
    cores the random baseline gets a process of its own (it talks to this one once, at the
    end). The filter (fed scan by scan; the robot waits for it only at decisions and video
    frames) gets one only on 3 or more cores, where it has a core of its own beside the
    learned run and the baseline. On 2 it runs in this process, because a process sharing
    a core costs more than it overlaps: every scan crosses a pipe (pickled both ways, ~0.8 s
    of sends and ~1.2 s of waits at decisions per 3-hour replay). Measured on the shared
    2-core VM, a 3-hour mcl replay with video, runs in turn: with its baseline, quiet (load
    0.1-0.8) 9.6-9.7 s wall and 15.8 s CPU with the filter here against 11.3-12.0 s and
    19.0 s with it in a third process, and beside four busy processes (load 5.5)
    30.4-32.2 s against 32.7-35.1 s; without a baseline (the filter alone beside the run)
    a tie on the wall, 11.9-12.9 s against 11.9-12.2 s, for 2 s more CPU. (An earlier
    round had measured the third process winning at load 12-13, 36-47 s against 46-48 s
    for a 1-hour replay.)

    Cheaper messages do not change this on two cores. Scans sent as raw bytes on a pipe the
    filter does not sleep on (it reads them every 0.5 ms and before each question), so a
    send neither pickles nor wakes it, cut the robot's own CPU from 9.3-10.2 s to 8.0-8.5 s,
    but the wall was 10.9-12.1 s with the baseline against 9.5-10.6 s with the filter here
    (the baseline's process and the filter's then share one core: 10 s of CPU there, and
    the scan pipe fills), and 9.9-10.0 s against 9.7-9.8 s without a baseline: at every
    decision the robot still waits for the filter's last update (~0.4 ms, 1.1 s per
    replay), the one the decision needs. Results do not depend on the choice
    (bit-identical, tested).
    """
    n = usable_cores() if cores is None else int(cores)
    if not parallel or n < 2:
        return False, False
    return bool(baseline), bool(mcl) and n >= 3


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
