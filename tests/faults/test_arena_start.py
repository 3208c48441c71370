"""An arena whose start puts the robot off the floor, in an obstacle or with its body through
a box or a wall is refused at load, naming the file, the key and what is wrong."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.faults.conftest import assert_refused, run_cli


def _arena(work: Path, start: str, clearance: str = "") -> Path:
    path = work / "a.toml"
    path.write_text('name = "a"\n[floor]\nsize = [1.5, 1.5]\n[walls]\nheight = 0.25\n'
                    'thickness = 0.05\n'
                    f'[start]\npose = [{start}, 90.0]\n{clearance}'
                    '[[obstacles]]\nkind = "box"\ncenter = [0.3, 0.3]\nsize = [0.2, 0.2]\n'
                    'height = 0.3\n[[goals]]\nname = "G"\ncenter = [-0.4, -0.4]\n'
                    'radius = 0.1\n')
    return path


@pytest.mark.parametrize(("start", "needles"), [
    ("2.0, 0.0", ("start.pose", "outside the floor")),
    ("0.3, 0.3", ("start.pose", "inside an obstacle")),
    ("0.3, 0.16", ("start.pose", "would overlap a wall or obstacle")),  # body in the box
    ("0.7, 0.0", ("start.pose", "would overlap a wall or obstacle")),   # body in the wall
])
def test_a_start_that_puts_the_robot_in_a_box_or_off_the_floor_is_named(
        work: Path, capsys, start: str, needles: tuple[str, ...]) -> None:
    arena = _arena(work, start)
    res = run_cli(f"drive --arena {arena} --steps 2".split(), capsys)
    assert_refused(res, "a.toml", *needles)


def _states_in_obstacles(work: Path) -> Path:
    """A 25-state lattice of the table with two centres moved into table_obstacles' box
    (-0.22, 0.22) and cylinder (0.24, -0.22): 2 of 25 (8 %) only warn."""
    import numpy as np

    from discretize.voronoi import Discretizer

    g = np.linspace(-0.6, 0.6, 5)
    centres = np.array([(x, y) for y in g[::-1] for x in g])
    centres[6] = (-0.22, 0.22)
    centres[18] = (0.24, -0.22)
    return Discretizer(centres=centres).save(work / "s.json")


def test_walks_from_states_whose_centre_is_in_an_obstacle_start_where_the_robot_fits(
        work: Path, capsys) -> None:
    """``collect --arena table_obstacles --start-states 6,18``: both centres lie inside an
    obstacle. Each walk starts at the nearest place of its state where the robot's body
    fits (said in a warning), so the first transition is a move the robot can make, not
    the engine ejecting it (0.57 m in 1.2 s before)."""
    import numpy as np

    from simlab.data.dataset import read_dataset
    from simlab.physics.arena import load_arena
    from simlab.physics.robot import load_robot_spec

    states = _states_in_obstacles(work)
    res = run_cli(f"collect --arena table_obstacles --states {states} --start-states 6,18 "
                  f"--transitions 6 --seed 1 --out {work}/o --no-progress".split(), capsys)
    assert res.code == 0, res.stderr
    for s in (6, 18):
        assert f"start state {s}: the robot does not fit at its centre" in res.stderr
    tab = read_dataset(work / "o")
    arena, spec = load_arena("table_obstacles"), load_robot_spec()
    from discretize.voronoi import load_states

    disc = load_states(states)
    for w, s in enumerate((6, 18)):
        rows = tab.filter(tab.column("worker").to_numpy() == w)
        x, y = rows.column("x").to_numpy(), rows.column("y").to_numpy()
        assert rows.column("s").to_numpy()[0] == s  # it starts in its state
        assert not arena.occupied(np.array([x[0], y[0]]))
        jump = np.hypot(rows.column("x_next").to_numpy() - x, rows.column("y_next").to_numpy() - y)
        # a primitive drives at most v_max for its duration (plus the turn's wobble)
        assert np.all(jump <= spec.v_max * rows.column("duration").to_numpy() + 0.02), jump
        centre = disc.centres[s]
        assert 0.05 < np.hypot(x[0] - centre[0], y[0] - centre[1]) < 0.3


def test_a_start_state_where_the_robot_fits_nowhere_is_refused(work: Path, capsys) -> None:
    """A state whose whole cell lies inside the box: refused before anything is written,
    naming the state and the fix."""
    import numpy as np

    from discretize.voronoi import Discretizer

    g = np.linspace(-0.6, 0.6, 5)
    centres = np.array([(x, y) for y in g[::-1] for x in g])
    # a state at the box's centre hemmed in by four free ones just outside the box (x -0.34
    # .. -0.10, y 0.17 .. 0.27): its cell lies inside the box; 1 of 30 centres only warns
    extra = np.array([[-0.22, 0.22], [-0.38, 0.22], [-0.06, 0.22], [-0.22, 0.31],
                      [-0.22, 0.13]])
    states = Discretizer(centres=np.vstack([centres, extra])).save(work / "s.json")
    before = {p.name for p in work.iterdir()}
    res = run_cli(f"collect --arena table_obstacles --states {states} --start-states 25 "
                  f"--transitions 6 --out {work}/o --no-progress".split(), capsys)
    assert_refused(res, "s.json", "start_states", "start state 25", "fits nowhere",
                   "leave state 25 out of --start-states")
    assert {p.name for p in work.iterdir()} == before
