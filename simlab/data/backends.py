"""Where parts run: in this process, in a local process pool, or as Ray tasks.

Every backend runs the same function, :func:`simlab.data.walkers.run_part`, on the
same :class:`~simlab.data.walkers.PartJob`, and a part's rows depend only on its job;
so the data are identical on every backend. The driver keeps at most one part per
worker in flight (part ``p + 1`` starts from the end of part ``p``).

Workers send their rows back to the driver, which alone writes files: a Ray cluster
needs no shared file system.
"""

from __future__ import annotations

import concurrent.futures as cf
from typing import Any, Protocol

from simlab.data.walkers import PartJob, PartResult, WalkerCache, run_part
from simlab.errors import ConfigError
from simlab.raycluster import check_address, connect_ray

BACKENDS = ("local", "ray")


class Backend(Protocol):
    """Runs part jobs; ``wait`` blocks until at least one submitted job is finished."""

    def submit(self, job: PartJob) -> Any: ...

    def wait(self, handles: list[Any]) -> list[tuple[Any, PartResult]]: ...

    def close(self) -> None: ...


class InProcessBackend:
    """Runs each job immediately in this process (``workers == 1``; handy in tests)."""

    def __init__(self) -> None:
        self._cache = WalkerCache()
        self._done: dict[int, PartResult] = {}
        self._next = 0

    def submit(self, job: PartJob) -> int:
        handle = self._next
        self._next += 1
        self._done[handle] = run_part(job, self._cache)
        return handle

    def wait(self, handles: list[int]) -> list[tuple[int, PartResult]]:
        return [(h, self._done.pop(h)) for h in handles]

    def close(self) -> None:
        self._cache.close()


class ProcessPoolBackend:
    """A :class:`concurrent.futures.ProcessPoolExecutor` with the ``spawn`` context.

    ``spawn`` (not ``fork``) so that no PyBullet client, thread or lock of the parent
    is inherited; each process builds its own world on its first part and keeps it.
    """

    def __init__(self, processes: int) -> None:
        from simlab.experiments.executors import worker_pool

        self._pool = worker_pool(processes)  # spawn; workers exit when this process dies

    def submit(self, job: PartJob) -> cf.Future[PartResult]:
        return self._pool.submit(run_part, job)

    def wait(self, handles: list[cf.Future[PartResult]]) -> list[tuple[Any, PartResult]]:
        done, _ = cf.wait(handles, return_when=cf.FIRST_COMPLETED)
        return [(f, f.result()) for f in handles if f in done]

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)


class RayBackend:
    """The same worker function as Ray tasks (one CPU each).

    Connects to ``address`` (an existing cluster, e.g. ``"ray://head:10001"`` or
    ``"auto"``) when given; otherwise reuses a Ray runtime this process already
    initialized, or starts a local one (shut down again by :meth:`close`). Ray is
    imported only here (the ``ray`` extra).
    """

    def __init__(self, address: str | None = None) -> None:
        self._ray, self._owns_runtime = connect_ray(address)
        self._remote = self._ray.remote(num_cpus=1)(run_part)

    def submit(self, job: PartJob) -> Any:
        return self._remote.remote(job)

    def wait(self, handles: list[Any]) -> list[tuple[Any, PartResult]]:
        ready, _ = self._ray.wait(handles, num_returns=1)
        return [(ref, self._ray.get(ref)) for ref in ready]

    def close(self) -> None:
        if self._owns_runtime:
            self._ray.shutdown()


def make_backend(name: str, workers: int, address: str | None = None) -> Backend:
    """The backend ``name`` for ``workers`` concurrent walks.

    ``local`` with one worker runs in this process; with more it uses a process pool of
    ``workers`` processes (one arena per process).
    """
    check_address(name, address)
    if name == "local":
        return InProcessBackend() if workers == 1 else ProcessPoolBackend(workers)
    if name == "ray":
        return RayBackend(address)
    raise ConfigError(f"unknown backend {name!r}", key="backend",
                      fix=f"choose one of {', '.join(BACKENDS)}")
