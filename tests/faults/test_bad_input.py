"""The fault corpus, part 1: bad files and bad options for every subcommand.

Each case runs one ``simlab`` command in-process on a private copy of tiny inputs
(:mod:`tests.faults.conftest`) after damaging one thing, and asserts the promise of the
README's "Determinism and safety": exit code 2, exactly one error line that names the
file or field, no traceback, and every file that existed before is byte-identical.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from .conftest import assert_refused, run_cli, tree_hashes
from .conftest import writes_file as _write


def _manifest(edit: Callable[[dict], None]) -> Callable[[Path], None]:
    def setup(w: Path) -> None:
        p = w / "data" / "_manifest.json"
        m = json.loads(p.read_text())
        edit(m)
        p.write_text(json.dumps(m))
    return setup


def _del(*keys: str) -> Callable[[dict], None]:
    def edit(m: dict) -> None:
        target = m
        for k in keys[:-1]:
            target = target[k]
        del target[keys[-1]]
    return edit


def _set(value: object, *keys: str | int) -> Callable[[dict], None]:
    def edit(m: dict) -> None:
        target = m
        for k in keys[:-1]:
            target = target[k]
        target[keys[-1]] = value
    return edit


def _dup_part(m: dict) -> None:
    m["parts"].append(dict(m["parts"][0]))


def _npz_pickle(w: Path) -> None:
    np.savez(w / "bad.npz", T=np.array([object()], dtype=object))


def _arena(text: str) -> Callable[[Path], None]:
    return _write("arena.toml", text)


_TABLE = (Path(__file__).resolve().parents[2] / "arenas" / "table.toml").read_text()
BIG_ARENA = _TABLE.replace("size = [1.5, 1.5]", "size = [2000.0, 2000.0]")

NO = None
E = "estimate"
# (id, setup, argv ({w}: the work folder), words the one error line must contain)
CASES: list[tuple[str, Callable[[Path], None] | None, str, tuple[str, ...]]] = [
    # ---- states files
    ("collect-states-missing", NO, "collect --states {w}/nope.json --transitions 10 "
     "--simulator kinematic --out {w}/o --no-progress", ("nope.json",)),
    ("collect-states-notjson", _write("s.json", "{oops"), "collect --states {w}/s.json "
     "--transitions 10 --simulator kinematic --out {w}/o --no-progress", ("s.json",)),
    ("collect-states-binary", _write("s.json", b"\xff\xfe\x00garbage"), "collect --states "
     "{w}/s.json --transitions 10 --simulator kinematic --out {w}/o --no-progress", ("s.json",)),
    ("collect-states-empty", _write("s.json", ""), "collect --states {w}/s.json "
     "--transitions 10 --simulator kinematic --out {w}/o --no-progress", ("s.json",)),
    ("collect-states-other-arena", NO, "collect --states {w}/other_states.json --transitions 10 "
     "--simulator kinematic --out {w}/o --no-progress", ("other_states.json", "centres")),
    ("collect-states-list", _write("s.json", "[1, 2, 3]"), "collect --states {w}/s.json "
     "--transitions 10 --simulator kinematic --out {w}/o --no-progress", ("s.json",)),
    ("replay-states-missing", NO, "replay --states {w}/nope.json --qtables {w}/q --hours 0.01 "
     "--out {w}/r --no-progress", ("nope.json",)),
    ("replay-states-other-arena", NO, "replay --states {w}/other_states.json --qtables {w}/q "
     "--hours 0.01 --out {w}/r --no-progress", ("other_states.json", "centres")),
    ("estimate-states-notjson", _write("s.json", "{"), "estimate --counts {w}/counts.csv "
     "--states {w}/s.json --out {w}/m.npz --no-plot", ("s.json",)),
    ("estimate-dataset-other-states", NO, "estimate {w}/data --states {w}/other_states.json "
     "--out {w}/m.npz --no-plot", ("_manifest.json", "discretizer")),
    ("drive-states-notjson", _write("s.json", "nope"), "drive --states {w}/s.json --steps 1 "
     "--mode until_state_change --no-progress", ("s.json",)),
    ("arena-from-map-states-missing", NO, "arena-from-map {w}/map/map.yaml --out {w}/a.toml "
     "--states {w}/nope.json --start 0,0,0", ("nope.json",)),
    # ---- arena files
    ("map-arena-missing", NO, "map --arena {w}/nope.toml --minutes 0.1 --out {w}/m "
     "--no-progress", ("nope.toml",)),
    ("map-arena-badtoml", _arena("name = [\n"), "map --arena {w}/arena.toml --minutes 0.1 "
     "--out {w}/m --no-progress", ("arena.toml",)),
    ("map-arena-wrongtype", _arena('name = "x"\n[floor]\nsize = "big"\n'),
     "map --arena {w}/arena.toml --minutes 0.1 --out {w}/m --no-progress", ("arena.toml",)),
    ("map-arena-unknown-name", NO, "map --arena nosuch --minutes 0.1 --out {w}/m "
     "--no-progress", ("nosuch",)),
    ("map-arena-2km", _arena(BIG_ARENA), "map --arena {w}/arena.toml --minutes 0.1 "
     "--resolution 0.001 --out {w}/m --no-progress", ("resolution", "GiB")),
    ("collect-arena-badtoml", _arena("[[["), "collect --arena {w}/arena.toml --states "
     "{w}/states.json --transitions 10 --simulator kinematic --out {w}/o --no-progress",
     ("arena.toml",)),
    ("drive-arena-binary", _arena(b"\xff\xfe"), "drive --arena {w}/arena.toml --steps 1 "
     "--no-progress", ("arena.toml",)),
    ("estimate-arena-missing", NO, "estimate {w}/data --arena {w}/nope.toml --out {w}/m.npz "
     "--no-plot", ("nope.toml",)),
    ("train-arena-missing", NO, "train --mdp {w}/mdp.npz --arena {w}/nope.toml --episodes 2 "
     "--runs 1 --out {w}/t --no-progress", ("nope.toml",)),
    ("replay-arena-badtoml", _arena("x = "), "replay --arena {w}/arena.toml --states "
     "{w}/states.json --qtables {w}/q --hours 0.01 --out {w}/r --no-progress",
     ("arena.toml",)),
    ("pipeline-arena-missing", NO, "pipeline --arena {w}/nope.toml --out {w}/p --no-progress",
     ("nope.toml",)),
    # ---- count tables
    ("counts-missing", NO, "estimate --counts {w}/nope.csv --out {w}/m.npz --no-plot",
     ("nope.csv",)),
    ("counts-non-utf8", _write("c.csv", b"s,a,s_next,count\n0,0,1,\xff\n"),
     "estimate --counts {w}/c.csv --out {w}/m.npz --no-plot", ("c.csv",)),
    ("counts-beyond-int64", _write("c.csv", "s,a,s_next,count\n0,0,1,99999999999999999999\n"),
     "estimate --counts {w}/c.csv --out {w}/m.npz --no-plot", ("c.csv",)),
    ("counts-sum-overflow", _write("c.csv", "s,a,s_next,count\n0,0,1,9223372036854775807\n"
                                   "0,1,1,9223372036854775807\n"),
     "estimate --counts {w}/c.csv --out {w}/m.npz --no-plot", ("c.csv",)),
    ("counts-huge-index", _write("c.csv", "s,a,s_next,count\n0,0,4000000000,1\n"),
     "estimate --counts {w}/c.csv --out {w}/m.npz --no-plot", ("c.csv",)),
    ("counts-negative", _write("c.csv", "s,a,s_next,count\n0,0,1,-4\n"),
     "estimate --counts {w}/c.csv --out {w}/m.npz --no-plot", ("c.csv", "negative")),
    ("counts-missing-column", _write("c.csv", "s,a,count\n0,0,4\n"),
     "estimate --counts {w}/c.csv --out {w}/m.npz --no-plot", ("c.csv",)),
    ("counts-empty", _write("c.csv", ""), "estimate --counts {w}/c.csv --out {w}/m.npz "
     "--no-plot", ("c.csv",)),
    ("counts-text-count", _write("c.csv", "s,a,s_next,count\n0,0,1,many\n"),
     "estimate --counts {w}/c.csv --out {w}/m.npz --no-plot", ("c.csv",)),
    ("counts-json-garbage", _write("c.json", "{\"rows\": 3}"), "estimate --counts {w}/c.json "
     "--out {w}/m.npz --no-plot", ("c.json",)),
    ("counts-action-out-of-range", _write("c.csv", "s,a,s_next,count\n0,16,1,1\n"),
     "estimate --counts {w}/c.csv --out {w}/m.npz --no-plot", ("c.csv",)),
    ("counts-n-states-memory", NO, "estimate --counts {w}/counts.csv --n-states 2000000 "
     "--out {w}/m.npz --no-plot", ("n_states",)),
    # ---- model files (npz)
    ("train-mdp-missing", NO, "train --mdp {w}/nope.npz --episodes 2 --runs 1 --out {w}/t "
     "--no-progress", ("nope.npz",)),
    ("train-mdp-text", _write("bad.npz", "hello"), "train --mdp {w}/bad.npz --episodes 2 "
     "--runs 1 --out {w}/t --no-progress", ("bad.npz",)),
    ("train-mdp-pickle", _npz_pickle, "train --mdp {w}/bad.npz --episodes 2 --runs 1 "
     "--out {w}/t --no-progress", ("bad.npz",)),
    ("train-mdp-truncated", lambda w: (w / "bad.npz").write_bytes((w / "mdp.npz").read_bytes()
                                                                   [:200]),
     "train --mdp {w}/bad.npz --episodes 2 --runs 1 --out {w}/t --no-progress", ("bad.npz",)),
    ("train-mdp-is-dir", NO, "train --mdp {w}/q --episodes 2 --runs 1 --out {w}/t "
     "--no-progress", ("q",)),
    ("replay-mdp-text", _write("bad.npz", "hello"), "replay --states {w}/states.json "
     "--qtables {w}/q --mdp {w}/bad.npz --hours 0.01 --out {w}/r --no-progress", ("bad.npz",)),
    ("replay-qtables-missing", NO, "replay --states {w}/states.json --qtables {w}/nope "
     "--hours 0.01 --out {w}/r --no-progress", ("nope",)),
    ("replay-qtable-corrupt", lambda w: next((w / "q").glob("q_*.npz")).write_text("x"),
     "replay --states {w}/states.json --qtables {w}/q --hours 0.01 --out {w}/r --no-progress",
     ("q_",)),
    # ---- maps
    ("discretize-map-missing", NO, "discretize --map {w}/nope.yaml --out {w}/s2.json",
     ("nope.yaml",)),
    ("discretize-map-badyaml", _write("map/map.yaml", "image: [\n"), "discretize --map "
     "{w}/map/map.yaml --out {w}/s2.json", ("map.yaml",)),
    ("discretize-map-image-missing", lambda w: (w / "map" / "map.pgm").unlink(),
     "discretize --map {w}/map/map.yaml --out {w}/s2.json", ("map.pgm",)),
    ("discretize-map-image-garbage", _write("map/map.pgm", b"P5\n9 9\n255\nxx"),
     "discretize --map {w}/map/map.yaml --out {w}/s2.json", ("map.pgm",)),
    ("train-map-missing", NO, "train --mdp {w}/mdp.npz --map {w}/nope.yaml --episodes 2 "
     "--runs 1 --out {w}/t --no-progress", ("nope.yaml",)),
    ("replay-map-badyaml", _write("map/map.yaml", "resolution: -1\n"), "replay --states "
     "{w}/states.json --qtables {w}/q --map {w}/map/map.yaml --hours 0.01 --out {w}/r "
     "--no-progress", ("map.yaml",)),
    ("arena-from-map-badyaml", _write("map/map.yaml", ": : :"), "arena-from-map "
     "{w}/map/map.yaml --out {w}/a.toml --start 0,0,0", ("map.yaml",)),
    # ---- manifests
    ("manifest-missing", lambda w: (w / "data" / "_manifest.json").unlink(),
     "estimate {w}/data --out {w}/m.npz --no-plot", ("_manifest.json",)),
    ("manifest-notjson", _write("data/_manifest.json", "{"), "estimate {w}/data "
     "--out {w}/m.npz --no-plot", ("_manifest.json",)),
    ("manifest-not-object", _write("data/_manifest.json", "[]"), "estimate {w}/data "
     "--out {w}/m.npz --no-plot", ("_manifest.json",)),
    ("manifest-no-discretizer", _manifest(_del("discretizer")), "estimate {w}/data "
     "--out {w}/m.npz --no-plot", ("_manifest.json", "discretizer")),
    ("manifest-no-hash", _manifest(_del("discretizer", "hash")), "estimate {w}/data "
     "--out {w}/m.npz --no-plot", ("discretizer.hash",)),
    ("manifest-seed-string", _manifest(_set("7", "seed")), "estimate {w}/data "
     "--out {w}/m.npz --no-plot", ("seed",)),
    ("manifest-workers-bool", _manifest(_set(True, "workers")), "estimate {w}/data "
     "--out {w}/m.npz --no-plot", ("workers",)),
    ("manifest-parts-dict", _manifest(_set({}, "parts")), "estimate {w}/data "
     "--out {w}/m.npz --no-plot", ("parts",)),
    ("manifest-part-no-rows", _manifest(_del("parts", 0, "rows")), "estimate {w}/data "
     "--out {w}/m.npz --no-plot", ("parts[0].rows",)),
    ("manifest-part-rows-text", _manifest(_set("100", "parts", 1, "rows")), "estimate "
     "{w}/data --out {w}/m.npz --no-plot", ("parts[1].rows",)),
    ("manifest-duplicate-part", _manifest(_dup_part), "estimate {w}/data --out {w}/m.npz "
     "--no-plot", ("listed twice",)),
    ("manifest-arena-null", _manifest(_set(None, "arena")), "estimate {w}/data "
     "--out {w}/m.npz --no-plot", ("arena",)),
    ("manifest-centres-string", _manifest(_set("x", "discretizer", "centres")),
     "estimate {w}/data --out {w}/m.npz --no-plot", ("discretizer.centres",)),
    ("manifest-schema-entry", _manifest(_set([1], "schema")), "estimate {w}/data "
     "--out {w}/m.npz --no-plot", ("schema[0]",)),
    ("manifest-part-worker-range", _manifest(_set(9, "parts", 0, "worker")), "estimate "
     "{w}/data --out {w}/m.npz --no-plot", ("parts[0].worker",)),
    ("collect-resume-damaged-manifest", _manifest(_del("parts", 0, "sha256")),
     "collect --states {w}/states.json --transitions 300 --seed 3 --part-size 100 "
     "--simulator kinematic --out {w}/data --resume --no-progress", ("parts[0].sha256",)),
    ("export-minari-damaged-manifest", _manifest(_set("x", "workers")),
     "export-minari {w}/data --id simlab/faults-v0", ("workers",)),
    ("part-file-damaged", lambda w: next((w / "data").rglob("*.parquet")).write_bytes(b"PAR1"),
     "estimate {w}/data --out {w}/m.npz --no-plot", ("parquet",)),
    # ---- outputs in the way
    ("train-out-is-file", _write("t", "mine"), "train --mdp {w}/mdp.npz --episodes 2 --runs 1 "
     "--out {w}/t --no-progress", ("t",)),
    ("train-out-parent-is-file", _write("t", "mine"), "train --mdp {w}/mdp.npz --episodes 2 "
     "--runs 1 --out {w}/t/sub --no-progress", ("t",)),
    ("train-outputs-exist", NO, "train --mdp {w}/mdp.npz --episodes 2 --runs 1 --out {w}/q "
     "--no-progress --no-plots", ("already exists", "--overwrite")),
    ("estimate-out-exists", NO, "estimate {w}/data --out {w}/mdp.npz --no-plot",
     ("mdp.npz", "--overwrite")),
    ("estimate-out-parent-is-file", NO, "estimate {w}/data --out {w}/counts.csv/m.npz "
     "--no-plot", ("counts.csv",)),
    ("estimate-out-inside-dataset", NO, "estimate {w}/data --out {w}/data/m.npz --no-plot",
     ("m.npz",)),
    ("map-out-is-file", _write("m", "mine"), "map --minutes 0.1 --out {w}/m --no-progress",
     ("m",)),
    ("map-outputs-exist", NO, "map --minutes 0.1 --out {w}/map --no-progress",
     ("map", "--overwrite")),
    ("collect-out-is-file", _write("o", "mine"), "collect --states {w}/states.json "
     "--transitions 10 --simulator kinematic --out {w}/o --no-progress", ("o",)),
    ("collect-out-has-dataset", NO, "collect --states {w}/states.json --transitions 10 "
     "--simulator kinematic --out {w}/data --no-progress", ("data",)),
    ("replay-out-is-file", _write("r", "mine"), "replay --states {w}/states.json --qtables "
     "{w}/q --hours 0.01 --out {w}/r --no-progress", ("r",)),
    ("discretize-out-exists", NO, "discretize --map {w}/map/map.yaml --out {w}/states.json",
     ("states.json",)),
    ("pipeline-out-is-file", _write("p", "mine"), "pipeline --out {w}/p --no-progress",
     ("p",)),
    ("pipeline-out-not-empty", NO, "pipeline --out {w}/q --no-progress", ("q",)),
    ("pipeline-resume-damaged-state", _write("p/pipeline.json", "{"), "pipeline --out {w}/p "
     "--resume --no-progress --map-minutes 0.05", ("pipeline.json",)),
    ("arena-from-map-out-exists", NO, "arena-from-map {w}/map/map.yaml --out "
     "{w}/states.json --start 0,0,0", ("states.json",)),
    # ---- bad options, found before any work
    ("pipeline-agent-nosuch", NO, "pipeline --agent nosuch --out {w}/p --no-progress",
     ("agent", "nosuch")),
    ("pipeline-hours-zero", NO, "pipeline --hours 0 --out {w}/p --no-progress", ("hours",)),
    ("pipeline-resolution-memory", NO, "pipeline --arena {w}/arena.toml --out {w}/p "
     "--no-progress", ("map_resolution",)),
    ("train-agent-nosuch", NO, "train --mdp {w}/mdp.npz --agent nosuch --episodes 2 --runs 1 "
     "--out {w}/t --no-progress", ("nosuch",)),
    ("train-goal-nosuch", NO, "train --mdp {w}/mdp.npz --goals nosuch --episodes 2 --runs 1 "
     "--out {w}/t --no-progress", ("nosuch",)),
    ("train-param-bad", NO, "train --mdp {w}/mdp.npz --param tau=-1 --episodes 2 --runs 1 "
     "--out {w}/t --no-progress", ("tau",)),
    ("train-episodes-memory", NO, "train --mdp {w}/mdp.npz --episodes 1000000000000 --runs 10 "
     "--out {w}/t --no-progress", ("episodes", "GiB")),
    ("train-start-out-of-range", NO, "train --mdp {w}/mdp.npz --start 999 --episodes 2 "
     "--runs 1 --out {w}/t --no-progress", ("start",)),
    ("map-minutes-negative", NO, "map --minutes -1 --out {w}/m --no-progress", ("minutes",)),
    ("map-resolution-tiny", NO, "map --resolution 0.00001 --out {w}/m --no-progress",
     ("resolution",)),
    ("collect-workers-zero", NO, "collect --states {w}/states.json --transitions 10 --workers 0 "
     "--simulator kinematic --out {w}/o --no-progress", ("workers",)),
    ("collect-hours-nan", NO, "collect --states {w}/states.json --hours nan "
     "--simulator kinematic --out {w}/o --no-progress", ("hours",)),
    ("replay-hours-negative", NO, "replay --states {w}/states.json --qtables {w}/q "
     "--hours -1 --out {w}/r --no-progress", ("hours",)),
    ("replay-qtables-other-states", NO, "replay --states {w}/other_states.json --arena "
     "{w}/arena.toml --qtables {w}/q --hours 0.01 --out {w}/r --no-progress",
     ("q_", "states_hash", "other_states.json")),
    ("estimate-unvisited-bad", NO, "estimate {w}/data --unvisited nope --out {w}/m.npz",
     ("unvisited",)),
    ("export-minari-bad-length", NO, "export-minari {w}/data --id simlab/f-v0 "
     "--episode-length 0", ("episode",)),
    ("import-log-missing", NO, "import-log {w}/nope.csv --states {w}/states.json "
     "--out {w}/il", ("nope.csv",)),
    # ---- the tabular half and the orchestration commands
    ("visitlab-nav-human", NO, "visitlab train --task nav --human nosuch --out {w}/v "
     "--no-progress", ("human",)),
    ("visitlab-agent-nosuch", NO, "visitlab train --task nav --agent nosuch --out {w}/v "
     "--no-progress", ("nosuch",)),
    ("visitlab-set-bad", NO, "visitlab train --task nav --set tau=x --out {w}/v --no-progress",
     ("tau",)),
    ("visitlab-plot-missing", NO, "visitlab plot {w}/nope.npz --out {w}/p.png",
     ("nope.npz",)),
    ("visitlab-plot-garbage", _write("c.npz", "x"), "visitlab plot {w}/c.npz --out {w}/p.png",
     ("c.npz",)),
    ("visitlab-trials-memory", NO, "visitlab train --task nav --trials 1000000000000 "
     "--out {w}/v --no-progress", ("trials", "TiB")),
    ("visitlab-grid-memory", NO, "visitlab train --task nav --layout gridworld-100000x100000 "
     "--out {w}/v --no-progress", ("layout", "GiB")),
    ("visitlab-out-is-a-file", _write("vfile", "x"), "visitlab train --task nav --trials 5 "
     "--seeds 1 --out {w}/vfile --no-progress", ("vfile", "not a directory")),
    ("visitlab-show-png-exists", _write("show.png", b"\x89PNG old"), "visitlab show --task nav "
     "--png {w}/show.png", ("show.png", "--overwrite")),
    ("reproduce-only-nosuch", NO, "reproduce --only nosuch --out {w}/r", ("nosuch",)),
    ("reproduce-experiments-missing", NO, "reproduce --experiments {w}/nope --out {w}/r",
     ("nope",)),
    ("export-minari-not-dataset", NO, "export-minari {w}/q --id simlab/f-v0", ("q",)),
    ("import-log-states-missing", NO, "import-log {w}/counts.csv --states {w}/nope.json "
     "--out {w}/il", ("nope.json",)),
    ("import-log-binary", _write("log.csv", b"\x00\xff\xfe"), "import-log {w}/log.csv "
     "--states {w}/states.json --out {w}/il", ("log.csv",)),
]

BIG_ARENA_CASES = {"pipeline-resolution-memory"}
OTHER_ARENA_CASES = {"replay-qtables-other-states"}

WIDE_ARENA = _TABLE.replace("size = [1.5, 1.5]", "size = [4.5, 4.5]")


@pytest.mark.parametrize(("case", "setup", "argv", "needles"), CASES,
                         ids=[c[0] for c in CASES])
def test_bad_input_is_one_line_exit_2_and_nothing_changes(
        case: str, setup: Callable[[Path], None] | None, argv: str, needles: tuple[str, ...],
        work: Path, capsys: pytest.CaptureFixture[str]) -> None:
    if case in BIG_ARENA_CASES:
        (work / "arena.toml").write_text(BIG_ARENA.replace("2000.0", "300.0"))
    if case in OTHER_ARENA_CASES:
        (work / "arena.toml").write_text(WIDE_ARENA)
    if setup is not None:
        setup(work)
    before = tree_hashes(work)
    res = run_cli(argv.format(w=work).split(), capsys)
    assert_refused(res, *needles)
    assert tree_hashes(work) == before
