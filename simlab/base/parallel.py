"""The one parallel layer of simlab: where jobs run (this process, local processes or Ray).

Every caller (dataset collection, the experiments of ``simlab reproduce``, calibration,
Visit-the-lab training, the replay's worker) gets its workers here:

* :func:`worker_pool` — the ONE way simlab starts local worker processes: a
  :class:`concurrent.futures.ProcessPoolExecutor` of ``N`` ``spawn`` processes (no PyBullet
  client, thread or lock of the parent is inherited) whose workers exit with their parent
  (:func:`exit_with_parent`); :func:`spawn_worker` is the pool of one (a single worker
  process, e.g. for a replay that must not share this process's PyBullet client);
* :func:`connect_ray` — the one place that imports Ray and starts or connects a runtime;
* :func:`make_executor` — one API over the three places a job can run:
  :class:`InProcessExecutor`, :class:`LocalExecutor` (a lazily created :func:`worker_pool`)
  and :class:`RayExecutor` (Ray tasks of one CPU each). Each has
  ``submit(fn, *args, **kwargs) -> handle``, ``wait(handles)`` (the finished ones, at
  least one), ``map(fn, kwargs_list, desc=, progress=)`` (results in job order, with an
  optional progress bar counting finished jobs), ``describe()`` and ``close()``, and is a
  context manager.

A job's result depends only on its function and arguments, so a deterministic job gives
the same result on every executor (the tests of collection and of the experiments check
it). Results come back to the driver, which alone writes files: a Ray cluster needs no
shared file system. Ray is an optional extra (``pip install "simlab[ray]"``).
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import os
from collections.abc import Callable, Iterator, Sequence
from types import ModuleType
from typing import TYPE_CHECKING, Any

from simlab.base import validation
from simlab.base.errors import WARNING_PREFIX_ENV, ConfigError, show_warnings_as

if TYPE_CHECKING:
    from multiprocessing.managers import SyncManager

#: Where jobs can run (``--backend``).
BACKENDS = ("local", "ray")

#: Seconds between two checks of a worker's parent (the longest an orphan lives).
PARENT_POLL_SECONDS = 0.5


# --------------------------------------------------------------------------- local processes


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


#: True in a worker process while it runs a job (see :func:`_init_worker`).
_BUSY = False


def _on_sigint(signum: int, frame: Any) -> None:
    if _BUSY:
        raise KeyboardInterrupt


@contextlib.contextmanager
def _sigint_held() -> Iterator[None]:
    """Ctrl-C held back while a worker process starts, and handled after.

    Ctrl-C in a terminal reaches the whole process group. A worker still importing (a
    ``spawn`` child needs ~1 s before its initializer runs) would die of it with a
    ``KeyboardInterrupt`` traceback of the import it was in. A blocked signal mask is
    inherited through fork and exec, so the child starts with SIGINT blocked and unblocks
    it once its handler is in place (:func:`_init_worker`, :func:`_init_manager`), as
    :mod:`multiprocessing.resource_tracker` starts its own process.

    In the driver the signal is only postponed: another thread of this process (a progress
    bar's, the executor's) may still take it, so the main thread's handler is replaced by
    one that notes it, and the signal is raised again once the start is over. A
    ``KeyboardInterrupt`` in the middle of a start would leave a started process that no
    one owns (a manager ignoring SIGINT then holds the interpreter's exit forever). The
    resource tracker is started first: a spawn starts it if it is not running, and it
    unblocks SIGINT after its own start (it does not restore the mask it found)."""
    import signal
    import threading
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()
    main = threading.current_thread() is threading.main_thread()
    caught: list[int] = []
    handler = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum)) \
        if main else None
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)
        if main:
            signal.signal(signal.SIGINT, signal.SIG_DFL if handler is None else handler)
            if caught:
                signal.raise_signal(signal.SIGINT)


def _unblock_sigint() -> None:
    import signal

    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def _init_worker(parent_pid: int) -> None:
    """Initializer of every :func:`worker_pool` process: :func:`exit_with_parent`, Ctrl-C
    handled as the driver needs it, and warnings printed as the command line prints them.

    Ctrl-C in a terminal sends SIGINT to the whole process group, workers included. A worker
    waiting for its next job would die of it with a ``KeyboardInterrupt`` traceback printed
    by :mod:`multiprocessing`, on the user's terminal, beside the driver's one-line
    ``interrupted``. So SIGINT is ignored while the worker is idle (the driver, interrupted
    too, shuts the pool down and the worker exits on the pool's stop message) and is a
    ``KeyboardInterrupt`` inside a job (it stops the job at once; the pool hands it back to
    the driver as the job's exception)."""
    import signal

    exit_with_parent(parent_pid)
    signal.signal(signal.SIGINT, _on_sigint)
    _unblock_sigint()  # blocked since the process started (:func:`_sigint_held`)
    # A command line's warnings read as its own lines (``simlab calibrate: warning: ...``),
    # not as Python's two-line default pointing into multiprocessing's code.
    prefix = os.environ.get(WARNING_PREFIX_ENV)
    if prefix is not None:
        show_warnings_as(prefix or None)


def _run_job(fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Any:
    """``fn(*args, **kwargs)`` in a worker, marked busy for :func:`_on_sigint`."""
    global _BUSY
    _BUSY = True
    try:
        return fn(*args, **kwargs)
    finally:
        _BUSY = False


class WorkerPool(cf.ProcessPoolExecutor):
    """The executor :func:`worker_pool` returns: a ``ProcessPoolExecutor`` that says how many
    processes it has (:attr:`processes`), for callers that feed it one job per process
    (``simlab train``'s goals) instead of reading the executor's private count. Its jobs
    stop on Ctrl-C and its idle workers ignore it (:func:`_init_worker`)."""

    def __init__(self, processes: int, **kwargs: Any) -> None:
        super().__init__(max_workers=processes, **kwargs)
        self.processes = int(processes)

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> cf.Future[Any]:
        with _sigint_held():  # a submit starts the next worker process
            return super().submit(_run_job, fn, *args, **kwargs)

    def stop_now(self) -> None:
        """Cancel the jobs not started and end the worker processes at once (SIGTERM), for
        a driver that stops (Ctrl-C) and will read no result. ``shutdown(wait=False)``
        alone leaves the running jobs to finish, and the interpreter's exit then waits for
        them (``visitlab train --workers 2`` took 24 s to stop). The workers are this
        pool's own processes (``spawn``), holding nothing another process needs."""
        processes = list((getattr(self, "_processes", None) or {}).values())
        self.shutdown(wait=False, cancel_futures=True)
        for proc in processes:  # the stdlib keeps them in _processes (3.14: terminate_workers)
            if proc.is_alive():
                proc.terminate()
        for proc in processes:
            proc.join(timeout=5)


def worker_pool(processes: int) -> WorkerPool:
    """A pool of ``processes`` local worker processes: ``spawn`` context (no PyBullet
    client, thread or lock of the parent inherited), each exiting with this process
    (:func:`exit_with_parent`). The caller shuts it down."""
    import multiprocessing

    return WorkerPool(processes, mp_context=multiprocessing.get_context("spawn"),
                      initializer=_init_worker, initargs=(os.getpid(),))


def _init_manager() -> None:
    """Initializer of a :func:`manager`'s server process: Ctrl-C ignored (see
    :func:`manager`), then unblocked (:func:`_sigint_held`)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _unblock_sigint()


def manager() -> SyncManager:
    """A started ``spawn`` :class:`multiprocessing.managers.SyncManager`, whose proxies
    (a progress queue) travel to :func:`worker_pool` jobs. The caller shuts it down.

    Decision: the manager outlives Ctrl-C and the pool. Its server ignores SIGINT, so only
    its owner ends it, and that owner stops the pool's workers first
    (:meth:`LocalExecutor.stop_now`): a worker of a stopped driver may still be unpickling
    a queued job, and a proxy whose manager has gone fails there with a
    ``FileNotFoundError`` traceback per worker."""
    import multiprocessing
    from multiprocessing.managers import SyncManager

    made = SyncManager(ctx=multiprocessing.get_context("spawn"))
    with _sigint_held():
        made.start(_init_manager)
    return made


def spawn_worker() -> WorkerPool:
    """A single fresh worker process (:func:`worker_pool` of one): for work that must run
    outside this process (its own PyBullet client, its own numba threads)."""
    return worker_pool(1)


# --------------------------------------------------------------------------- Ray


def connect_ray(address: str | None = None) -> tuple[ModuleType, bool]:
    """Import Ray and make sure a runtime is up; returns ``(ray, owns_runtime)``.

    With ``address`` (an existing cluster: ``"auto"``, ``"ray://head:10001"``...) it
    connects there; without, it reuses a runtime this process already initialized or
    starts a local one. ``owns_runtime`` is True when this call started or connected the
    runtime, so the caller shuts it down when done, and never one it did not start.
    """
    try:
        import ray
    except ModuleNotFoundError:
        raise ConfigError("the ray backend needs Ray", key="backend",
                          fix='pip install "simlab[ray]", or use --backend local') from None
    if address is not None:
        if ray.is_initialized():
            raise ConfigError(f"Ray is already initialized in this process; cannot connect "
                              f"to {address!r}", key="address", fix="omit --address to reuse it")
        check_reachable(address)
        try:
            ray.init(address=address)
        except (ConnectionError, TimeoutError, ValueError) as exc:
            raise ConfigError(f"cannot connect to the Ray cluster at {address!r}: "
                              f"{' '.join(str(exc).split())[:200]}", key="address",
                              fix=_ADDRESS_FIX) from None
        return ray, True
    if not ray.is_initialized():
        ray.init(include_dashboard=False)
        return ray, True
    return ray, False


#: Seconds :func:`check_reachable` waits for a Ray head to accept a connection.
CONNECT_TIMEOUT = 5.0

_ADDRESS_FIX = ("start the cluster first (ray start --head), check HOST:PORT (the head's GCS "
                "port, 6379 by default; ray://HOST:10001 for Ray Client), or omit --address "
                "for a local runtime")


def check_reachable(address: str, timeout: float = CONNECT_TIMEOUT) -> None:
    """Fail within ``timeout`` seconds when ``address`` (``HOST:PORT`` or
    ``ray://HOST:PORT``) accepts no TCP connection: ``ray.init`` itself keeps retrying an
    unreachable head for minutes. ``"auto"`` and ``"local"`` (found by Ray on this machine)
    are left to Ray. A malformed address is a :class:`ConfigError` naming it."""
    import socket

    if address in ("auto", "local"):
        return
    rest = address.split("://", 1)[1] if "://" in address else address
    host, sep, port = rest.rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ConfigError(f"expected HOST:PORT, ray://HOST:PORT or auto, got {address!r}",
                          key="address", fix=_ADDRESS_FIX)
    try:
        with socket.create_connection((host, int(port)), timeout=timeout):
            pass
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise ConfigError(f"no Ray cluster answers at {address!r} ({reason}, waited at most "
                          f"{timeout:g} s)", key="address", fix=_ADDRESS_FIX) from None


def check_address(backend: str, address: str | None) -> None:
    """``--address`` only makes sense with the Ray backend."""
    if backend != "ray" and address is not None:
        raise ConfigError("--address applies to the ray backend only", key="address",
                          fix="add --backend ray or drop --address")


# --------------------------------------------------------------------------- executors


def _apply(fn: Callable[..., Any], args: tuple[Any, ...], kwargs: dict[str, Any]) -> Any:
    return fn(*args, **kwargs)


class _Bar:
    """A tqdm bar of finished jobs (nothing when disabled or for a single job)."""

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


def _serial_map(fn: Callable[..., Any], jobs: list[dict[str, Any]], bar: _Bar) -> list[Any]:
    out = []
    for kw in jobs:
        out.append(fn(**kw))
        bar.update()
    return out


class _Executor:
    """What the three executors share: ``map`` with its progress bar, and the
    context-manager protocol. Subclasses set ``name`` and ``workers``."""

    name = ""
    workers = 1

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Any:
        raise NotImplementedError

    def wait(self, handles: Sequence[Any]) -> list[tuple[Any, Any]]:
        raise NotImplementedError

    def map(self, fn: Callable[..., Any], kwargs_list: Sequence[dict[str, Any]], *,
            desc: str | None = None, progress: bool = False) -> list[Any]:
        """``[fn(**kw) for kw in kwargs_list]``, computed by the workers; results in job
        order. ``progress`` shows a bar of finished jobs titled ``desc``."""
        jobs = list(kwargs_list)
        bar = _Bar(len(jobs), desc, progress)
        try:
            return self._map(fn, jobs, bar)
        finally:
            bar.close()

    def _map(self, fn: Callable[..., Any], jobs: list[dict[str, Any]], bar: _Bar) -> list[Any]:
        raise NotImplementedError

    def describe(self) -> str:
        return f"{self.name} ({self.workers} worker{'s' if self.workers != 1 else ''})"

    def stop_now(self) -> None:
        """End the jobs at once and read no result (a stopping driver); the executor stays
        usable. Only local processes are ended (:meth:`WorkerPool.stop_now`)."""

    def close(self) -> None:
        """Release the workers (idempotent)."""

    def __enter__(self) -> _Executor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class InProcessExecutor(_Executor):
    """Runs each job at once, in this process (one worker; handy in tests and for jobs
    whose arguments cannot be pickled). ``submit`` raises what the job raises."""

    name = "in-process"

    def __init__(self) -> None:
        self._done: dict[int, Any] = {}
        self._next = 0

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> int:
        handle = self._next
        self._next += 1
        self._done[handle] = fn(*args, **kwargs)
        return handle

    def wait(self, handles: Sequence[int]) -> list[tuple[int, Any]]:
        return [(h, self._done.pop(h)) for h in handles]

    def _map(self, fn: Callable[..., Any], jobs: list[dict[str, Any]], bar: _Bar) -> list[Any]:
        return _serial_map(fn, jobs, bar)


class LocalExecutor(_Executor):
    """A :func:`worker_pool` of ``workers`` processes (default: the machine's cores),
    created on the first job that needs it and reused until :meth:`close` (process
    start-up and imports are paid once). A map of a single job, or with one worker,
    runs in this process."""

    name = "local"

    def __init__(self, workers: int | None = None) -> None:
        if workers is None:
            workers = os.cpu_count() or 1
        self.workers = validation.whole(workers, "workers", minimum=1)
        self._pool: WorkerPool | None = None

    def _get_pool(self) -> WorkerPool:
        if self._pool is None:
            self._pool = worker_pool(self.workers)
        return self._pool

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> cf.Future[Any]:
        return self._get_pool().submit(fn, *args, **kwargs)

    def wait(self, handles: Sequence[cf.Future[Any]]) -> list[tuple[cf.Future[Any], Any]]:
        done, _ = cf.wait(handles, return_when=cf.FIRST_COMPLETED)
        return [(f, f.result()) for f in handles if f in done]

    def _map(self, fn: Callable[..., Any], jobs: list[dict[str, Any]], bar: _Bar) -> list[Any]:
        if len(jobs) <= 1 or self.workers == 1:
            return _serial_map(fn, jobs, bar)
        futures = [self.submit(fn, **kw) for kw in jobs]
        try:
            for _ in cf.as_completed(futures):
                bar.update()
            return [f.result() for f in futures]
        except BaseException:
            for f in futures:
                f.cancel()
            raise

    def stop_now(self) -> None:
        if self._pool is not None:
            self._pool.stop_now()
            self._pool = None

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


class RayExecutor(_Executor):
    """Ray tasks (one CPU each) on the runtime of :func:`connect_ray` (``address``, or
    the one this process already initialized, or a new local one, shut down again by
    :meth:`close`). ``workers`` is the cluster's CPU count."""

    name = "ray"

    def __init__(self, address: str | None = None) -> None:
        self._ray, self._owns = connect_ray(address)
        self._remote = self._ray.remote(num_cpus=1)(_apply)
        self.workers = int(self._ray.cluster_resources().get("CPU", 1))

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Any:
        return self._remote.remote(fn, args, kwargs)

    def wait(self, handles: Sequence[Any]) -> list[tuple[Any, Any]]:
        ready, _ = self._ray.wait(list(handles), num_returns=1)
        return [(ref, self._ray.get(ref)) for ref in ready]

    def _map(self, fn: Callable[..., Any], jobs: list[dict[str, Any]], bar: _Bar) -> list[Any]:
        if not jobs:
            return []
        fn_ref = self._ray.put(fn)  # shipped once, not once per job
        refs = [self._remote.remote(fn_ref, (), kw) for kw in jobs]
        pending = list(refs)
        while pending:
            done, pending = self._ray.wait(pending, num_returns=1)
            for _ in done:
                bar.update()
        return self._ray.get(refs)

    def describe(self) -> str:
        return f"ray ({self.workers} CPUs)"

    def close(self) -> None:
        if self._owns:
            self._ray.shutdown()
            self._owns = False


Executor = InProcessExecutor | LocalExecutor | RayExecutor


def make_executor(backend: str = "local", *, workers: int | None = None,
                  address: str | None = None, in_process_single: bool = False) -> Executor:
    """The executor of ``backend`` (one of :data:`BACKENDS`).

    ``local``: :class:`LocalExecutor` of ``workers`` processes (default: the cores), or
    :class:`InProcessExecutor` when ``workers == 1`` and ``in_process_single`` (no worker
    process at all). ``ray``: :class:`RayExecutor` on ``address`` (``workers`` must be
    None: Ray uses its cluster's CPUs).
    """
    check_address(backend, address)
    if backend == "local":
        if in_process_single and workers == 1:
            return InProcessExecutor()
        return LocalExecutor(workers)
    if backend == "ray":
        if workers is not None:
            raise ConfigError("--workers applies to the local backend only (Ray uses its "
                              "cluster's CPUs)", key="workers")
        return RayExecutor(address)
    raise ConfigError(f"unknown backend {backend!r}", key="backend",
                      fix=f"choose one of {', '.join(BACKENDS)}")
