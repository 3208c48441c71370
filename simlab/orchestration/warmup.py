"""Numba compilation off the pipeline's critical path.

Every numba kernel of the physics chain is ``@njit(cache=True)``: the first run on a
machine compiles it (the value-iteration softmax training about 12 s on a quiet 2-core
box, the particle filter's kernels a few seconds) and writes the machine code to the numba cache
directory of this source version (:mod:`simlab.base._numba_cache`, or the user's
``NUMBA_CACHE_DIR``); later processes load it in milliseconds. Numba caches per *type signature*, not per array size, so
running a kernel once on a tiny problem of the same dtypes and layouts fills the cache
for the real one.

:func:`warm_kernels` does that for the training agent and the MCL filter.
:func:`start_warmup` runs it in a ``spawn`` process, so a pipeline can compile while its
first stages step physics (the map stage steps one world, leaving a core free) and its
training and replay then load the cached code. The decision taken: a separate process
(not a thread: numba's compiler holds the GIL) that only writes numba's own cache; it
changes no result, and if it has not finished when a stage needs a kernel, that stage
compiles the kernel itself as before (or, with :meth:`Warmup.wait`, waits for it, which
is never slower than compiling again).

The worker then stays up (:attr:`Warmup.worker`): it has imported the training, replay and
plotting modules and loaded the compiled kernels, so the pipeline lends it to the later
stages for their second core (the training's share of the goals, the replay's random
baseline) instead of starting a fresh process, which costs ~2-3 s of imports per stage on
a 2-core machine. :meth:`Warmup.close` ends it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np


def warm_mcl() -> None:
    """Compile the particle filter's kernels (likelihood field, reweighting, mean shift, spread) with the
    signatures of a replay: one predict and one update on a coarse map of the table."""
    from types import SimpleNamespace

    from simlab.localization.filter import MCLParams, ParticleFilter
    from simlab.localization.likelihood import LikelihoodField
    from simlab.localization.maps import arena_map
    from simlab.physics.arena import load_arena

    field = LikelihoodField(arena_map(load_arena("table"), 0.05))
    pf = ParticleFilter(field, MCLParams(), rng=np.random.default_rng(0))
    pf.init_gaussian(np.zeros(3))
    pf.predict(np.zeros(3), np.array([0.01, 0.0, 0.01]))
    n = 360
    scan = SimpleNamespace(ranges=np.full(n, 0.3), angles=np.arange(n) * (2 * np.pi / n),
                           sensor_offset=np.array([-0.03, 0.0]))
    pf.update(scan)
    pf.spread()


def warm_training(agent: str = "vi-softmax") -> None:
    """Compile ``agent``'s training kernels: :func:`simlab.training.train.train` on a
    3-state, 16-action MDP for 2 episodes (no files written)."""
    from simlab.data.mdp import EmpiricalMDP
    from simlab.training.train import train

    s, a = 3, 16
    t = np.zeros((s, a, s))
    t[:, :, 0] = t[:, :, 1] = 0.5
    mdp = EmpiricalMDP(T=t, goal_names=("g",), goal_masks=np.array([[False, True, False]]))
    train(mdp, agent=agent, episodes=2, runs=1, out=None, plots=False, progress=False)


def warm_kernels(agent: str | None = "vi-softmax", mcl: bool = True) -> float:
    """Fill numba's cache for the training of ``agent`` (None: skip) and the MCL filter,
    and import what the later stages run in this process (:data:`LATER_STAGE_MODULES`);
    returns the wall seconds it took. Warnings of the tiny problems are silenced."""
    import importlib
    import warnings

    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if mcl:
            warm_mcl()
        if agent is not None:
            warm_training(agent)
        for name in LATER_STAGE_MODULES:
            importlib.import_module(name)
    return time.perf_counter() - t0


#: Modules a lent worker runs later (the replay's baseline, the training's figures).
LATER_STAGE_MODULES = ("simlab.replay.loop", "simlab.replay.scheduling",
                       "simlab.training.train", "simlab.training.heatmap",
                       "simlab.training.curves", "matplotlib.pyplot")


@dataclass
class Warmup:
    """Handle of a warm-up worker (see :func:`start_warmup`)."""

    future: Any
    pool: Any
    started: float

    def wait(self, timeout: float | None = None) -> bool:
        """Wait up to ``timeout`` s (None: until it ends); True when it has ended."""
        import concurrent.futures as cf

        cf.wait([self.future], timeout=timeout)
        return self.future.done()

    @property
    def worker(self) -> Any:
        """The warmed worker (a one-process executor) to lend to later stages once the
        warm-up has ended well; None while it runs or after it failed (its process may be
        gone: the stages then start their own, as without a warm-up)."""
        return self.pool if self.ok else None

    def close(self) -> None:
        """End the worker (pending work is cancelled)."""
        self.pool.shutdown(wait=True, cancel_futures=True)

    def __enter__(self) -> Warmup:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def done(self) -> bool:
        return self.future.done()

    @property
    def ok(self) -> bool:
        """True when the warm-up ended without an error."""
        return self.future.done() and self.future.exception() is None


def start_warmup(agent: str | None = "vi-softmax", mcl: bool = True) -> Warmup:
    """Start :func:`warm_kernels` in a fresh worker process and return at once.

    Call it before the physics stages (``simlab pipeline``: before the map) and, before
    training, ``wait()`` on the handle; lend :attr:`Warmup.worker` to later stages and
    ``close()`` it at the end (or use the handle as a context manager). A failure in the
    worker is harmless: the stages then compile as they would without it. The worker is
    a :func:`simlab.base.parallel.spawn_worker` (it exits with its parent).
    """
    from simlab.base.parallel import spawn_worker

    pool = spawn_worker()
    return Warmup(future=pool.submit(warm_kernels, agent, mcl), pool=pool,
                  started=time.perf_counter())
