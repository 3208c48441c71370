"""A robot whose states come from a noisy localization drives until its *localized* state
changes (physics walker, drive-until-state-change mode with pose noise)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from simlab.data.collect import collect
from simlab.data.dataset import read_dataset
from simlab.physics.motion import PrimitiveParams


def test_moves_end_when_the_reading_leaves_the_cell(tmp_path: Path,
                                                     table_states_file: Path) -> None:
    # 5 cm of localization error on ~0.2 m cells: a move that ended on the true position's
    # state change would read its old cell again about a third of the time (the reading of
    # a robot just past a boundary falls back across it); watching the reading, a move that
    # is not blocked and not timed out always reads a new cell at its end.
    params = PrimitiveParams(mode="until_state_change", max_drive_time=3.0,
                             pose_noise_xy=0.05, decision_latency=1.0)
    collect("table", table_states_file, out=tmp_path / "d", transitions=150, params=params,
            seed=11, workers=1, progress=False)
    t = read_dataset(tmp_path / "d")
    s, s2 = t.column("s").to_numpy(), t.column("s_next").to_numpy()
    blocked = t.column("blocked").to_numpy(zero_copy_only=False)
    duration = t.column("duration").to_numpy()
    moved = ~blocked
    assert moved.sum() > 80
    # the reading changed state on nearly every unblocked move; the few that did not are
    # moves cut short by the detector re-run during the drive or the time limit
    changed = np.mean(s[moved] != s2[moved])
    assert changed > 0.85, changed
    assert np.all(duration > 0)
