"""Fixtures of the fault corpus: one tiny, complete set of inputs, built once.

Everything is cheap: a 25-state lattice on the table, a kinematic walk of 300
transitions, an MDP estimated from it, Q-tables of a 3-episode training, a map made from
the arena's geometry. Each test copies what it damages into its own folder and checks
that every file that existed before the command is byte-identical afterwards.
"""

from __future__ import annotations

import hashlib
import math
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from discretize.voronoi import Discretizer


@dataclass(frozen=True)
class Inputs:
    root: Path
    states: Path          # 25-state lattice on the table (JSON)
    other_states: Path    # 25 states of a 4 m square: the wrong arena
    dataset: Path         # kinematic walk, 300 transitions, complete
    mdp: Path             # estimated from the dataset, with goals
    qtables: Path         # `simlab train` output (3 episodes, 1 run, no plots)
    counts: Path          # a valid counts CSV
    map_yaml: Path        # map of the table (from its geometry)
    log: Path             # pose log 't x y yaw' of 8 decisions on the table (2 Hz)


def pose_log_lines(cells: bool = False) -> list[str]:
    """A 2 Hz pose log on the table: 8 decisions, each a quarter turn in place (1 s) then
    a 0.2 m drive at 0.1 m/s (2 s), then a 1 s pause; a square walked twice from (-0.2,
    -0.2). ``cells``: add the columns ``cell n_cells`` of the 25-state lattice."""
    lattice = _lattice(0.6)
    t, x, y, yaw = 0.0, -0.2, -0.2, 0.0
    rows = [(t, x, y, yaw)]
    for k in range(8):
        target = (k + 1) * math.pi / 2
        for f in (0.5, 1.0):  # the turn
            t += 0.5
            rows.append((t, x, y, yaw + f * (target - yaw)))
        yaw = target
        for _ in range(4):  # the drive
            t += 0.5
            x, y = x + 0.05 * math.cos(yaw), y + 0.05 * math.sin(yaw)
            rows.append((t, x, y, yaw))
        for _ in range(2):  # the pause
            t += 0.5
            rows.append((t, x, y, yaw))
    out = []
    for t, x, y, a in rows:
        a = math.atan2(math.sin(a), math.cos(a))
        line = f"{t:.1f} {x:.4f} {y:.4f} {a:.4f}"
        if cells:
            line += f" {int(lattice.state_of(np.array([[x, y]]))[0])} 25"
        out.append(line)
    return out


def _lattice(half: float) -> Discretizer:
    g = np.linspace(-half, half, 5)
    return Discretizer(centres=np.array([(x, y) for y in g[::-1] for x in g]))


@pytest.fixture(scope="session")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> Inputs:
    from simlab.data.collect import collect
    from simlab.data.estimate import estimate
    from simlab.localization.maps import arena_map
    from simlab.physics.arena import load_arena
    from simlab.training.train import train

    root = tmp_path_factory.mktemp("faults-inputs")
    states = _lattice(0.6).save(root / "states.json")
    other = _lattice(2.0).save(root / "other_states.json")
    collect(arena="table", states=states, out=root / "data", transitions=300, seed=3,
            workers=1, part_size=100, simulator="kinematic", progress=False)
    estimate(root / "data", root / "mdp.npz", plot=False)
    with pytest.warns(UserWarning):
        train(root / "mdp.npz", "vi-softmax", "all", episodes=3, runs=1, seed=0,
              out=root / "q", plots=False, progress=False)
    counts = root / "counts.csv"
    counts.write_text("s,a,s_next,count\n0,0,1,3\n1,3,0,2\n2,15,2,1\n")
    from discretize.mapio import write_map

    write_map(root / "map" / "map.yaml", arena_map(load_arena("table"), 0.02))
    (root / "log.txt").write_text("# t x y yaw\n" + "\n".join(pose_log_lines()) + "\n")
    return Inputs(root=root, states=states, other_states=other, dataset=root / "data",
                  mdp=root / "mdp.npz", qtables=root / "q", counts=counts,
                  map_yaml=root / "map" / "map.yaml", log=root / "log.txt")


def tree_hashes(root: Path) -> dict[str, str]:
    """sha256 of every file under ``root`` (relative names)."""
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.fixture()
def work(tmp_path: Path, inputs: Inputs) -> Path:
    """A private copy of the inputs that a test may damage (cwd for the command)."""
    dst = tmp_path / "w"
    shutil.copytree(inputs.root, dst)
    return dst


@dataclass
class Outcome:
    code: int
    stderr: str
    stdout: str

    @property
    def error_lines(self) -> list[str]:
        return [ln for ln in self.stderr.splitlines() if ": error: " in ln
                or ": internal error: " in ln]


def run_cli(argv: list[str], capsys: pytest.CaptureFixture[str]) -> Outcome:
    """``simlab argv`` in this process; returns the exit code and the captured output."""
    from simlab.cli import main

    capsys.readouterr()
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse
        code = exc.code if isinstance(exc.code, int) else 2
    out = capsys.readouterr()
    return Outcome(code=code, stderr=out.err, stdout=out.out)


def assert_refused(res: Outcome, *needles: str, code: int = 2) -> None:
    """Exit ``code``, no traceback, exactly one error line, naming every needle."""
    assert "Traceback" not in res.stderr, res.stderr
    assert res.code == code, (res.code, res.stderr)
    lines = res.error_lines if code != 130 else [ln for ln in res.stderr.splitlines()
                                                 if "interrupted" in ln]
    if code == 2 and not lines:  # argparse usage errors: "simlab X: error: ..." via usage
        lines = [ln for ln in res.stderr.splitlines() if "error:" in ln]
    assert len(lines) == 1, res.stderr
    for needle in needles:
        assert needle.lower() in lines[0].lower(), (needle, lines[0])


PYTHON = sys.executable


def failing(err: int, nth: int, real):
    """``real`` (``os.fsync``, ``tempfile.mkstemp``, ...) that raises ``OSError(err)`` from
    its ``nth`` call on (1: the very first write fails; 3: after two files were written)."""
    import os

    calls = {"n": 0}

    def fake(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] >= nth:
            raise OSError(err, os.strerror(err))
        return real(*args, **kwargs)

    return fake


def writes_file(name: str, data: str | bytes):
    """A case's setup: write ``data`` (text or bytes) to ``name`` inside the test's copy of
    the inputs (parents made)."""

    def setup(w: Path) -> None:
        p = w / name
        p.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(data, bytes):
            p.write_bytes(data)
        else:
            p.write_text(data)

    return setup
