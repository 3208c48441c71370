"""Where the parts of a random walk run: the collection's jobs on :mod:`simlab.base.parallel`.

Every executor runs the same function, :func:`simlab.data.walkers.run_part`, on the
same :class:`~simlab.data.walkers.PartJob`, and a part's rows depend only on its job;
so the data are identical on every backend. The driver keeps at most one part per
worker in flight (part ``p + 1`` starts from the end of part ``p``). This module only
binds the part function to the parallel layer (it has no pool or Ray code of its own);
in this process the walkers live in a :class:`~simlab.data.walkers.WalkerCache` closed
with the backend, in a worker process in that process's cache.
"""

from __future__ import annotations

from typing import Any

from simlab.base.parallel import BACKENDS, Executor, make_executor
from simlab.data.walkers import PartJob, PartResult, WalkerCache, run_part

__all__ = ["BACKENDS", "PartBackend", "make_backend"]


class PartBackend:
    """Runs part jobs on an executor; ``wait`` blocks until at least one is finished."""

    def __init__(self, executor: Executor) -> None:
        self.executor = executor
        self._cache = WalkerCache() if executor.name == "in-process" else None

    def submit(self, job: PartJob) -> Any:
        if self._cache is not None:  # an unpicklable cache: in this process only
            return self.executor.submit(run_part, job, self._cache)
        return self.executor.submit(run_part, job)

    def wait(self, handles: list[Any]) -> list[tuple[Any, PartResult]]:
        return self.executor.wait(handles)

    def close(self) -> None:
        self.executor.close()
        if self._cache is not None:
            self._cache.close()


def make_backend(name: str, workers: int, address: str | None = None) -> PartBackend:
    """The backend ``name`` for ``workers`` concurrent walks: ``local`` with one worker
    runs in this process, with more a pool of ``workers`` processes (one arena per
    process); ``ray`` runs Ray tasks on ``address`` (see :func:`simlab.base.parallel.connect_ray`).
    """
    if name == "ray":
        return PartBackend(make_executor("ray", address=address))
    return PartBackend(make_executor(name, workers=workers, address=address,
                                     in_process_single=True))
