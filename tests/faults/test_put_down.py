"""One rule sets the robot down wherever a command or an env puts it: where it fits.

``online --arena table_obstacles --start-states 6`` with state 6's centre inside the box
put the robot at that centre at every restart (the engine then ejected it), while
``collect`` already moved such a start to the nearest place of the state where the robot
fits. Now the online restarts, the replay's start and the envs' resets follow the same
rule (:func:`simlab.base.statecheck.put_down`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.faults.conftest import run_cli


def _states_in_the_box() -> object:
    """A 25-state lattice of the table with centre 6 moved into table_obstacles' box
    (-0.22, 0.22); 1 of 25 only warns."""
    from discretize.voronoi import Discretizer

    g = np.linspace(-0.6, 0.6, 5)
    centres = np.array([(x, y) for y in g[::-1] for x in g])
    centres[6] = (-0.22, 0.22)
    return Discretizer(centres=centres)


def _fits(pose: np.ndarray, arena: object) -> bool:
    from simlab.base.statecheck import _fits
    from simlab.physics.robot import load_robot_spec

    return bool(_fits(np.asarray(pose[:2], float)[None, :], load_robot_spec().footprint,
                      arena, float(pose[2]))[0])


@pytest.mark.parametrize("yaw", [0.0, 1.2, np.pi, -2.0])
def test_an_online_restart_in_a_state_whose_centre_is_in_a_box_puts_the_robot_where_it_fits(
        yaw: float) -> None:
    from simlab.online.physics import PhysicsLab, PhysicsTask, RunStreams, _Lab
    from simlab.physics.arena import load_arena
    from simlab.physics.motion import PrimitiveParams

    arena, disc = load_arena("table_obstacles"), _states_in_the_box()
    lab = PhysicsLab(arena, disc, PrimitiveParams())
    run = _Lab(lab, PhysicsTask((12,), (6,), 4, ()), RunStreams.from_seed(
        np.random.SeedSequence(0)))
    try:
        run.walker.place(np.array([0.4, -0.5, yaw]), run.streams.mcl)  # the heading kept
        assert run.restart() == 6
        pose = run.walker.world.pose()
        assert _fits(pose, arena), pose
        assert abs(pose[2] - yaw) < 1e-6
        assert int(disc.state_of(pose[:2])) == 6
        assert 0.05 < np.hypot(pose[0] + 0.22, pose[1] - 0.22) < 0.3
    finally:
        run.close()


def test_online_says_where_a_start_state_puts_the_robot_once(tmp_path: Path, capsys) -> None:
    states = _states_in_the_box().save(tmp_path / "s.json")
    res = run_cli(f"online --arena table_obstacles --states {states} --criteria mf "
                  f"--goal 12 --start-states 6 --decisions 6 --seeds 1 --workers 1 "
                  f"--no-plots --out {tmp_path}/o".split(), capsys)
    assert res.code == 0, res.stderr
    assert res.stderr.count("start state 6: the robot does not fit at its centre") == 1, \
        res.stderr


def test_an_env_reset_at_a_pose_in_a_box_puts_the_robot_where_it_fits() -> None:
    from simlab.envs.table_arena import TableArenaEnv

    env = TableArenaEnv("table_obstacles")
    try:
        with pytest.warns(UserWarning, match=r"the reset pose \(-0.22, 0.22\) m: the robot "
                          "does not fit there"):
            obs, _ = env.reset(seed=0, options={"pose": (-0.22, 0.22, 0.5)})
        pose = env.world.pose()
        assert _fits(pose, env.arena), pose
        assert np.allclose(obs["pose"][:2], pose[:2], atol=1e-5)
        assert 0.05 < np.hypot(pose[0] + 0.22, pose[1] - 0.22) < 0.25
        env.reset(seed=0)  # the arena's start fits: unchanged
        assert np.allclose(env.world.pose(), env.arena.start, atol=1e-6)
    finally:
        env.close()


def test_a_replay_starts_where_the_robot_fits(tmp_path: Path) -> None:
    """An arena whose lowered ``[start] clearance`` lets the robot's tail (0.10 m behind
    the wheels) into a box: the replay starts, drives back to and localizes from the
    nearest place where it fits."""
    from simlab.physics.arena import load_arena
    from simlab.replay.config import ReplayConfig
    from simlab.replay.replay import _load_inputs

    path = tmp_path / "a.toml"
    path.write_text('name = "a"\n[floor]\nsize = [1.5, 1.5]\n[walls]\nheight = 0.25\n'
                    'thickness = 0.05\n[start]\npose = [0.3, 0.16, -90.0]\nclearance = 0.0\n'
                    '[[obstacles]]\nkind = "box"\ncenter = [0.3, 0.3]\nsize = [0.2, 0.2]\n'
                    'height = 0.3\n[[goals]]\nname = "G"\ncenter = [-0.4, -0.4]\n'
                    'radius = 0.1\n')
    arena = load_arena(path)
    assert not _fits(np.asarray(arena.start), arena)
    states = _states_in_the_box().save(tmp_path / "s.json")
    with pytest.warns(UserWarning, match="the start pose of arena 'a'"):
        inp = _load_inputs(ReplayConfig(arena=str(path), states=str(states), policy="random",
                                        out=str(tmp_path / "o")))
    start = np.asarray(inp.arena.start)
    assert _fits(start, inp.arena) and start[2] == arena.start[2]
    assert np.hypot(*(start[:2] - arena.start[:2])) < 0.1
