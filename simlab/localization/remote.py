"""An :class:`~simlab.localization.tracker.MCLTracker` in a process of its own.

In a closed-loop replay with the ``mcl`` pose source the particle filter costs about as
much CPU as the physics it localizes. Within a motion primitive the robot steers by its
true (or odometry) heading, never by the filter, so the filter's updates need not hold
the physics up: :class:`RemoteTracker` sends each scan and odometry pose to a ``spawn``
process running an ordinary ``MCLTracker`` and returns at once; only a question whose
answer the robot needs (the pose at a decision, the particles of a video frame, the
log at the end) waits for the filter to have caught up. The worker processes the same
messages in the same order with the same Generator (built there from the same
``SeedSequence``), so every number is bit-identical to an in-process tracker (tested).
The replay uses it only when a core is left for it beside its runs
(:func:`simlab.replay.scheduling.schedule`): sharing a core, its messages cost more than
it overlaps.

The decision taken: a process (the filter's numpy calls hold the GIL, so a thread would
not overlap) fed through a ``multiprocessing`` pipe; a scan is ~40 ranges, so a message
costs tens of microseconds.
"""

from __future__ import annotations

import traceback
import weakref
from types import SimpleNamespace
from typing import Any, NoReturn

import numpy as np
from numpy.typing import NDArray


def _serve(conn: Any) -> None:
    """The worker: an MCLTracker built from the first message of :class:`RemoteTracker`
    and driven by the next ones."""
    import signal

    from simlab.localization.tracker import MCLTracker

    # Ctrl-C in a terminal reaches this process too: the replay (interrupted as well) ends
    # it by closing the pipe; dying of it here would print a traceback beside "interrupted"
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        field, seq, params, initial_pose, odometry = conn.recv()
        field.log_table.setflags(write=False)  # as built (the numba kernel's signature)
        tracker = MCLTracker(field, np.random.default_rng(seq), params,
                             initial_pose=initial_pose, odometry=odometry)
        conn.send(("ok", None))
        while True:
            msg = conn.recv()
            kind = msg[0]
            if kind == "scan":
                _, ranges, angles, offset, pose, stamp, odom = msg
                tracker.on_scan(SimpleNamespace(ranges=ranges, angles=angles,
                                                sensor_offset=offset, pose=pose,
                                                stamp=stamp), odom)
            elif kind == "pose":
                conn.send(("ok", tracker.pose(msg[1])))
            elif kind == "particles":
                conn.send(("ok", tracker.filter.particles.copy()))
            elif kind == "log":
                conn.send(("ok", tracker.log()))
                return
            else:  # pragma: no cover - a programming error
                raise ValueError(f"unknown message {kind!r}")
    except EOFError:  # the replay went away
        return
    except BaseException:  # reported to the replay, which raises it
        conn.send(("error", traceback.format_exc()))


class _FilterView:
    """What the replay reads of ``tracker.filter``: the beam subset and the particles."""

    def __init__(self, owner: RemoteTracker, n_beams: int) -> None:
        self._owner = owner
        self._n_beams = n_beams

    def beam_subset(self, n_total: int) -> NDArray[np.int64]:
        """Same as :meth:`ParticleFilter.beam_subset`."""
        k = min(self._n_beams, n_total)
        return np.floor(np.arange(k) * (n_total / k)).astype(np.int64)

    @property
    def particles(self) -> NDArray[np.float64]:
        return self._owner._ask(("particles",))


class RemoteTracker:
    """``MCLTracker(field, default_rng(seq), params, initial_pose=..., odometry=...)`` in a
    worker process; the methods the replay uses: :meth:`on_scan` (no wait), :meth:`pose`
    and ``filter.particles`` (wait for the filter), :meth:`log` (ends the worker)."""

    def __init__(self, field: Any, seq: np.random.SeedSequence, params: Any, *,
                 initial_pose: NDArray[np.float64], odometry: NDArray[np.float64]) -> None:
        import multiprocessing

        ctx = multiprocessing.get_context("spawn")
        self._conn, child = ctx.Pipe()
        # The map goes through the pipe, not in the process's arguments: Python writes
        # those to the new process while holding the reading end itself, so a worker that
        # dies as it starts (a script calling simlab without the __main__ guard) would
        # leave that write, megabytes of map, blocked forever. Through the pipe, its end
        # closes with it and the send fails at once.
        self._proc = ctx.Process(target=_serve, args=(child,), daemon=True, name="simlab-mcl")
        self._proc.start()
        child.close()
        self.filter = _FilterView(self, params.n_beams)
        # A replay that fails mid-run drops the tracker: closing the pipe ends the worker.
        weakref.finalize(self, self._conn.close)
        try:
            self._ask((field, seq, params, np.asarray(initial_pose, np.float64),
                       np.asarray(odometry, np.float64)))
        except BaseException:
            self.close()
            raise

    def _answer(self) -> Any:
        """The worker's next answer; a clear error if it failed or ended instead."""
        while not self._conn.poll(0.2):
            if not self._proc.is_alive():
                self._died()
        try:
            status, value = self._conn.recv()
        except EOFError:
            self._proc.join(timeout=5)
            self._died()
        if status == "error":
            raise RuntimeError(f"the MCL worker process failed:\n{value}")
        return value

    def _died(self) -> NoReturn:
        raise RuntimeError(
            f"the MCL worker process ended unexpectedly (exit code {self._proc.exitcode}); a "
            "script that calls simlab must do so under `if __name__ == \"__main__\":`, "
            "because every worker process starts by importing the script")

    def _ask(self, msg: tuple[Any, ...]) -> Any:
        try:
            self._conn.send(msg)
        except (BrokenPipeError, ConnectionResetError):
            self._proc.join(timeout=5)
            self._died()
        return self._answer()

    def on_scan(self, scan: Any, odom: NDArray[np.float64]) -> None:
        """Queue ``scan`` and the odometry pose for the filter (returns at once)."""
        self._conn.send(("scan", np.asarray(scan.ranges), np.asarray(scan.angles),
                         np.asarray(scan.sensor_offset), getattr(scan, "pose", None),
                         float(getattr(scan, "stamp", np.nan)),
                         np.asarray(odom, dtype=np.float64)))

    def pose(self, odometry: NDArray[np.float64]) -> NDArray[np.float64]:
        """:meth:`MCLTracker.pose` once the filter has taken every scan sent so far."""
        return self._ask(("pose", np.asarray(odometry, dtype=np.float64)))

    def log(self) -> Any:
        """:meth:`MCLTracker.log`; the worker then ends."""
        out = self._ask(("log",))
        self.close()
        return out

    def close(self) -> None:
        """End the worker (idempotent): it reads the end of the pipe and returns."""
        self._conn.close()
        self._proc.join(timeout=10)
        if self._proc.is_alive():  # pragma: no cover - a stuck worker
            self._proc.terminate()

    def __enter__(self) -> RemoteTracker:
        return self

    def __exit__(self, *exc: Any) -> None:
        if not self._conn.closed:
            self.close()
