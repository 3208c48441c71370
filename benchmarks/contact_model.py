"""Step cost and fidelity of candidate robot-floor contact models, interleaved in one run.

Every candidate is the shipped URDF and :class:`~simlab.physics.world.World` with a few
settings changed (a URDF edit, a PyBullet engine parameter, the solver iterations). For
each one this prints, best of ``--repeats`` runs interleaved across the candidates (the
machine's speed drifts from minute to minute; the best run is the one least disturbed):

* bare: CPU microseconds per ``stepSimulation`` of the robot driving a 0.3 m circle in
  the table arena (the step the pipeline's floor is made of), and its ratio to ``before``
  (the model of the previous release: wheel spinning friction 0.001, implicit cone
  friction, 5 solver iterations);
* wall: the same with the robot pushing its front against a wall (a contact with a wall
  on top of the floor's);
* prim: CPU seconds per simulated second of ``--primitives`` uniformly random motion
  primitives from the table's start (the dataset's workload, the Python around the steps
  included);
* the fidelity figures the physics tests bound: speed error straight at v_max and yaw-rate
  error turning in place at w_max (steady state, relative), the straight run's lateral
  drift (m), the odometry's error after a 3 rad turn in place (relative to the true turn),
  and over the 16 primitives from the centre the largest heading error (deg), length
  error (relative) and lateral offset (m).

``nofloor`` is not a model: it is the robot with its floor contacts filtered out (it floats
in zero gravity), the lower bound of any contact model's bare step.

    python benchmarks/contact_model.py [--repeats 5] [--primitives 150]
                                       [--only before,shipped,...]
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from simlab.base.actions import HEADINGS
from simlab.base.assets import resolve
from simlab.physics.motion import PrimitiveParams, execute_primitive
from simlab.physics.world import World

URDF = resolve("robots", "turtlebot3_burger", ".urdf")


@dataclass(frozen=True)
class Candidate:
    """A contact model: the shipped one with these changes.

    ``urdf``: edits of the URDF tree (applied to a copy); ``engine``: extra
    ``setPhysicsEngineParameter`` keywords after each reset; ``iterations``: solver
    iterations (None: the World default); ``floorless``: filter the floor out (bound only).
    """

    urdf: tuple[Callable[[ET.Element], None], ...] = ()
    engine: dict[str, float] = field(default_factory=dict)
    iterations: int | None = None
    floorless: bool = False


def _wheels(root: ET.Element) -> list[ET.Element]:
    return [link for link in root.iter("link") if link.get("name", "").startswith("wheel_")]


def spinning(value: float) -> Callable[[ET.Element], None]:
    """Set the wheels' spinning (torsional) friction coefficient (m)."""
    def edit(root: ET.Element) -> None:
        for link in _wheels(root):
            link.find("contact/spinning_friction").set("value", repr(value))
    edit.__name__ = f"spinning_{value:g}"
    return edit


def no_housing_collision(root: ET.Element) -> None:
    """Drop the LIDAR housing's collision cylinder (it lies inside the chassis box's
    outline, so floor-standing walls and obstacles meet the box first)."""
    for link in root.iter("link"):
        if link.get("name") == "base_scan":
            for col in link.findall("collision"):
                link.remove(col)


#: The model of the previous release, rebuilt from today's files.
BEFORE = Candidate(urdf=(spinning(0.001),), engine={"enableConeFriction": 1}, iterations=5)

CANDIDATES: dict[str, Candidate] = {
    "before": BEFORE,
    "shipped": Candidate(),
    "nofloor": Candidate(floorless=True),
    "spin0": Candidate(urdf=(spinning(0.0),), engine={"enableConeFriction": 1}, iterations=5),
    "pyramid": Candidate(urdf=(spinning(0.001),), engine={"enableConeFriction": 0},
                         iterations=5),
    "iter3": Candidate(urdf=(spinning(0.001),), engine={"enableConeFriction": 1},
                       iterations=3),
    "nohousing": Candidate(urdf=(spinning(0.001), no_housing_collision),
                           engine={"enableConeFriction": 1}, iterations=5),
    "spin0+iter4": Candidate(urdf=(spinning(0.0),), engine={"enableConeFriction": 1},
                             iterations=4),
    "spin0+iter3": Candidate(urdf=(spinning(0.0),), engine={"enableConeFriction": 1},
                             iterations=3),
    "spin0+nohousing": Candidate(urdf=(spinning(0.0), no_housing_collision),
                                 engine={"enableConeFriction": 1}, iterations=5),
    "spin0+pyramid": Candidate(urdf=(spinning(0.0),), engine={"enableConeFriction": 0},
                               iterations=5),
    "spin0+pyramid+iter3": Candidate(urdf=(spinning(0.0),), engine={"enableConeFriction": 0},
                                     iterations=3),
    "spin0+pyramid+iter2": Candidate(urdf=(spinning(0.0),), engine={"enableConeFriction": 0},
                                     iterations=2),
}


class Bench:
    """Builds worlds of one candidate (its URDF copy is written once)."""

    def __init__(self, name: str, cand: Candidate, tmp: Path) -> None:
        self.cand = cand
        self.robot: str | Path = "turtlebot3_burger"
        if cand.urdf:
            tree = ET.parse(URDF)
            for edit in cand.urdf:
                edit(tree.getroot())
            self.robot = tmp / f"{name.replace('+', '_')}.urdf"
            tree.write(self.robot)

    def world(self) -> World:
        # at 200 Hz with Bullet's contacts, the settings the candidates were measured at
        # (the default rate's own settings are benchmarks/step_size.py's)
        kw = {} if self.cand.iterations is None else {"solver_iterations": self.cand.iterations}
        return World("table", robot=self.robot, physics_hz=200.0, **kw)

    def reset(self, world: World, pose: tuple[float, float, float] | None = None) -> None:
        world.reset(pose)
        c = world.client
        if self.cand.engine:
            c.setPhysicsEngineParameter(**self.cand.engine)
        if self.cand.floorless:
            c.setGravity(0.0, 0.0, 0.0)
            for link in range(-1, c.getNumJoints(world.body)):
                c.setCollisionFilterPair(world.floor, world.body, -1, link, 0)


def step_cost(b: Bench, pose: tuple[float, float, float], v: float, w: float,
              seconds: float = 20.0) -> float:
    """CPU microseconds per bare step driving (v, w) from ``pose``."""
    with b.world() as world:
        b.reset(world, pose)
        world.drive.command(v, w)
        world.step(round(world.physics_hz))
        n = round(seconds * world.physics_hz)
        step = world.client.stepSimulation
        t = time.thread_time()
        for _ in range(n):
            step()
        return (time.thread_time() - t) / n * 1e6


def primitive_cost(b: Bench, n: int, seed: int = 7) -> float:
    """CPU seconds per simulated second of ``n`` random primitives."""
    rng = np.random.default_rng(seed)
    params = PrimitiveParams()
    with b.world() as world:
        b.reset(world)
        t, sim = time.thread_time(), 0.0
        for _ in range(n):
            sim += execute_primitive(world, int(rng.integers(16)), rng, params).duration
        return (time.thread_time() - t) / sim


def _run(world: World, seconds: float) -> np.ndarray:
    rows = []
    for _ in range(round(seconds * world.physics_hz / 4)):
        world.step(4)
        rows.append((world.time, *world.pose()))
    return np.array(rows)


def fidelity(b: Bench) -> dict[str, float]:
    """The figures tests/physics bound (see the module docstring)."""
    f: dict[str, float] = {}
    with b.world() as world:
        b.reset(world, (0.0, -0.62, math.pi / 2))
        world.drive.command(0.22, 0.0)
        r = _run(world, 3.0)
        s = r[:, 0] >= 0.5
        speed = np.hypot(np.diff(r[s, 1]), np.diff(r[s, 2])).sum() / (r[s, 0][-1] - r[s, 0][0])
        f["v err"] = speed / 0.22 - 1
        f["drift m"] = abs(r[-1, 1])
        b.reset(world)
        world.drive.command(0.0, 2.84)
        r = _run(world, 2.0)
        s = r[:, 0] >= 0.25
        rate = np.diff(np.unwrap(r[s, 3])).sum() / (r[s, 0][-1] - r[s, 0][0])
        f["w err"] = rate / 2.84 - 1
        b.reset(world, (0.0, -0.5, math.pi / 2))
        yaw0, odom0 = world.pose()[2], world.odometry()[2]
        world.drive.command(0.0, 1.5)
        _run(world, 2.0)
        world.drive.command(0.0, 0.0)
        _run(world, 0.3)
        turned = math.remainder(world.pose()[2] - yaw0, 2 * math.pi) % (2 * math.pi)
        odom = math.remainder(world.odometry()[2] - odom0, 2 * math.pi) % (2 * math.pi)
        f["odom turn err"] = odom / turned - 1
        params = PrimitiveParams()
        head = dist = lat = 0.0
        for action in range(16):
            b.reset(world)
            res = execute_primitive(world, action, np.random.default_rng(action), params)
            target = float(HEADINGS[action % 8])
            head = max(head, abs(math.degrees(math.remainder(res.pose_after[2] - target,
                                                             2 * math.pi))))
            d = res.pose_after[:2] - res.pose_before[:2]
            dist = max(dist, abs(np.hypot(*d) / params.nominal_distance(action) - 1))
            lat = max(lat, abs(-math.sin(target) * d[0] + math.cos(target) * d[1]))
        f["prim head deg"], f["prim len err"], f["prim lat m"] = head, dist, lat
    return f


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5, help="interleaved runs (best kept)")
    ap.add_argument("--primitives", type=int, default=150, help="random primitives per run")
    ap.add_argument("--only", default=None, help="comma-separated candidate names")
    args = ap.parse_args()
    names = args.only.split(",") if args.only else list(CANDIDATES)
    if "before" not in names:
        names.insert(0, "before")
    with tempfile.TemporaryDirectory() as tmp:
        benches = {n: Bench(n, CANDIDATES[n], Path(tmp)) for n in names}
        bare: dict[str, float] = {}
        wall: dict[str, float] = {}
        prim: dict[str, float] = {}
        for _ in range(args.repeats):
            for n, b in benches.items():
                bare[n] = min(bare.get(n, math.inf), step_cost(b, (0.0, -0.3, 0.0), 0.15, 0.5))
                # facing the east wall (inner face at x = 0.75), front 1 cm from it, pushing
                wall[n] = min(wall.get(n, math.inf),
                              step_cost(b, (0.70, 0.0, 0.0), 0.10, 0.0, 10.0))
                if not b.cand.floorless:
                    prim[n] = min(prim.get(n, math.inf), primitive_cost(b, args.primitives))
        fid = {n: fidelity(b) for n, b in benches.items() if not b.cand.floorless}
    cols = list(next(iter(fid.values())))
    print(f"{'candidate':<20} {'bare us':>8} {'x before':>8} {'wall us':>8} {'x before':>8} "
          f"{'prim CPU/s':>10} {'x before':>8} " + " ".join(f"{c:>13}" for c in cols))
    for n in names:
        p = (f"{prim[n]:10.4f} {prim[n] / prim['before']:8.2f}" if n in prim
             else f"{'-':>10} {'-':>8}")
        figs = " ".join(f"{fid[n][c]:13.4f}" for c in cols) if n in fid else ""
        print(f"{n:<20} {bare[n]:8.1f} {bare[n] / bare['before']:8.2f} {wall[n]:8.1f} "
              f"{wall[n] / wall['before']:8.2f} {p} {figs}")


if __name__ == "__main__":
    main()
