"""The fault corpus, part 2: the operating system says no (full disk, read-only file
system) in the middle of writing, simulated by failing the n-th ``fsync``/temporary file.

Every case: exit 2, one line naming the problem and the fix, no traceback, and the tree
byte-identical, which includes the previous outputs an ``--overwrite`` run was replacing
(outputs appear whole or not at all).
"""

from __future__ import annotations

import errno
import os
import tempfile
from pathlib import Path

import pytest

from .conftest import assert_refused, failing, run_cli, tree_hashes

COMMANDS = {
    "train": "train --mdp {w}/mdp.npz --episodes 2 --runs 1 --out {w}/q --overwrite "
             "--no-progress",
    "train-plots": "train --mdp {w}/mdp.npz --episodes 2 --runs 1 --out {w}/q --overwrite "
                   "--no-progress --arena table",
    "estimate": "estimate {w}/data --out {w}/mdp.npz --overwrite",
    "estimate-counts": "estimate --counts {w}/counts.csv --out {w}/mdp.npz --overwrite "
                       "--no-plot",
    "discretize": "discretize --map {w}/map/map.yaml --out {w}/states.json --states 9 "
                  "--overwrite --no-progress",
    "collect": "collect --states {w}/states.json --transitions 50 --simulator kinematic "
               "--out {w}/new --no-progress",
    "arena-from-map": "arena-from-map {w}/map/map.yaml --out {w}/a.toml --start 0,0,0",
    "import-log": "import-log {w}/log.txt --states {w}/states.json --out {w}/il",
    "import-log-overwrite": "import-log {w}/log.txt --states {w}/states.json --out {w}/data "
                            "--overwrite",
    "visitlab-train": "visitlab train --task nav --trials 5 --seeds 1 --out {w}/v "
                      "--no-progress",
}

ERRORS = {
    errno.ENOSPC: "no space left",
    errno.EROFS: "read-only",
    errno.EDQUOT: "quota",
    errno.EIO: "input/output",
}

#: The n-th write that fails: 1 = the very first, 3 = after two files were written.
WHEN = (1, 3)


CASES = [(c, e, n) for c in COMMANDS for e in (errno.ENOSPC, errno.EROFS) for n in WHEN]
CASES += [("train", errno.EDQUOT, 2), ("estimate", errno.EIO, 2)]


@pytest.mark.parametrize(("command", "err", "nth"), CASES,
                         ids=[f"{c}-{errno.errorcode[e]}-{n}" for c, e, n in CASES])
def test_write_failure_is_one_line_and_leaves_everything_as_it_was(
        command: str, err: int, nth: int, work, capsys, monkeypatch) -> None:
    before = tree_hashes(work)
    if err == errno.EROFS and nth == 1:  # the file system refuses to create anything
        monkeypatch.setattr(tempfile, "mkstemp", failing(err, 1, tempfile.mkstemp))
    else:
        monkeypatch.setattr(os, "fsync", failing(err, nth, os.fsync))
    res = run_cli(COMMANDS[command].format(w=work).split(), capsys)
    monkeypatch.undo()
    if res.code == 0:  # fewer writes than nth: nothing failed, nothing to check here
        assert nth > 1
        return
    assert_refused(res, ERRORS[err])
    line = res.error_lines[0]
    assert str(work) in line, line  # the output that could not be written
    assert ".simlab-staging-" not in line and ".tmp" not in line, line  # never our hidden names
    after = tree_hashes(work)
    assert {k: after.get(k) for k in before} == before  # nothing that existed changed
    if command == "collect":
        # a dataset keeps its finished parts by design (resumable): the manifest lists
        # exactly the parts on disk, and --resume completes it
        from simlab.data.manifest import read_manifest

        new = work / "new"
        if (new / "_manifest.json").exists():
            listed = {e["file"] for e in read_manifest(new)["parts"]}
            on_disk = {p.relative_to(new).as_posix() for p in new.rglob("*.parquet")}
            assert listed <= on_disk  # orphans are redone
            res = run_cli([*COMMANDS[command].format(w=work).split(), "--resume"], capsys)
            assert res.code == 0, res.stderr
    else:
        assert after == before, sorted(set(after) ^ set(before))
    leftovers = [p for p in work.rglob("*") if ".simlab-staging-" in p.name
                 or p.name.endswith(".tmp")]
    assert not leftovers


def test_describe_os_error_names_the_file_and_the_fix() -> None:
    from simlab.cli import describe_os_error

    text = describe_os_error(OSError(errno.ENOSPC, "No space left on device", "/x/q.npz"))
    assert text.startswith("No space left on device: /x/q.npz (free some space")
    assert "\n" not in text


def test_write_npy_keeps_the_errno_of_a_full_disk() -> None:
    """NumPy writes a real file with C stdio and turns a short write into "N requested and
    M written" (no errno); simlab.base.io.write_npy writes through Python's layer."""
    import io

    import numpy as np

    from simlab.base.io import write_npy

    class Full(io.RawIOBase):
        def writable(self) -> bool:
            return True

        def write(self, b) -> int:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    with pytest.raises(OSError) as exc:
        write_npy(Full(), np.zeros((2560, 22)))
    assert exc.value.errno == errno.ENOSPC
    buf = io.BytesIO()
    write_npy(buf, np.arange(6.0).reshape(2, 3))
    buf.seek(0)
    np.testing.assert_array_equal(np.load(buf, allow_pickle=False), np.arange(6.0).reshape(2, 3))


@pytest.fixture()
def tiny_disk(tmp_path: Path):
    """A 256 KiB tmpfs (root only: skipped where mount is not allowed)."""
    import shutil
    import subprocess

    mnt = tmp_path / "tiny"
    mnt.mkdir()
    if os.geteuid() != 0 or shutil.which("mount") is None or subprocess.run(
            ["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(mnt)],
            capture_output=True).returncode != 0:
        pytest.skip("needs a tmpfs mount (root)")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", str(mnt)], capture_output=True)


def test_social_pipeline_on_a_really_full_disk_says_no_space_left(tiny_disk: Path,
                                                                    capsys) -> None:
    """The social module's Q-table meets a full disk (a 256 KiB file system): the line
    says "No space left on device" and names the user's file, and nothing is left."""
    res = run_cli(f"social-pipeline --out {tiny_disk}/sp --hours 0.002 --runs 1 "
                  "--trials 200".split(), capsys)
    assert_refused(res, "no space left", f"{tiny_disk}/sp")
    assert not any(tiny_disk.rglob("*.npy"))
