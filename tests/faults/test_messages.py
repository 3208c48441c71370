"""The fault corpus, part 5: cases that were handled but said too little, or said it in a
library's words (a directory given for a file, a text file given as an npz, a TOML nested
too deeply, a field of the wrong type, a dataset that names no arena here).

Same promise as the other parts: exit 2, one line naming the user's file or field with a
fix that works, no traceback, every file that existed before byte-identical.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from .conftest import assert_refused, run_cli, tree_hashes
from .conftest import writes_file as _write


def _mkdir(name: str) -> Callable[[Path], None]:
    def setup(w: Path) -> None:
        (w / name).mkdir()
    return setup


def _imported_log(w: Path) -> None:
    """A dataset imported from a robot's pose log: it records no arena that is here."""
    from simlab.data.poselog import import_log

    import_log(w / "log.txt", states=w / "states.json", out=w / "robot")


NO = None
# (id, setup, argv ({w}: the work folder), words the one error line must contain)
CASES: list[tuple[str, Callable[[Path], None] | None, str, tuple[str, ...]]] = [
    ("drive-arena-is-a-directory", _mkdir("a.toml"), "drive --arena {w}/a.toml --steps 1 "
     "--no-progress", ("a.toml", "is a directory", "the .toml file itself")),
    ("export-bag-imported-log-without-arena", _imported_log, "export-bag {w}/robot "
     "--out {w}/bag --no-scans", ("_manifest.json", "arena", "--arena")),
]


@pytest.mark.parametrize(("case", "setup", "argv", "needles"), CASES,
                         ids=[c[0] for c in CASES])
def test_the_one_line_names_the_file_and_the_fix(
        case: str, setup: Callable[[Path], None] | None, argv: str, needles: tuple[str, ...],
        work: Path, capsys: pytest.CaptureFixture[str]) -> None:
    if case.startswith("export-bag"):
        pytest.importorskip("rosbags")
    if setup is not None:
        setup(work)
    before = tree_hashes(work)
    res = run_cli(argv.format(w=work).split(), capsys)
    assert_refused(res, *needles)
    assert tree_hashes(work) == before


_ = _write  # used by the cases added below
