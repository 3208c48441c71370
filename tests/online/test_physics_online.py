"""Online learning in physics: the driver's transitions feed both experts; changes apply."""

from __future__ import annotations

import numpy as np
import pytest

from discretize.voronoi import Discretizer
from simlab.base.errors import ConfigError
from simlab.online import meta
from simlab.online.physics import (
    PhysicsChange,
    PhysicsLab,
    PhysicsTask,
    RunStreams,
    run_physics_online,
)
from simlab.physics.arena import load_arena
from simlab.physics.motion import PrimitiveParams


def _lattice() -> Discretizer:
    g = np.linspace(-0.6, 0.6, 5)
    return Discretizer(centres=np.array([(x, y) for y in g[::-1] for x in g]))


def _lab() -> PhysicsLab:
    return PhysicsLab(load_arena("table"), _lattice(), PrimitiveParams())


def _run(experts, criterion: str, n: int, changes=(), seed: int = 0, **task):
    mf, mb = experts
    ag = meta.make_meta_agent(mf, mb, 25, 16, meta.Arbitration(criterion=criterion))
    run = run_physics_online(ag, _lab(), PhysicsTask((11, 12, 13), (6, 7, 8), n, changes,
                                                     **task),
                             RunStreams.from_seed(np.random.SeedSequence(seed)))
    return ag, run


def test_transitions_rewards_and_the_passive_observer(experts) -> None:
    changes = (PhysicsChange(12, "goal", goal=(0,)), PhysicsChange(20, "box",
                                                                   box=(0.0, -0.3, 0.4, 0.05)))
    ag, run = _run(experts, "mb", 30, changes)
    log = run.log
    assert np.all(log.expert == meta.EXPERT_MB)
    assert list(log.phase[[0, 11, 12, 19, 20, 29]]) == [0, 0, 1, 1, 2, 2]
    goal = np.where(log.phase == 0, np.isin(log.s_next, (11, 12, 13)), log.s_next == 0)
    np.testing.assert_array_equal(log.reward > 0, goal)
    cont = np.flatnonzero(log.reward[:-1] == 0)
    np.testing.assert_array_equal(log.s[cont + 1], log.s_next[cont])  # no reward: go on
    assert np.all(np.isin(log.s[np.flatnonzero(log.reward[:-1] > 0) + 1], (6, 7, 8)))
    assert run.boxes == [(0.0, -0.3, 0.4, 0.05, 0.0)]  # the box was added to the world
    assert run.robot_seconds > 0 and np.all(log.backups >= 0)
    # MF learned exactly by Q-learning on the transitions MB decided
    Q = np.full((25, 16), 1 / 1.9)
    for s, a, r, s2 in zip(log.s, log.a, log.reward, log.s_next, strict=True):
        Q[s, a] += 0.6 * (r + 0.9 * Q[s2].max() - Q[s, a])
        if r > 0:
            Q[s2] = 0.0
    np.testing.assert_allclose(ag.mf.Q, Q, rtol=0, atol=1e-12)


def test_same_seed_same_run(experts) -> None:
    _, a = _run(experts, "entropy_and_cost", 12, seed=3)
    _, b = _run(experts, "entropy_and_cost", 12, seed=3)
    for col, x in a.log.columns().items():
        if col != "seconds":
            np.testing.assert_array_equal(x, b.log.columns()[col], err_msg=col)
    np.testing.assert_array_equal(a.blocked, b.blocked)


def test_bad_sizes_are_refused(experts) -> None:
    mf, mb = experts
    streams = RunStreams.from_seed(np.random.SeedSequence(0))
    with pytest.raises(ConfigError, match="expected \\(25, 16\\)"):
        run_physics_online(meta.make_meta_agent(mf, mb, 10, 16), _lab(),
                           PhysicsTask((1,), (0,), 1), streams)
    with pytest.raises(ConfigError, match="goal"):
        run_physics_online(meta.make_meta_agent(mf, mb, 25, 16), _lab(),
                           PhysicsTask((30,), (0,), 1), streams)
    with pytest.raises(ConfigError, match="pose_source"):
        PhysicsTask((1,), (0,), 1, pose_source="gps")
    with pytest.raises(ConfigError, match="mcl_map"):
        PhysicsTask((1,), (0,), 1, pose_source="mcl", mcl_map="sometimes")


@pytest.mark.parametrize(("mcl_map", "inside"), [("updated", 0.0), ("stale", None)])
def test_the_mcl_map_follows_the_box_or_stays_stale(experts, mcl_map, inside) -> None:
    """A 0.4 x 0.2 m box at (0, -0.3) is added at decision 2 with the MCL pose source: in
    the updated map the likelihood field's distance at the box's centre is 0 (an obstacle
    there); in the stale map it is the distance to the nearest wall of the empty table
    (the box's centre is 0.45 m from the table's 0.75 m half-width walls, no closer)."""
    box = (0.0, -0.3, 0.4, 0.2)
    _, run = _run(experts, "mb", 4, (PhysicsChange(2, "box", box=box),),
                     pose_source="mcl", mcl_map=mcl_map)
    f = run.mcl_field
    row, col = f.map.world_to_pixel(np.array(box[:2]))
    d = float(f.distance[row, col])
    if inside is not None:
        assert d == inside
    else:
        assert d > 0.3
    assert np.all(np.isfinite(run.log.s)) and run.boxes


def test_a_removed_passage_is_never_crossed_and_its_moves_are_taken_back(experts) -> None:
    """``closing = "remove"`` on the passage 12 <-> 13 (the lattice's centre and its East
    neighbour) from decision 0, the robot starting in 12 and the goal 13: no logged
    transition crosses the passage either way; moves are taken back only from 12 or 13,
    each decision's count at most REDRAWS + 1, the robot staying put (blocked, the same
    state) exactly when every draw crossed; no box enters the world."""
    from simlab.online.physics import REDRAWS

    task = PhysicsTask((13,), (12,), 60, (PhysicsChange(0, "passages", passages=((12, 13),),
                                                        closing="remove"),))
    mf, mb = experts
    ag = meta.make_meta_agent(mf, mb, 25, 16, meta.Arbitration(criterion="mf"))
    run = run_physics_online(ag, _lab(), task, RunStreams.from_seed(np.random.SeedSequence(1)))
    s, s2 = run.log.s, run.log.s_next
    crossed = ((s == 12) & (s2 == 13)) | ((s == 13) & (s2 == 12))
    assert not crossed.any()
    assert run.undone.sum() > 0  # the agent did try the passage
    assert np.all(np.isin(s[run.undone > 0], (12, 13)))
    assert run.undone.max() <= REDRAWS + 1
    stuck = run.undone == REDRAWS + 1
    assert np.all(s2[stuck] == s[stuck]) and np.all(run.blocked[stuck])
    assert run.boxes == []


@pytest.mark.parametrize("params", [
    PrimitiveParams(),
    PrimitiveParams(mode="until_state_change", pose_noise_xy=0.03, pose_noise_yaw=0.02,
                    pose_noise_persistence=0.8),
], ids=["exact pose", "localization error that persists"])
def test_an_undone_move_puts_the_robot_back(params) -> None:
    """hold / undo: after a primitive is taken back the true pose and the believed pose
    are those held before it (the set-down is upright at rest), and so is a persistent
    localization error."""
    lab = PhysicsLab(load_arena("table"), _lattice(), params)
    walker = lab.walker("truth")
    try:
        walker.reset(None, np.random.default_rng(0))
        rng = np.random.default_rng(1)
        walker.step(0, rng)
        held = walker.hold()
        believed = walker.believed_pose().copy()
        out = walker.step(0, rng)
        assert np.linalg.norm(out.truth_after[:2] - held[0][:2]) > 0.05  # it moved
        walker.undo(held)
        np.testing.assert_allclose(walker.world.pose(), held[0], atol=1e-6)
        np.testing.assert_allclose(walker.believed_pose(), believed, atol=1e-9)
        np.testing.assert_array_equal(walker.hold()[2], held[2])
        assert np.any(held[2] != 0) == bool(params.pose_noise_persistence)
    finally:
        walker.close()


def test_removing_a_passage_needs_the_truth_pose() -> None:
    change = PhysicsChange(0, "passages", passages=((12, 13),), closing="remove")
    with pytest.raises(ConfigError, match="takes moves back") as err:
        PhysicsTask((1,), (0,), 1, (change,), pose_source="mcl")
    assert err.value.key == "closing"
    with pytest.raises(ConfigError, match="unknown passage closing"):
        PhysicsChange(0, "passages", passages=((12, 13),), closing="wall")
