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


_DEEP_JSON = "[" * 100_000 + "]" * 100_000
_DEEP_TOML = f"a = {_DEEP_JSON}\n"

NO = None
# (id, setup, argv ({w}: the work folder), words the one error line must contain)
CASES: list[tuple[str, Callable[[Path], None] | None, str, tuple[str, ...]]] = [
    ("drive-arena-is-a-directory", _mkdir("a.toml"), "drive --arena {w}/a.toml --steps 1 "
     "--no-progress", ("a.toml", "is a directory", "the .toml file itself")),
    ("export-bag-imported-log-without-arena", _imported_log, "export-bag {w}/robot "
     "--out {w}/bag --no-scans", ("_manifest.json", "arena", "--arena")),
    # ---- a text file given as an npz: numpy's "pickled data ... load it unsafely" before
    ("visitlab-show-q-text", _write("c.npz", "hello world\n"), "visitlab show --task nav "
     "--q {w}/c.npz", ("c.npz", "not an npz archive", "text file")),
    ("visitlab-plot-text", _write("c.npz", "0 1 2\n3 4 5\n"), "visitlab plot {w}/c.npz "
     "--out {w}/p.png", ("c.npz", "not an npz archive", "text file")),
    ("replay-qtable-text", _write("q/q_NE.npz", "Q = [[0, 1]]\n"), "replay --states "
     "{w}/states.json --qtables {w}/q --hours 0.01 --out {w}/r --no-progress",
     ("q_NE.npz", "not an npz archive", "text file")),
    # ---- files nested too deeply for the parser: the file named, not "an input"
    ("drive-config-nested", _write("c.toml", _DEEP_TOML), "drive --config {w}/c.toml "
     "--steps 1", ("c.toml", "nested too deeply")),
    ("drive-arena-nested", _write("a.toml", _DEEP_TOML), "drive --arena {w}/a.toml "
     "--steps 1", ("a.toml", "nested too deeply")),
    ("collect-states-nested", _write("s.json", _DEEP_JSON), "collect --states {w}/s.json "
     "--transitions 5 --simulator kinematic --out {w}/o --no-progress",
     ("s.json", "nested too deeply")),
    ("estimate-counts-nested", _write("c.json", _DEEP_JSON), "estimate --counts {w}/c.json "
     "--out {w}/m.npz --no-plot", ("c.json", "nested too deeply")),
    ("discretize-map-nested", _write("m.yaml", "image: " + _DEEP_JSON + "\n"),
     "discretize --map {w}/m.yaml --out {w}/s2.json", ("m.yaml", "nested too deeply")),
    # ---- a value of the wrong kind for a field that takes a file or an object
    ("drive-config-params-table", _write("c.toml", "params = {drive_time = 0.5}\n"),
     "drive --config {w}/c.toml --steps 1", ("c.toml", "params", "[primitives] TOML path")),
    ("drive-config-params-number", _write("c.toml", "params = 3\n"), "drive --config "
     "{w}/c.toml --steps 1", ("c.toml", "params", "[primitives] TOML path")),
    ("visitlab-show-q-binary", _write("c.npz", b"\x00\x01\xfe\xffgarbage"), "visitlab show "
     "--task nav --q {w}/c.npz", ("c.npz", "not an npz archive", "not a zip archive")),
    # ---- a table of a --config file checked field by field, not by the constructor
    ("collect-config-params-unknown", _write("c.toml", "params = {x = 1}\n"), "collect "
     "--config {w}/c.toml --states {w}/states.json --transitions 5 --out {w}/o "
     "--no-progress", ("c.toml", "params.x", "allowed")),
    ("collect-config-kinematic-params-type", _write("c.toml", 'params = {drive_time = "x"}\n'
                                                   'simulator = "kinematic"\n'),
     "collect --config {w}/c.toml --states {w}/states.json --transitions 5 --out {w}/o "
     "--no-progress", ("c.toml", "params.drive_time", "number")),
    ("collect-config-truth-pose-options", _write("c.toml", "pose_source_options = {x = 1}\n"),
     "collect --config {w}/c.toml --states {w}/states.json --transitions 5 --out {w}/o "
     "--no-progress", ("c.toml", "pose_source_options", "mcl")),
    ("collect-config-arena-number", _write("c.toml", "arena = 7\n"), "collect --config "
     "{w}/c.toml --states {w}/states.json --transitions 5 --out {w}/o --no-progress",
     ("c.toml", "arena", ".toml")),
    ("map-config-primitive-params", _write("c.toml", "primitive_params = {x = 1}\n"),
     "map --config {w}/c.toml --out {w}/m --no-progress", ("c.toml", "primitive_params.x")),
    ("map-config-log-odds", _write("c.toml", 'log_odds = {l_occ = "high"}\n'),
     "map --config {w}/c.toml --out {w}/m --no-progress", ("c.toml", "log_odds.l_occ",
                                                            "number")),
    ("replay-config-arena-number", _write("c.toml", "arena = 7\n"), "replay --config "
     "{w}/c.toml --states {w}/states.json --qtables {w}/q --out {w}/r --no-progress",
     ("c.toml", "arena", ".toml")),
    ("replay-config-map-number", _write("c.toml", "map = 7\n"), "replay --config "
     "{w}/c.toml --states {w}/states.json --qtables {w}/q --out {w}/r --no-progress",
     ("c.toml", "map", "path")),
    ("train-config-goals-number", _write("c.toml", "goals = 3\n"), "train --config "
     "{w}/c.toml --mdp {w}/mdp.npz --out {w}/t --no-progress", ("c.toml", "goals",
                                                                 "names")),
]

#: Library wording that must never reach the user's line.
NEVER = ("allow_pickle", "load it unsafely", "pickle.load")


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
    assert not any(words in res.stderr for words in NEVER), res.stderr
    assert tree_hashes(work) == before
