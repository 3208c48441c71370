"""``simlab online --arena``: the online experiment in physics from the command line.

Analytic doorways, the robot's own action set in physics, boxes that survive a restart, and
the command end to end (outputs, the physics summary and its agreement with the log)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from discretize.voronoi import Discretizer
from simlab.base.errors import ConfigError
from simlab.cli import main
from simlab.online import meta
from simlab.online.doorway import doorway
from simlab.online.physics import (
    PhysicsChange,
    PhysicsLab,
    PhysicsTask,
    RunStreams,
    run_physics_online,
)
from simlab.physics.arena import load_arena
from simlab.physics.motion import PrimitiveParams


def _lattice(n: int = 5, half: float = 0.6) -> Discretizer:
    g = np.linspace(-half, half, n)
    return Discretizer(centres=np.array([(x, y) for y in g[::-1] for x in g]))


# ----------------------------------------------------------------------------- doorways
def _corridor(xy: np.ndarray) -> np.ndarray:
    """Free inside the corridor 0 < x < 4, |y| < 0.4 m, and nowhere else."""
    p = np.asarray(xy, dtype=float)
    return ~((p[..., 0] > 0) & (p[..., 0] < 4) & (np.abs(p[..., 1]) < 0.4))


def test_a_doorway_spans_the_corridor_on_the_bisector() -> None:
    """Two centres along a 0.8 m wide corridor: the doorway is the cross-section at their
    midpoint, 0.8 m of free width (to the 0.01 m sampling), a box 2 x 0.03 m longer, turned
    across the corridor."""
    d = Discretizer(centres=np.array([[1.0, 0.0], [2.0, 0.0], [3.0, 0.0]]))
    door = doorway(_corridor, d.state_of, d.centres, 0, 1)
    assert door.x == pytest.approx(1.5) and door.y == pytest.approx(0.0, abs=0.01)
    assert door.free_width == pytest.approx(0.8, abs=0.011)
    assert door.length == pytest.approx(door.free_width + 0.06)
    assert abs(math.cos(door.yaw)) < 1e-9  # its length runs along y, across the corridor
    # the order of the two states does not move the box
    other = doorway(_corridor, d.state_of, d.centres, 1, 0)
    assert (other.x, other.y, other.free_width) == pytest.approx((door.x, door.y,
                                                                  door.free_width))


def test_cells_that_do_not_touch_have_no_doorway() -> None:
    d = Discretizer(centres=np.array([[1.0, 0.0], [2.0, 0.0], [3.0, 0.0]]))
    with pytest.raises(ConfigError, match="share no free boundary"):
        doorway(_corridor, d.state_of, d.centres, 0, 2)  # state 1 lies between them


# ----------------------------------------------------------------------------- the runs
def _run(experts, n: int, lab: PhysicsLab, task: PhysicsTask, criterion: str = "mb",
         seed: int = 0):
    mf, mb = experts
    ag = meta.make_meta_agent(mf, mb, lab.n_states, lab.n_actions,
                              meta.Arbitration(criterion=criterion))
    return ag, run_physics_online(ag, lab, task, RunStreams.from_seed(
        np.random.SeedSequence(seed)))


def test_a_real_robots_eight_actions_drive_their_headings(experts) -> None:
    """8 actions numbered counter-clockwise from East: every unblocked move heads where its
    action says (within 10 degrees, truth pose), and the agent's tables are (25, 8)."""
    from simlab.base.actions import parse_action_set

    aset = parse_action_set(8, "ccw-east", "fast")
    lab = PhysicsLab(load_arena("table"), _lattice(), PrimitiveParams(),
                     tuple(int(p) for p in aset.primitives()))
    ag, run = _run(experts, 40, lab, PhysicsTask((24,), (12,), 40))
    assert ag.mf.Q.shape == (25, 8)
    log = run.log
    x, y = run.xy[:, 0], run.xy[:, 1]
    prev = np.vstack([[0.0, 0.0], run.xy[:-1]])  # the first decision starts at state 12
    moved = ~run.blocked & (np.hypot(x - prev[:, 0], y - prev[:, 1]) > 0.05)
    moved[1:] &= log.reward[:-1] == 0  # a restart teleports: no move to measure
    heading = np.arctan2(y - prev[:, 1], x - prev[:, 0])
    want = np.radians(45.0) * log.a
    err = np.abs(np.angle(np.exp(1j * (heading - want))))
    assert moved.sum() >= 10 and np.all(np.degrees(err[moved]) < 10)


def test_a_box_stays_through_restarts(experts) -> None:
    """A wall across the whole table at y = -0.3 m from decision 0; start and goal both
    below it (states 22 and 21 of the lower row, y = -0.6 m), moves that drive until the
    state changes: the robot is rewarded and put back at the start again and again, and
    never passes the wall."""
    lab = PhysicsLab(load_arena("table"), _lattice(),
                     PrimitiveParams(mode="until_state_change"))
    task = PhysicsTask((21,), (22,), 80, (PhysicsChange(0, "box",
                                                        box=(0.0, -0.3, 1.6, 0.05)),))
    _, run = _run(experts, 80, lab, task)
    assert run.boxes == [(0.0, -0.3, 1.6, 0.05, 0.0)]
    assert run.log.reward.sum() >= 2  # restarts happened
    assert np.all(run.xy[:, 1] < -0.3)


# ----------------------------------------------------------------------------- the command
@pytest.fixture(scope="module")
def table_states(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _lattice().save(tmp_path_factory.mktemp("arena") / "states.json")


def test_online_in_physics_end_to_end(table_states: Path, tmp_path: Path, capsys) -> None:
    import pyarrow.parquet as pq

    out = tmp_path / "run"
    argv = ["online", "--arena", "table", "--states", str(table_states), "--out", str(out),
            "--decisions", "24", "--seeds", "1", "--criteria", "mb", "entropy_and_cost",
            "--goal", "12", "--start-states", "0", "24", "--change", "passages",
            "--passages", "11-12", "--change-at", "8", "--workers", "1", "--no-progress",
            "--physics-hz", "100"]
    assert main(argv) == 0
    names = {p.name for p in out.iterdir()}
    assert names == {"decisions.parquet", "cumulative_reward.png", "cumulative_cost.png",
                     "mb_share.png", "summary.json", "summary.md", "physics.png",
                     "visits.png"}
    table = pq.read_table(out / "decisions.parquet").to_pandas()
    assert len(table) == 2 * 24 and {"blocked", "duration", "x", "y"} <= set(table.columns)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["states"] == 25 and summary["actions"] == 16
    phys = summary["physics"]
    assert phys["physics_hz"] == 100.0  # the rate asked for, recorded
    for arm, rec in phys["arms"].items():
        rows = table[table.arm == arm]
        assert rec["blocked"] == pytest.approx(rows.blocked.mean())
        assert rec["blocked_after"] == pytest.approx(rows[rows.t >= 8].blocked.mean())
        assert rec["robot_hours"]["mean"] == pytest.approx(rows.duration.sum() / 3600)
    # the box stands on the doorway between the centres of 11 (-0.3, 0) and 12 (0, 0)
    (x, y, length, thick, yaw), = phys["boxes"]
    assert (x, y, thick) == pytest.approx((-0.15, 0.0, 0.05), abs=0.01)
    assert abs(math.cos(yaw)) < 1e-3  # across the line of the two centres
    assert length == pytest.approx(0.3 + 0.06, abs=0.02)  # the cell's side, 0.3 m
    assert "## In physics" in (out / "summary.md").read_text()


def test_a_passage_removed_from_the_command_line(table_states: Path, tmp_path: Path) -> None:
    """``--closing remove``: no box, the passage 11 <-> 12 is never crossed after the
    change, the summary's moves taken back are those of the ``undone`` column."""
    import pyarrow.parquet as pq

    out = tmp_path / "run"
    argv = ["online", "--arena", "table", "--states", str(table_states), "--out", str(out),
            "--decisions", "40", "--seeds", "1", "--criteria", "mb", "--goal", "12",
            "--start-states", "11", "--change", "passages", "--passages", "11-12",
            "--closing", "remove", "--change-at", "4", "--workers", "1", "--no-progress"]
    assert main(argv) == 0
    rows = pq.read_table(out / "decisions.parquet").to_pandas()
    after = rows[rows.t >= 4]
    crossed = after[((after.s == 11) & (after.s_next == 12))
                    | ((after.s == 12) & (after.s_next == 11))]
    assert crossed.empty and after.undone.sum() > 0
    summary = json.loads((out / "summary.json").read_text())
    rec = summary["physics"]["arms"]["mb"]
    assert rec["undone_after"] == pytest.approx(after.undone.mean())
    assert summary["physics"]["boxes"] == []
    assert summary["change"] == "passages 11<->12 closed (transitions removed) at decision 4"
    assert "Moves taken back" in (out / "summary.md").read_text()


@pytest.mark.parametrize(("argv", "key"), [
    (["--arena", "table"], "states"),
    (["MDP", "--arena", "table", "--states", "S"], "mdp"),
    (["MDP", "--primitives", "p.toml"], "primitives"),
    (["MDP", "--n-actions", "8"], "n_actions"),
    (["--arena", "table", "--states", "S", "--goal", "12", "--start-states", "0", "--change",
      "passages", "--passages", "0-24"], "passages"),
    (["--arena", "table", "--states", "S"], "start_states"),  # the default 0, 32 of 38
    (["MDP", "--physics-hz", "100"], "physics_hz"),  # a rate without a world
    (["MDP", "--closing", "remove"], "closing"),  # a closing without a world
    (["--arena", "table", "--states", "S", "--goal", "12", "--start-states", "0",
      "--closing", "remove"], "closing"),  # a closing without passages to close
    (["--arena", "table", "--states", "S", "--goal", "12", "--start-states", "0", "--change",
      "passages", "--passages", "11-12", "--closing", "remove", "--pose-source", "mcl"],
     "takes moves back"),
    (["--arena", "table", "--states", "S", "--goal", "12", "--start-states", "0",
      "--physics-hz", "20"], "minimum is 40 Hz"),
])
def test_bad_arena_options_are_refused(table_states: Path, tmp_path: Path, capsys, argv,
                                       key) -> None:
    argv = [str(table_states) if a == "S" else str(tmp_path / "m.npz") if a == "MDP" else a
            for a in argv]
    assert main(["online", *argv, "--out", str(tmp_path / "o"), "--no-progress"]) != 0
    err = capsys.readouterr().err
    assert key in err
    assert not (tmp_path / "o").exists()


# ----------------------------------------------------------------------------- the protocol
def _published_rules(task: PhysicsTask, change_at: int = -1, **changes):
    """The published loop rules of ``task`` (its first start state first)."""
    from simlab.online.protocol import PROTOCOLS

    return PROTOCOLS["published"].loop_rules(change_at, task.start_states[0])._replace(**changes)


def _until_change_lab() -> PhysicsLab:
    return PhysicsLab(load_arena("table"), _lattice(), PrimitiveParams(mode="until_state_change"))


def _run_rules(experts, n: int, task: PhysicsTask, rules, seed: int = 0):
    mf, mb = experts
    ag = meta.make_meta_agent(mf, mb, 25, 16, meta.Arbitration(criterion="mb"))
    run = run_physics_online(ag, _until_change_lab(), task,
                             RunStreams.from_seed(np.random.SeedSequence(seed)), rules=rules)
    return ag, run


def test_the_published_rules_in_physics(experts) -> None:
    """The environment's published rules (simlab's agent): the run starts in the first
    start state; a rewarded arrival is followed by one decision in the goal whose move is
    the restart (no physics: no time, not blocked) to a start state; the experts learned the
    phantom (s0, 0, 0, s0) first: MF's table is Q-learning replayed over it and the log."""
    task = PhysicsTask((7,), (12, 2), 200)
    ag, run = _run_rules(experts, 200, task, _published_rules(task))
    log = run.log
    assert log.s[0] == 12 and ag.seen[12]
    hits = np.flatnonzero(log.reward > 0)
    assert hits.size >= 2
    for t in hits[hits < 199]:
        assert log.s[t + 1] == 7 and log.s_next[t + 1] in (12, 2)  # the goal's decision
        assert run.duration[t + 1] == 0 and not run.blocked[t + 1]
        assert log.reward[t + 1] == 0
    cont = np.flatnonzero(log.s[:-1] != 7)
    np.testing.assert_array_equal(log.s[cont + 1], log.s_next[cont])  # elsewhere: go on
    Q = np.full((25, 16), 1 / 1.9)
    for s, a, r, s2 in [(12, 0, 0.0, 12), *zip(log.s, log.a, log.reward, log.s_next,
                                               strict=True)]:
        Q[s, a] += 0.6 * (r + 0.9 * Q[s2].max() - Q[s, a])
        if r > 0:
            Q[s2] = 0.0
    np.testing.assert_allclose(ag.mf.Q, Q, rtol=0, atol=1e-12)


def test_the_changes_decision_pays_nothing(experts) -> None:
    """The same seed with and without a silenced decision t*, chosen where the first run
    arrived in the goal: the runs are the same up to t*, whose reward is 0 in the second."""
    task = PhysicsTask((7,), (12,), 150)
    _, a = _run_rules(experts, 150, task, _published_rules(task, silent_at=-1))
    t_star = int(np.flatnonzero(a.log.reward > 0)[1])
    _, b = _run_rules(experts, 150, task, _published_rules(task, silent_at=t_star))
    np.testing.assert_array_equal(a.log.s_next[:t_star + 1], b.log.s_next[:t_star + 1])
    assert a.log.reward[t_star] == 1 and b.log.reward[t_star] == 0
    np.testing.assert_array_equal(a.log.reward[:t_star], b.log.reward[:t_star])


def test_a_run_without_reward_starts_again(experts) -> None:
    """A goal behind a wall across the table cannot be reached: every 6 decisions without a
    reward the run starts again from its first state, the experts keeping what they learned
    (at most max_restarts times)."""
    task = PhysicsTask((2,), (22,), 8, (PhysicsChange(0, "box", box=(0.0, -0.3, 1.6, 0.05)),))
    ag, run = _run_rules(experts, 8, task, _published_rules(task, restart_after=6, max_restarts=3))
    assert run.log.restarts == 3 and run.log.s[0] == 22
    assert run.log.reward.sum() == 0 and ag.seen.sum() >= 1


def test_the_more_used_passage_is_closed(experts) -> None:
    """Two passages with a counting state each: the box goes on the doorway of the one
    whose state saw more decisions before the change, and the counts are those of the log."""
    from simlab.online.doorway import doorway

    passages = ((12, 13), (11, 12))
    task = PhysicsTask((7,), (12,), 24, (PhysicsChange(16, "passages", passages=passages,
                                                       use_states=(13, 11)),))
    _, run = _run_rules(experts, 24, task, None)
    seen = np.bincount(run.log.s[:16], minlength=25)[[13, 11]]
    np.testing.assert_array_equal(run.log.use_counts[1:], seen)
    k = int(np.argmax(seen))
    lat = _lattice()
    door = doorway(load_arena("table").occupied, lat.state_of, lat.centres, *passages[k])
    assert run.boxes == [(door.x, door.y, door.length, door.thickness, door.yaw)]
    assert np.all(run.log.phase[16:] == 1 + k) and np.all(run.log.phase[:16] == 0)
