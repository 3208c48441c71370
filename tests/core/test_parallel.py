"""The one parallel layer: every executor gives the same results in job order."""

from __future__ import annotations

import os

import pytest

from simlab.base.errors import ConfigError
from simlab.base.parallel import (
    InProcessExecutor,
    LocalExecutor,
    make_executor,
    spawn_worker,
    worker_pool,
)


def _square_plus(x: int, c: int = 0) -> int:
    return x * x + c


def _pid() -> int:
    return os.getpid()


def test_map_same_results_in_order_in_process_and_local_pool() -> None:
    jobs = [{"x": x, "c": 1} for x in range(7)]
    expected = [x * x + 1 for x in range(7)]
    with InProcessExecutor() as ex:
        assert ex.map(_square_plus, jobs) == expected
    with LocalExecutor(2) as ex:
        assert ex.map(_square_plus, jobs) == expected
        assert ex.describe() == "local (2 workers)"


def test_submit_wait_returns_every_handle_once() -> None:
    for ex in (InProcessExecutor(), LocalExecutor(2)):
        with ex:
            handles = {ex.submit(_square_plus, x, c=2): x for x in range(5)}
            got = {}
            while handles:
                for h, res in ex.wait(list(handles)):
                    got[handles.pop(h)] = res
            assert got == {x: x * x + 2 for x in range(5)}


def test_pool_workers_are_other_processes_and_single_worker_spawns() -> None:
    with LocalExecutor(2) as ex:
        pids = ex.map(_pid, [{} for _ in range(4)])
    assert os.getpid() not in pids
    pool = spawn_worker()
    try:
        assert pool.submit(_pid).result() != os.getpid()
        assert pool._max_workers == pool.processes == 1
    finally:
        pool.shutdown()
    pool = worker_pool(3)
    try:
        assert pool._max_workers == pool.processes == 3
        assert pool._mp_context.get_start_method() == "spawn"
    finally:
        pool.shutdown()


def test_make_executor_choices_and_errors() -> None:
    assert isinstance(make_executor("local", workers=1, in_process_single=True),
                      InProcessExecutor)
    assert isinstance(make_executor("local", workers=1), LocalExecutor)
    with pytest.raises(ConfigError, match="address"):
        make_executor("local", address="auto")
    with pytest.raises(ConfigError, match="unknown backend"):
        make_executor("dask")
    with pytest.raises(ConfigError, match="whole number"):
        LocalExecutor(0)
    with pytest.raises(ConfigError, match="workers"):
        make_executor("ray", workers=2)


def test_an_unreachable_or_malformed_ray_address_is_refused_at_once() -> None:
    import socket

    import pytest

    from simlab.base.errors import ConfigError
    from simlab.base.parallel import check_reachable

    with socket.socket() as free:  # a port nobody listens on: bound, then closed
        free.bind(("127.0.0.1", 0))
        port = free.getsockname()[1]
    with pytest.raises(ConfigError, match=rf"address: no Ray cluster answers at "
                                          rf"'127\.0\.0\.1:{port}'.*ray start --head"):
        check_reachable(f"127.0.0.1:{port}", timeout=2.0)
    for bad in ("nowhere", "ray://host", "host:99999", ":6379"):
        with pytest.raises(ConfigError, match="expected HOST:PORT"):
            check_reachable(bad)
    with socket.socket() as server:  # something listens: accepted
        server.bind(("127.0.0.1", 0))
        server.listen(1)
        check_reachable(f"ray://127.0.0.1:{server.getsockname()[1]}", timeout=2.0)
    check_reachable("auto")  # Ray's own lookup
