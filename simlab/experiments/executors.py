"""Where ``ctx.map`` runs its jobs: a local process pool or Ray tasks.

Both run ``fn(**kwargs)`` for each job and return the results in job order, so a
deterministic ``fn`` gives the same list on either backend. The local pool uses the
``spawn`` start method (no PyBullet client, thread or lock of the driver is inherited)
and is created on the first map with more than one job, then reused by every experiment
of the run (process start-up and imports are paid once). A map of a single job, or a
pool of one worker, runs in the driver process.
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
from collections.abc import Callable, Sequence
from typing import Any

from simlab.errors import ConfigError
from simlab.raycluster import check_address, connect_ray

BACKENDS = ("local", "ray")


#: Seconds between two checks of a worker's parent (the longest an orphan lives).
PARENT_POLL_SECONDS = 0.5


def _watch_parent(parent_pid: int, interval: float) -> None:
    import time

    while os.getppid() == parent_pid:
        time.sleep(interval)
    os._exit(1)  # the parent died (SIGKILL, OOM killer): nobody will read our results


def exit_with_parent(parent_pid: int, interval: float = PARENT_POLL_SECONDS) -> None:
    """Process-pool initializer: end this worker as soon as ``parent_pid`` dies.

    A SIGKILL of the driver (``collect``, ``pipeline``, ``reproduce``) gives its workers no
    chance to be told; without this they run (and hold ~190 MB each) forever. Decision:
    a daemon thread polling ``os.getppid()`` (portable to every POSIX, and unlike
    ``PR_SET_PDEATHSIG`` not fooled by the death of the *thread* that spawned the worker);
    the worker exits within ``interval`` seconds of its parent.
    """
    import threading

    if os.getppid() != parent_pid:
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent_pid, interval), daemon=True,
                     name="simlab-parent-watchdog").start()


def worker_pool(processes: int) -> cf.ProcessPoolExecutor:
    """The ONE way simlab starts local worker processes: ``spawn`` context (no PyBullet
    client, thread or lock of the parent inherited) and :func:`exit_with_parent`."""
    return cf.ProcessPoolExecutor(max_workers=processes,
                                  mp_context=multiprocessing.get_context("spawn"),
                                  initializer=exit_with_parent, initargs=(os.getpid(),))


def _call(fn: Callable[..., Any], kwargs: dict[str, Any]) -> Any:
    return fn(**kwargs)


class _Bar:
    def __init__(self, total: int, desc: str | None, enabled: bool) -> None:
        self._bar = None
        if enabled and total > 1:
            from tqdm.auto import tqdm

            self._bar = tqdm(total=total, desc=desc or "jobs", unit="job", dynamic_ncols=True,
                             leave=False)

    def update(self) -> None:
        if self._bar is not None:
            self._bar.update(1)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


class LocalExecutor:
    """A process pool of ``workers`` processes (default: the machine's cores)."""

    name = "local"

    def __init__(self, workers: int | None = None) -> None:
        if workers is None:
            workers = os.cpu_count() or 1
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise ConfigError(f"expected a whole number >= 1, got {workers!r}", key="workers")
        self.workers = workers
        self._pool: cf.ProcessPoolExecutor | None = None

    def map(self, fn: Callable[..., Any], kwargs_list: Sequence[dict[str, Any]], *,
            desc: str | None = None, progress: bool = False) -> list[Any]:
        jobs = list(kwargs_list)
        bar = _Bar(len(jobs), desc, progress)
        try:
            if len(jobs) <= 1 or self.workers == 1:
                out = []
                for kw in jobs:
                    out.append(fn(**kw))
                    bar.update()
                return out
            if self._pool is None:
                self._pool = worker_pool(self.workers)
            futures = [self._pool.submit(_call, fn, kw) for kw in jobs]
            try:
                for _ in cf.as_completed(futures):
                    bar.update()
                return [f.result() for f in futures]
            except BaseException:
                for f in futures:
                    f.cancel()
                raise
        finally:
            bar.close()

    def describe(self) -> str:
        return f"local ({self.workers} worker{'s' if self.workers != 1 else ''})"

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


class RayExecutor:
    """Ray tasks (one CPU each).

    Connects to ``address`` when given; otherwise reuses a Ray runtime this process
    already initialized, or starts a local one (shut down again by :meth:`close`).
    """

    name = "ray"

    def __init__(self, address: str | None = None) -> None:
        self._ray, self._owns = connect_ray(address)
        self._remote = self._ray.remote(num_cpus=1)(_call)
        self.workers = int(self._ray.cluster_resources().get("CPU", 1))

    def map(self, fn: Callable[..., Any], kwargs_list: Sequence[dict[str, Any]], *,
            desc: str | None = None, progress: bool = False) -> list[Any]:
        jobs = list(kwargs_list)
        if not jobs:
            return []
        bar = _Bar(len(jobs), desc, progress)
        try:
            fn_ref = self._ray.put(fn)
            refs = [self._remote.remote(fn_ref, kw) for kw in jobs]
            pending = list(refs)
            while pending:
                done, pending = self._ray.wait(pending, num_returns=1)
                for _ in done:
                    bar.update()
            return self._ray.get(refs)
        finally:
            bar.close()

    def describe(self) -> str:
        return f"ray ({self.workers} CPUs)"

    def close(self) -> None:
        if self._owns:
            self._ray.shutdown()
            self._owns = False


Executor = LocalExecutor | RayExecutor


def make_executor(backend: str = "local", *, workers: int | None = None,
                  address: str | None = None) -> Executor:
    """The executor of ``backend`` (``"local"`` or ``"ray"``)."""
    check_address(backend, address)
    if backend == "local":
        return LocalExecutor(workers)
    if backend == "ray":
        if workers is not None:
            raise ConfigError("--workers applies to the local backend only (Ray uses its "
                              "cluster's CPUs)", key="workers")
        return RayExecutor(address)
    raise ConfigError(f"unknown backend {backend!r}", key="backend",
                      fix=f"choose one of {', '.join(BACKENDS)}")
