"""The one stage cache (simlab.orchestration.cache): store, races, fingerprints."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from simlab.base.errors import ConfigError
from simlab.orchestration.cache import (
    MARKER,
    SOURCES,
    StageCache,
    _source_path,
    code_fingerprint,
    source_fingerprint,
)


def test_store_writes_once_and_get_then_finds_it(tmp_path: Path) -> None:
    cache = StageCache(tmp_path, "visitlab-run")
    slot = cache.slot("run", {"k": 1})
    assert not slot.complete

    def write(d: Path) -> dict:
        (d / "a.txt").write_text("a")
        return {"steps": [3]}

    assert cache.store(slot, write, 12.5)
    assert slot.complete
    rec = json.loads((slot.path / MARKER).read_text())
    assert rec["summary"] == {"steps": [3]} and rec["wall_seconds"] == 12.5
    assert rec["key"]["k"] == 1 and rec["key"]["code"] == code_fingerprint("visitlab-run")
    # a second writer (another process finished first) does not overwrite
    assert not cache.store(slot, lambda d: pytest.fail("rewritten"), 1.0)
    st = StageCache(tmp_path, "visitlab-run").get("run", {"k": 1},
                                                  lambda d: pytest.fail("rebuilt"))
    assert not st.built and st.summary == {"steps": [3]} and st.path == slot.path


def test_a_failed_write_leaves_nothing(tmp_path: Path) -> None:
    cache = StageCache(tmp_path, "physics")
    slot = cache.slot("toy", {"k": 1})

    def boom(d: Path) -> dict:
        (d / "half.txt").write_text("x")
        raise RuntimeError("boom")

    with pytest.raises(RuntimeError):
        cache.store(slot, boom, 0.0)
    assert not slot.path.exists()


def test_scopes_have_distinct_fingerprints_and_every_source_exists() -> None:
    assert code_fingerprint("physics") != code_fingerprint("visitlab-run")
    for scope, names in SOURCES.items():
        for name in names:
            assert _source_path(name).exists(), (scope, name)
    # the mapping module is part of the physics key (it moved into orchestration/)
    assert "orchestration/mapping.py" in SOURCES["physics"]
    with pytest.raises(ConfigError, match="scope"):
        code_fingerprint("nosuch")


def test_source_fingerprint_changes_with_content_and_refuses_missing(tmp_path: Path) -> None:
    (tmp_path / "pkg").mkdir()
    f = tmp_path / "pkg" / "m.py"
    f.write_text("x = 1\n")
    a = source_fingerprint([tmp_path / "pkg"])
    f.write_text("x = 2\n")
    assert source_fingerprint([tmp_path / "pkg"]) != a
    with pytest.raises(FileNotFoundError):
        source_fingerprint([tmp_path / "gone.py"])
