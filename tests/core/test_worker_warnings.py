"""Warnings raised in worker processes read as the command line's own lines, each text
once per command."""

from __future__ import annotations

import warnings

from simlab.base.errors import WARNING_PREFIX_ENV, WARNINGS_SHOWN_ENV
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
        seen["shown"] = os.environ.get(WARNINGS_SHOWN_ENV)
        assert seen["shown"] and not os.path.exists(seen["shown"])  # made by a first warning
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
    assert WARNINGS_SHOWN_ENV not in os.environ and not os.path.exists(seen["shown"])


def test_a_warning_prints_once_per_command_whatever_the_process(monkeypatch, tmp_path,
                                                                capfd) -> None:
    """The same text from the command and from each of two workers: one line."""
    monkeypatch.setenv(WARNING_PREFIX_ENV, "simlab calibrate")
    monkeypatch.setenv(WARNINGS_SHOWN_ENV, str(tmp_path))
    from simlab.base.errors import show_warnings_as

    saved = warnings.showwarning
    try:
        show_warnings_as("simlab calibrate")
        warnings.warn("start state 6: off its centre", stacklevel=1)
        with worker_pool(2) as pool:
            for f in [pool.submit(warnings.warn, "start state 6: off its centre")
                      for _ in range(4)] + [pool.submit(warnings.warn, "start state 7")]:
                f.result()
    finally:
        warnings.showwarning = saved
    err = capfd.readouterr().err
    assert err.count("simlab calibrate: warning: start state 6: off its centre") == 1, err
    assert err.count("simlab calibrate: warning: start state 7") == 1, err


def test_calibrate_says_once_that_a_start_state_is_off_its_centre(tmp_path, capfd) -> None:
    """``simlab calibrate --workers 2``: the driver and both workers read the same states
    and meet the same two warnings; each is printed by one of them."""
    import numpy as np

    from discretize.voronoi import Discretizer
    from simlab.base.actions import parse_action_set
    from simlab.data.walkers import KinematicParams
    from tests.calibration.conftest import hidden_walk, write_counts_csv

    g = np.linspace(-0.6, 0.6, 5)
    centres = np.array([(x, y) for y in g[::-1] for x in g])
    centres[6] = (-0.22, 0.22)  # inside table_obstacles' box
    disc = Discretizer(centres=centres)
    states = disc.save(tmp_path / "s.json")
    aset = parse_action_set(8, "ccw-east")
    sim = hidden_walk(disc, KinematicParams(), aset, 0.3, 1, "kinematic")
    real = write_counts_csv(tmp_path / "real.csv", sim.counts)
    capfd.readouterr()
    code = main(["calibrate", "--real", str(real), "--states", str(states), "--arena",
                 "table_obstacles", "--out", str(tmp_path / "cal"), "--simulator", "kinematic",
                 "--n-actions", "8", "--convention", "ccw-east", "--hours-per-candidate",
                 "0.2", "--candidates", "3", "--workers", "2", "--n-boot", "10",
                 "--start-states", "6,12", "--no-confirm", "--transfer-seeds", "1",
                 "--no-progress"])
    err = capfd.readouterr().err
    assert code == 0, err
    assert err.count("start state 6: the robot does not fit at its centre") == 1, err
    assert err.count("state centres lie off the floor or inside an obstacle") == 1, err
    assert "start state 12" not in err
