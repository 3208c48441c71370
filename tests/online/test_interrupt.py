"""Ctrl-C of ``simlab online --arena`` while its processes start: one line, exit code 130.

The command starts a manager (the decisions' progress queue) and two worker processes; a
Ctrl-C reaches all of them (the terminal signals the process group). Each moment below is
one where a traceback was printed: while the manager starts, while the workers import,
and once they unpickle their first job (whose progress queue needs the manager)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest


def _spawned(pid: int) -> int:
    """How many ``multiprocessing.spawn`` children process ``pid`` has."""
    n = 0
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text().rsplit(") ", 1)[1].split()
            cmdline = Path(f"/proc/{entry}/cmdline").read_bytes()
        except (OSError, IndexError):
            continue
        n += int(stat[1]) == pid and b"multiprocessing.spawn" in cmdline
    return n


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize(("children", "after"), [(1, 0.0), (2, 0.0), (3, 0.3), (3, 1.5)])
def test_ctrl_c_while_the_workers_start_prints_one_line(tmp_path: Path, children: int,
                                                        after: float) -> None:
    """SIGINT to the process group once ``children`` processes (the manager, then the
    workers) have been spawned, ``after`` s later: no traceback, ``interrupted``, 130."""
    from discretize.voronoi import Discretizer

    g = np.linspace(-0.6, 0.6, 5)
    states = Discretizer(centres=np.array([(x, y) for y in g for x in g])).save(
        tmp_path / "s.json")
    cmd = [sys.executable, "-m", "simlab", "online", "--arena", "table", "--states",
           str(states), "--criteria", "mf", "mb", "entropy", "--goal", "12",
           "--start-states", "0", "--decisions", "2000", "--seeds", "2", "--workers", "2",
           "--out", str(tmp_path / "o")]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    while proc.poll() is None and _spawned(proc.pid) < children:
        time.sleep(0.01)
    time.sleep(after)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate()
    assert "Traceback" not in err, err
    assert "Error" not in err, err
    assert proc.returncode == 130, err
    assert err.count("interrupted") == 1, err
