"""``simlab online --arena ... --primitives FILE --ensemble``: each run drives a member of the
twin ensemble drawn by seed, the same in every arm, and the summary says which."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from simlab.cli import main
from simlab.physics.motion import PrimitiveParams
from simlab.physics.primitive_options import ensemble_members
from tests.faults.conftest import assert_refused, run_cli
from tests.physics.conftest import ensemble_lab

#: two clearly different robots: the second turns in place at 0.4 rad/s, not 2.84
QUICK, SLOW = PrimitiveParams(), PrimitiveParams(turn_rate=0.4)
SEEDS = 4


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    return ensemble_lab(tmp_path_factory.mktemp("ens"), (QUICK, SLOW))


def _argv(lab: tuple[Path, Path], out: Path, *extra: str) -> list[str]:
    states, prims = lab
    return ["online", "--arena", "table", "--states", str(states), "--goal", "12",
            "--start-states", "0", "--decisions", "6", "--seeds", str(SEEDS), "--criteria",
            "mb", "mf", "--workers", "1", "--no-plots", "--no-progress", "--out", str(out),
            "--primitives", str(prims), *extra]


def test_each_run_drives_its_drawn_member_in_every_arm(lab: tuple[Path, Path],
                                                       tmp_path: Path) -> None:
    import pyarrow.parquet as pq

    out = tmp_path / "run"
    assert main(_argv(lab, out, "--ensemble")) == 0
    summary = json.loads((out / "summary.json").read_text())
    ens = summary["physics"]["ensemble"]
    members = ensemble_members(0, SEEDS, 2)
    assert ens == {"size": 2, "run_members": members}
    assert set(members) == {0, 1}  # seed 0 draws both robots
    assert "Twin ensemble of 2 members" in (out / "summary.md").read_text()
    # the slow robot's runs take longer per decision, in both arms (the same latency)
    table = pq.read_table(out / "decisions.parquet").to_pandas()
    for _, rows in table.groupby("arm"):
        per_run = rows.groupby("seed").duration.mean()
        slow = [per_run[i] for i in range(SEEDS) if members[i] == 1]
        quick = [per_run[i] for i in range(SEEDS) if members[i] == 0]
        assert min(slow) > max(quick)
    # without --ensemble every run drives the [primitives] table: no ensemble recorded
    plain = tmp_path / "plain"
    assert main(_argv(lab, plain)) == 0
    assert "ensemble" not in json.loads((plain / "summary.json").read_text())["physics"]


@pytest.mark.parametrize(("extra", "needles"), [
    ("--ensemble", ("ensemble", "add --primitives")),
    ("--ensemble --primitives PLAIN", ("no twin ensemble", "without --ensemble")),
])
def test_ensemble_without_an_ensemble_file_is_refused(
        lab: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str],
        extra: str, needles: tuple[str, ...]) -> None:
    plain = tmp_path / "plain.toml"
    plain.write_text(QUICK.toml_text())
    argv = _argv(lab, tmp_path / "o")
    argv = argv[:argv.index("--primitives")]  # the file of each case only
    argv += extra.replace("PLAIN", str(plain)).split()
    assert_refused(run_cli(argv, capsys), *needles)
    assert not (tmp_path / "o").exists()


def test_ensemble_on_an_mdp_is_refused(tmp_path: Path, capsys) -> None:
    res = run_cli(["online", str(tmp_path / "m.npz"), "--ensemble", "--out",
                   str(tmp_path / "o"), "--no-progress"], capsys)
    assert_refused(res, "--ensemble applies to a run in physics only")
