"""The particle filter in a process of its own: it answers as the in-process tracker does,
and a worker that cannot start is an error, never a hang."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from types import SimpleNamespace

import numpy as np

from simlab.localization.filter import MCLParams
from simlab.localization.likelihood import LikelihoodField
from simlab.localization.maps import arena_map
from simlab.localization.remote import RemoteTracker
from simlab.localization.tracker import MCLTracker
from simlab.physics.arena import load_arena


def test_remote_tracker_answers_as_the_local_one() -> None:
    field = LikelihoodField(arena_map(load_arena("table"), 0.02))
    seq = np.random.SeedSequence(7)
    params = MCLParams(n_particles=200)
    start = np.array([0.0, -0.3, 0.0])
    local = MCLTracker(field, np.random.default_rng(seq), params, initial_pose=start,
                       odometry=np.zeros(3))
    n = 360
    scan = SimpleNamespace(ranges=np.full(n, 0.45), angles=np.arange(n) * (2 * np.pi / n),
                           sensor_offset=np.array([-0.03, 0.0]), pose=start, stamp=0.0)
    with RemoteTracker(field, seq, params, initial_pose=start,
                       odometry=np.zeros(3)) as remote:
        for k in range(4):
            odom = np.array([0.03 * k, 0.0, 0.05 * k])
            local.on_scan(scan, odom)
            remote.on_scan(scan, odom)
        assert np.array_equal(remote.pose(odom), local.pose(odom))
        assert np.array_equal(remote.filter.particles, local.filter.particles)
        log = remote.log()
    assert log.t.size == local.log().t.size > 0


def test_a_worker_that_dies_as_it_starts_is_an_error_not_a_hang(tmp_path) -> None:
    """A script without the ``__main__`` guard: the worker re-imports it and dies starting
    its own worker. Python used to be left writing the map to it forever."""
    script = tmp_path / "unguarded.py"
    script.write_text(textwrap.dedent("""
        import numpy as np
        from simlab.localization.filter import MCLParams
        from simlab.localization.likelihood import LikelihoodField
        from simlab.localization.maps import arena_map
        from simlab.localization.remote import RemoteTracker
        from simlab.physics.arena import load_arena

        field = LikelihoodField(arena_map(load_arena("table"), 0.01))  # megabytes
        RemoteTracker(field, np.random.SeedSequence(0), MCLParams(),
                      initial_pose=np.zeros(3), odometry=np.zeros(3))
        print("started")
    """))
    proc = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode != 0
    assert "started" not in proc.stdout
    assert "MCL worker process ended unexpectedly" in proc.stderr
    assert 'if __name__ == "__main__":' in proc.stderr
