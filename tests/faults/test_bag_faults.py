"""The fault corpus of the ROS bag commands (``export-bag``, ``import-bag``): damaged bags,
outputs in the way or equal to an input, full disks, a killed run, two writers.

Every case: exit 2, one line naming the user's file (never simlab's staging folders) and a
fix that works, and every file that existed before byte-identical afterwards.
"""

from __future__ import annotations

import errno
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags")

from .conftest import Inputs, assert_refused, failing, run_cli, tree_hashes


@pytest.fixture(scope="module")
def bag(inputs: Inputs, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``simlab export-bag`` of the corpus dataset (no scans: faster, same topics else)."""
    from simlab.ros.export import export_bag

    return export_bag(inputs.dataset, tmp_path_factory.mktemp("bag") / "bag",
                      scans=False).out


@pytest.fixture()
def wb(work: Path, bag: Path) -> Path:
    """The private work folder with the bag copied in as ``bag``."""
    shutil.copytree(bag, work / "bag")
    return work


def _unchanged(before: dict[str, str], root: Path) -> None:
    after = tree_hashes(root)
    assert {k: after.get(k) for k in before} == before


def _no_staging(root: Path) -> None:
    left = [p for p in root.rglob("*") if ".simlab" in p.name]
    assert not left, left


def _mcap(bag: Path) -> Path:
    return next(bag.glob("*.mcap"))


# ------------------------------------------------------------------ export-bag outputs
@pytest.mark.parametrize("out", ["data", "data/parts", ".", "map", "map/map.yaml"])
def test_export_bag_output_may_not_equal_or_contain_an_input(out: str, wb: Path, capsys
                                                             ) -> None:
    """``--out`` the source dataset (data loss before), inside it, holding it, or the
    ``--map`` given: refused even with ``--overwrite``."""
    before = tree_hashes(wb)
    res = run_cli(["export-bag", str(wb / "data"), "--out", str(wb / out), "--overwrite",
                   "--no-scans", "--map", str(wb / "map" / "map.yaml")], capsys)
    assert_refused(res, "overlaps", "choose an --out outside the inputs")
    _unchanged(before, wb)
    assert sorted(tree_hashes(wb)) == sorted(before)


@pytest.mark.parametrize("kind", ["folder", "file", "dataset"])
def test_export_bag_overwrite_replaces_only_a_bag_it_wrote(kind: str, wb: Path, capsys
                                                           ) -> None:
    """A folder holding notes (its content was deleted before), a file, another command's
    output: never replaced, and the message does not suggest --overwrite."""
    target = {"folder": wb / "notes", "file": wb / "counts.csv", "dataset": wb / "q"}[kind]
    if kind == "folder":
        target.mkdir()
        (target / "notes.txt").write_text("field notes\n")
    before = tree_hashes(wb)
    res = run_cli(["export-bag", str(wb / "data"), "--out", str(target), "--overwrite",
                   "--no-scans"], capsys)
    assert_refused(res, str(target), "never replaced", "choose another --out")
    assert "pass --overwrite" not in res.stderr
    _unchanged(before, wb)


def test_export_bag_hint_to_overwrite_works_and_replaces_the_bag(wb: Path, capsys) -> None:
    from simlab.ros.bag import read_bag

    before = tree_hashes(wb)
    res = run_cli(["export-bag", str(wb / "data"), "--out", str(wb / "bag"), "--no-scans"],
                  capsys)
    assert_refused(res, str(wb / "bag"), "pass --overwrite")
    _unchanged(before, wb)
    res = run_cli(["export-bag", str(wb / "data"), "--out", str(wb / "bag"), "--no-scans",
                   "--overwrite", "--start-time", "100"], capsys)
    assert res.code == 0, res.stderr
    assert read_bag(wb / "bag").t[0] == pytest.approx(0.0)  # the new bag, read back
    from simlab.ros.bag import read_metadata

    assert read_metadata(wb / "bag")["starting_time"]["nanoseconds_since_epoch"] == 100 * 10**9
    others = {k: v for k, v in before.items() if not k.startswith("bag/")}
    _unchanged(others, wb)
    _no_staging(wb)


@pytest.mark.parametrize("case", ["existing-bag", "folder", "overlap", "parent-file"])
def test_export_bag_refuses_before_any_work(case: str, wb: Path, capsys, monkeypatch
                                            ) -> None:
    """The output is checked before the source is read or a scan is cast."""
    import simlab.ros.export as export

    def never(*args, **kwargs):
        raise AssertionError("the work started before the output was checked")

    monkeypatch.setattr(export, "_from_dataset", never)
    monkeypatch.setattr(export, "_scans", never)
    (wb / "notes").mkdir()
    (wb / "notes" / "a.txt").write_text("x")
    out = {"existing-bag": wb / "bag", "folder": wb / "notes", "overlap": wb / "data",
           "parent-file": wb / "counts.csv" / "bag"}[case]
    before = tree_hashes(wb)
    res = run_cli(["export-bag", str(wb / "data"), "--out", str(out)], capsys)
    assert_refused(res, "--out")
    _unchanged(before, wb)


# ------------------------------------------------------------------ import-bag inputs
def _truncate(bag: Path) -> None:
    m = _mcap(bag)
    m.write_bytes(m.read_bytes()[: m.stat().st_size // 2])


def _garbage(bag: Path) -> None:
    _mcap(bag).write_bytes(np.random.default_rng(0).bytes(4000))


def _empty_mcap(bag: Path) -> None:
    _mcap(bag).write_bytes(b"")


def _yaml(text: str | bytes):
    def edit(bag: Path) -> None:
        p = bag / "metadata.yaml"
        p.write_bytes(text) if isinstance(text, bytes) else p.write_text(text)
    return edit


def _no_metadata(bag: Path) -> None:
    for p in bag.iterdir():
        p.unlink()


BAD_BAGS = {
    "truncated-mcap": (_truncate, [], "bag", "mcap recover"),
    "garbage-mcap": (_garbage, [], "bag", "not a readable ROS 2 bag"),
    "empty-mcap": (_empty_mcap, [], "bag", "empty"),
    "yaml-syntax": (_yaml("rosbag2_bagfile_information: [\n"), [], "bag/metadata.yaml",
                    "not valid YAML"),
    "yaml-not-a-bag": (_yaml("- 1\n- 2\n"), [], "bag/metadata.yaml",
                       "rosbag2_bagfile_information"),
    "yaml-missing-keys": (_yaml("rosbag2_bagfile_information:\n  version: 9\n"), [], "bag",
                          "relative_file_paths"),
    "yaml-binary": (_yaml(b"\xff\xfe\x00\x01"), [], "bag/metadata.yaml", "not a text file"),
    "empty-folder": (_no_metadata, [], "bag", "no metadata.yaml"),
    "no-pose-topic": (None, ["--pose-topic", "/base_pose"], "bag", "/base_pose"),
    "pose-topic-not-a-pose": (None, ["--pose-topic", "/simlab/action"], "bag",
                              "not a pose"),
}


@pytest.mark.parametrize("case", list(BAD_BAGS))
def test_import_bag_of_a_bad_bag_is_one_line_naming_it(case: str, wb: Path, capsys) -> None:
    damage, extra, needle, what = BAD_BAGS[case]
    if damage is not None:
        damage(wb / "bag")
    before = tree_hashes(wb)
    res = run_cli(["import-bag", str(wb / "bag"), "--states", str(wb / "states.json"),
                   "--out", str(wb / "ds"), *extra], capsys)
    assert_refused(res, str(wb / needle), what)
    assert "TypeError" not in res.stderr and "internal error" not in res.stderr
    _unchanged(before, wb)
    assert not (wb / "ds").exists()


@pytest.mark.parametrize("path", ["nowhere", "bag/metadata.yaml"])
def test_import_bag_of_a_missing_path_or_a_file(path: str, wb: Path, capsys) -> None:
    res = run_cli(["import-bag", str(wb / path), "--states", str(wb / "states.json"),
                   "--out", str(wb / "ds")], capsys)
    assert_refused(res, str(wb / path), "bag's directory")
    assert not (wb / "ds").exists()


# ------------------------------------------------------------------ import-bag outputs
@pytest.mark.parametrize("out", ["bag", "bag/ds", "."])
def test_import_bag_output_may_not_be_the_bag(out: str, wb: Path, capsys) -> None:
    before = tree_hashes(wb)
    res = run_cli(["import-bag", str(wb / "bag"), "--states", str(wb / "states.json"),
                   "--out", str(wb / out), "--overwrite"], capsys)
    assert_refused(res, "overlaps the bag")
    _unchanged(before, wb)


def test_import_bag_overwrite_replaces_only_its_own_dataset(wb: Path, capsys) -> None:
    """``collect``'s dataset is never replaced; import-bag's own is, with --overwrite (the
    hint of the refusal works)."""
    before = tree_hashes(wb)
    args = ["import-bag", str(wb / "bag"), "--states", str(wb / "states.json")]
    res = run_cli([*args, "--out", str(wb / "data"), "--overwrite"], capsys)
    assert_refused(res, str(wb / "data"), "did not write", "choose another --out")
    _unchanged(before, wb)
    assert run_cli([*args, "--out", str(wb / "ds")], capsys).code == 0
    first = tree_hashes(wb / "ds")
    res = run_cli([*args, "--out", str(wb / "ds")], capsys)
    assert_refused(res, str(wb / "ds"), "pass --overwrite")
    assert tree_hashes(wb / "ds") == first
    res = run_cli([*args, "--out", str(wb / "ds"), "--overwrite"], capsys)
    assert res.code == 0, res.stderr
    assert sorted(tree_hashes(wb / "ds")) == sorted(first)  # same files, none stale
    (wb / "ds" / "mine.txt").write_text("my notes")  # now it is not only a dataset
    res = run_cli([*args, "--out", str(wb / "ds"), "--overwrite"], capsys)
    assert_refused(res, "mine.txt", "never replaced")
    _unchanged(before, wb)


@pytest.mark.parametrize(("err", "nth"), [(errno.ENOSPC, 1), (errno.ENOSPC, 3),
                                          (errno.EROFS, 1)])
def test_import_bag_on_a_full_disk_leaves_nothing_and_the_rerun_works(
        err: int, nth: int, wb: Path, capsys, monkeypatch) -> None:
    before = tree_hashes(wb)
    if err == errno.EROFS:
        monkeypatch.setattr(tempfile, "mkstemp", failing(err, nth, tempfile.mkstemp))
    else:
        monkeypatch.setattr(os, "fsync", failing(err, nth, os.fsync))
    args = ["import-bag", str(wb / "bag"), "--states", str(wb / "states.json"), "--out",
            str(wb / "ds")]
    res = run_cli(args, capsys)
    monkeypatch.undo()
    assert_refused(res, os.strerror(err), str(wb / "ds"))
    assert ".simlab" not in res.stderr  # the user's path, not the staging folder
    _unchanged(before, wb)
    assert not (wb / "ds").exists()  # no empty ds/parts/ left to block the rerun
    assert run_cli(args, capsys).code == 0


# ------------------------------------------------------------------ export-bag, disk full
@pytest.mark.parametrize("overwrite", [False, True])
def test_export_bag_on_a_full_disk_keeps_the_previous_bag(overwrite: bool, wb: Path,
                                                          capsys, monkeypatch) -> None:
    """The disk fills up once the bag is mostly written (the MCAP library does not
    fsync, so the failure is injected after the real write, in the staging folder)."""
    import simlab.ros.bag as bagmod

    real = bagmod._write

    def full(rb, ts, plugin, out, traj, t0):
        real(rb, ts, plugin, out, traj, t0)
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(_mcap(out)))

    monkeypatch.setattr(bagmod, "_write", full)
    out = wb / "bag" if overwrite else wb / "new" / "bag"
    before = tree_hashes(wb)
    res = run_cli(["export-bag", str(wb / "data"), "--out", str(out), "--no-scans",
                   *(["--overwrite"] if overwrite else [])], capsys)
    assert_refused(res, "no space left", str(out))
    assert ".simlab" not in res.stderr
    _unchanged(before, wb)
    _no_staging(wb)
    assert overwrite or not (wb / "new").exists()  # the parent it made is gone too


# ------------------------------------------------------------------ kills and races
def test_a_killed_export_leaves_staging_that_the_next_one_removes(wb: Path, capsys) -> None:
    from simlab.ros.bag import STAGING_PREFIX

    stale = wb / f".bag2{STAGING_PREFIX}dead"
    (stale / "bag2").mkdir(parents=True)
    (stale / "bag2" / "bag2_0.mcap").write_bytes(b"\x89MCAP half")
    res = run_cli(["export-bag", str(wb / "data"), "--out", str(wb / "bag2"), "--no-scans"],
                  capsys)
    assert res.code == 0, res.stderr
    _no_staging(wb)
    assert (wb / "bag2" / "metadata.yaml").is_file()


def test_an_interrupt_between_the_renames_puts_the_previous_bag_back(wb: Path, capsys,
                                                                      monkeypatch) -> None:
    """Ctrl-C after the previous bag was moved aside and before the new one took its place:
    the previous bag is back, byte for byte, and no staging folder is left."""
    import simlab.ros.bag as bagmod

    real, calls = os.replace, []

    def replace(src, dst):
        calls.append(Path(dst).name)
        real(src, dst)
        if Path(dst).name == "previous":
            raise KeyboardInterrupt

    monkeypatch.setattr(bagmod.os, "replace", replace)
    before = tree_hashes(wb)
    res = run_cli(["export-bag", str(wb / "data"), "--out", str(wb / "bag"), "--no-scans",
                   "--overwrite"], capsys)
    assert res.code == 130 and "Traceback" not in res.stderr, res.stderr
    assert "previous" in calls                       # the interrupt did land there
    _unchanged(before, wb)
    _no_staging(wb)


def test_a_writer_killed_between_the_renames_loses_no_bag(wb: Path, capsys) -> None:
    """What a kill at that moment leaves (the previous bag only inside a staging folder, no
    bag at ``--out``): the next export puts it back before anything else, so without
    ``--overwrite`` it is refused as any existing bag is, the bag whole."""
    from simlab.ros.bag import STAGING_PREFIX

    before = tree_hashes(wb)
    stale = wb / f".bag{STAGING_PREFIX}dead"
    stale.mkdir()
    os.replace(wb / "bag", stale / "previous")
    (stale / "bag").mkdir()                           # the new bag, half written
    res = run_cli(["export-bag", str(wb / "data"), "--out", str(wb / "bag"), "--no-scans"],
                  capsys)
    assert_refused(res, "already exists", str(wb / "bag"))
    _unchanged(before, wb)
    _no_staging(wb)


def test_an_interrupt_as_the_staging_folder_is_made_leaves_none(wb: Path, capsys,
                                                                 monkeypatch) -> None:
    """Ctrl-C the moment ``mkdtemp`` has made the staging folder, before the writer holds
    its name: the folder is still removed."""
    import simlab.ros.bag as bagmod

    real, made = tempfile.mkdtemp, []

    def mkdtemp(*args, **kwargs):
        made.append(real(*args, **kwargs))
        if bagmod.STAGING_PREFIX in kwargs.get("prefix", ""):   # the bag's staging folder
            raise KeyboardInterrupt
        return made[-1]

    monkeypatch.setattr(bagmod.tempfile, "mkdtemp", mkdtemp)
    before = tree_hashes(wb)
    res = run_cli(["export-bag", str(wb / "data"), "--out", str(wb / "bag"), "--no-scans",
                   "--overwrite"], capsys)
    assert res.code == 130, res.stderr
    assert any(bagmod.STAGING_PREFIX in Path(m).name for m in made)
    _unchanged(before, wb)
    _no_staging(wb)


def test_a_killed_import_leaves_staging_that_the_next_one_removes(wb: Path, capsys) -> None:
    from simlab.base.io import STAGING_PREFIX

    (wb / "ds" / f"{STAGING_PREFIX}dead" / "parts").mkdir(parents=True)
    res = run_cli(["import-bag", str(wb / "bag"), "--states", str(wb / "states.json"),
                   "--out", str(wb / "ds")], capsys)
    assert res.code == 0, res.stderr
    _no_staging(wb)


def test_a_second_writer_stops_at_once(wb: Path, capsys) -> None:
    from simlab.base.io import exclusive_directory

    before = tree_hashes(wb)
    with exclusive_directory(wb):  # an export-bag writing beside --out (the one lock)
        res = run_cli(["export-bag", str(wb / "data"), "--out", str(wb / "b"), "--no-scans"],
                      capsys)
    assert_refused(res, "another process is writing", "wait")
    with exclusive_directory(wb / "ds"):  # an import-bag writing into --out
        res = run_cli(["import-bag", str(wb / "bag"), "--states", str(wb / "states.json"),
                       "--out", str(wb / "ds")], capsys)
    assert_refused(res, "another process", str(wb / "ds"))
    _unchanged(before, wb)


@pytest.mark.parametrize("command", ["export-bag", "import-bag"])
def test_a_read_only_output_is_one_line_naming_it(command: str, wb: Path, capsys,
                                                  monkeypatch) -> None:
    """The file system refuses the first directory the command creates (tests run as
    root, which chmod cannot stop: the refusal is injected)."""
    before = tree_hashes(wb)
    monkeypatch.setattr(tempfile, "mkdtemp", failing(errno.EROFS, 1, tempfile.mkdtemp))
    out = wb / "out"
    args = (["export-bag", str(wb / "data"), "--no-scans"] if command == "export-bag" else
            ["import-bag", str(wb / "bag"), "--states", str(wb / "states.json")])
    res = run_cli([*args, "--out", str(out)], capsys)
    monkeypatch.undo()
    assert_refused(res, "read-only", str(out))
    assert ".simlab" not in res.stderr
    _unchanged(before, wb)
    assert not out.exists()


def _staging(root: Path) -> list[Path]:
    from simlab.ros.bag import STAGING_PREFIX

    return list(root.glob(f".bag{STAGING_PREFIX}*"))


@pytest.mark.slow
@pytest.mark.parametrize("how", ["SIGKILL", "SIGINT"])
def test_export_bag_killed_or_interrupted_keeps_the_previous_bag(how: str, wb: Path) -> None:
    """A kill while the bag is written (scans cast: seconds of work) leaves the previous
    bag as it was and only a staging folder, which the rerun removes; Ctrl-C is exit 130,
    no traceback, and no staging folder at all. A signal that lands after the new bag is
    renamed into place (a busy machine can delay it that long) must find the whole new bag."""
    import signal

    from .test_races_kills import _simlab, _wait_for

    before = tree_hashes(wb)
    args = ("export-bag", str(wb / "data"), "--out", str(wb / "bag"), "--overwrite")
    proc = _simlab(*args, cwd=wb)
    _wait_for(lambda: _staging(wb) or proc.poll() is not None, "the staging folder")
    assert proc.poll() is None, "the export ended before it could be interrupted"
    proc.send_signal(getattr(signal, how))
    _, err = proc.communicate(timeout=120)
    after = tree_hashes(wb)
    if any(after.get(k) != before[k] for k in before if k.startswith("bag/")):
        # The signal landed in the export's last milliseconds, after the new bag was
        # renamed into place (the staging folder lives until then): the bag must then be
        # the whole new one, byte for byte what an export nobody interrupts writes.
        assert "Traceback" not in err, err
        ref = _simlab(*args[:2], "--out", str(wb / "ref" / "bag"), cwd=wb)
        _, ref_err = ref.communicate(timeout=300)
        assert ref.returncode == 0, ref_err
        ours = {k: v for k, v in after.items() if k.startswith("bag/")}
        theirs = {k.removeprefix("ref/"): v for k, v in tree_hashes(wb).items()
                  if k.startswith("ref/bag/")}
        assert ours == theirs
        assert {k: after.get(k) for k in before if not k.startswith("bag/")} == {
            k: v for k, v in before.items() if not k.startswith("bag/")}
        assert not _staging(wb)
        return
    _unchanged(before, wb)
    if how == "SIGINT":
        assert proc.returncode == 130 and "Traceback" not in err, err
        assert not _staging(wb)
        return
    assert _staging(wb)  # what a kill leaves
    proc = _simlab(*args, "--no-scans", cwd=wb)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    assert not _staging(wb)
