"""Warnings raised in worker processes read as the command line's own lines."""

from __future__ import annotations

import warnings

from simlab.base.errors import WARNING_PREFIX_ENV
from simlab.base.parallel import worker_pool
from simlab.cli import main


def test_a_worker_prints_warnings_as_the_command_line(monkeypatch, capfd) -> None:
    monkeypatch.setenv(WARNING_PREFIX_ENV, "simlab calibrate")
    with worker_pool(1) as pool:
        pool.submit(warnings.warn, "start state 36:\n    the robot does not fit").result()
    err = capfd.readouterr().err
    assert "simlab calibrate: warning: start state 36: the robot does not fit" in err
    assert "UserWarning" not in err and "process.py" not in err


def test_quiet_workers_print_no_warning(monkeypatch, capfd) -> None:
    monkeypatch.setenv(WARNING_PREFIX_ENV, "")  # -q
    with worker_pool(1) as pool:
        pool.submit(warnings.warn, "start state 36").result()
    assert "start state 36" not in capfd.readouterr().err


def test_outside_the_command_line_workers_keep_python_s_format(monkeypatch, capfd) -> None:
    monkeypatch.delenv(WARNING_PREFIX_ENV, raising=False)
    with worker_pool(1) as pool:
        pool.submit(warnings.warn, "start state 36").result()
    assert "UserWarning: start state 36" in capfd.readouterr().err


def test_the_command_line_hands_its_format_to_workers_and_restores_it(monkeypatch,
                                                                      tmp_path) -> None:
    monkeypatch.delenv(WARNING_PREFIX_ENV, raising=False)
    seen = {}

    def fake_run(args, verbosity):
        import os

        seen["prefix"] = os.environ.get(WARNING_PREFIX_ENV)
        return 0

    monkeypatch.setattr("simlab.cli._run", fake_run)
    saved = warnings.showwarning
    assert main(["estimate", str(tmp_path / "data"), "--out", str(tmp_path / "m.npz")]) == 0
    assert seen["prefix"] == "simlab estimate"
    assert main(["-q", "estimate", str(tmp_path / "data"), "--out",
                 str(tmp_path / "m.npz")]) == 0
    assert seen["prefix"] == ""
    import os

    assert WARNING_PREFIX_ENV not in os.environ and warnings.showwarning is saved
