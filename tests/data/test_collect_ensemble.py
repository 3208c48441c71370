"""``simlab collect --primitives FILE --ensemble``: each walk drives a member of the twin
ensemble, drawn by seed, recorded in the manifest and on every row (physics, 64
transitions per walk set)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from simlab.data.collect import collect
from simlab.data.dataset import read_dataset
from simlab.physics.motion import PrimitiveParams
from simlab.physics.primitive_options import ensemble_members
from tests.faults.conftest import assert_refused, run_cli
from tests.physics.conftest import ensemble_lab

#: two clearly different robots: the second turns in place at 0.4 rad/s, not 2.84
QUICK, SLOW = PrimitiveParams(), PrimitiveParams(turn_rate=0.4)
STARTS = "0,3,6,9,12,15,18,21"
WALKS = 8


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    return ensemble_lab(tmp_path_factory.mktemp("ens"), (QUICK, SLOW))


def _collect(lab: tuple[Path, Path], out: Path, workers: int) -> Path:
    states, prims = lab
    collect("table", states, out=out, transitions=8 * WALKS, seed=0, workers=workers,
            part_size=4, start_states=STARTS, primitives=prims, ensemble=True,
            progress=False)
    return out


@pytest.fixture(scope="module")
def walk(lab: tuple[Path, Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _collect(lab, tmp_path_factory.mktemp("walk") / "d", workers=1)


def test_each_walk_drives_the_member_drawn_for_it(walk: Path) -> None:
    params = json.loads((walk / "_manifest.json").read_text())["parameters"]
    ens = params["ensemble"]
    assert ens["size"] == 2 and ens["walk_members"] == ensemble_members(0, WALKS, 2)
    assert set(ens["walk_members"]) == {0, 1}  # seed 0 draws both robots
    assert [PrimitiveParams.from_json(m) for m in ens["members"]] == [QUICK, SLOW]
    assert PrimitiveParams.from_json(params["primitive"]) == QUICK  # the [primitives] table
    table = read_dataset(walk)
    worker = table.column("worker").to_numpy()
    member = table.column("twin_member").to_numpy()
    np.testing.assert_array_equal(member, np.asarray(ens["walk_members"])[worker])
    field = table.schema.field("twin_member")
    assert field.metadata[b"unit"] == b"1" and b"ensemble" in field.metadata[b"description"]


def test_the_slower_members_walks_take_longer(walk: Path) -> None:
    """A property of the members, not a tuned number: every walk of the robot that turns
    slowly has a longer mean primitive than every walk of the quick one."""
    table = read_dataset(walk)
    worker = table.column("worker").to_numpy()
    duration = table.column("duration").to_numpy()
    member = table.column("twin_member").to_numpy()
    means = {w: (int(member[worker == w][0]), duration[worker == w].mean())
             for w in range(WALKS)}
    slow = [d for m, d in means.values() if m == 1]
    quick = [d for m, d in means.values() if m == 0]
    assert min(slow) > max(quick)


@pytest.mark.parametrize("workers", [1, 2])
def test_the_same_seed_gives_the_same_dataset_with_any_workers(
        walk: Path, lab: tuple[Path, Path], tmp_path: Path, workers: int) -> None:
    again = _collect(lab, tmp_path / "again", workers=workers)
    assert read_dataset(again).equals(read_dataset(walk))
    first, second = (json.loads((d / "_manifest.json").read_text())["parameters"]["ensemble"]
                     for d in (walk, again))
    assert first == second


def test_a_resumed_collection_keeps_each_walks_member(walk: Path, lab: tuple[Path, Path],
                                                     tmp_path: Path) -> None:
    """Killed with the second part of walks 1 (slow) and 2 (quick) unwritten, then resumed
    on two workers: the walks go on with their own members, the dataset as uninterrupted."""
    import shutil

    out = tmp_path / "d"
    shutil.copytree(walk, out)
    manifest = json.loads((out / "_manifest.json").read_text())
    assert [manifest["parameters"]["ensemble"]["walk_members"][w] for w in (1, 2)] == [1, 0]
    lost = [e for e in manifest["parts"] if e["worker"] in (1, 2) and e["part"] == 1]
    for e in lost:
        (out / e["file"]).unlink()
    manifest["parts"] = [e for e in manifest["parts"] if e not in lost]
    manifest["complete"] = False
    (out / "_manifest.json").write_text(json.dumps(manifest))
    states, prims = lab
    res = collect("table", states, out=out, transitions=8 * WALKS, seed=0, workers=2,
                  part_size=4, start_states=STARTS, primitives=prims, ensemble=True,
                  resume=True, progress=False)
    assert res.parts_written == 2 and res.complete
    assert read_dataset(out).equals(read_dataset(walk))


@pytest.mark.parametrize(("extra", "needles"), [
    ("--ensemble", ("ensemble", "add --primitives")),
    ("--ensemble --primitives PLAIN", ("no twin ensemble", "within sampling of the winner",
                                       "without --ensemble")),
])
def test_ensemble_without_an_ensemble_file_is_refused(
        lab: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str],
        extra: str, needles: tuple[str, ...]) -> None:
    plain = tmp_path / "plain.toml"
    plain.write_text(QUICK.toml_text())
    args = (f"collect --arena table --states {lab[0]} --transitions 8 --no-progress "
            f"--out {tmp_path}/o {extra}").replace("PLAIN", str(plain)).split()
    assert_refused(run_cli(args, capsys), *needles)
    assert not (tmp_path / "o").exists()
