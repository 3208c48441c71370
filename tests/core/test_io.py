"""Atomic writes: all or nothing, never a replaced user file, normal permissions."""

from __future__ import annotations

import os
import stat

import pytest

from simlab.base.errors import ConfigError
from simlab.base.io import atomic_write, atomic_write_json, ensure_new


def test_atomic_write_is_all_or_nothing(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    with pytest.raises(RuntimeError), atomic_write(target, "w") as fh:
        fh.write("half")
        raise RuntimeError("crash while writing")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]  # no temporary left


def test_outputs_get_umask_permissions_not_0600(tmp_path):
    atomic_write_json(tmp_path / "a.json", {"x": 1})
    mode = stat.S_IMODE(os.stat(tmp_path / "a.json").st_mode)
    umask = os.umask(0)
    os.umask(umask)
    assert mode == 0o666 & ~umask


def test_ensure_new_refuses_existing_files(tmp_path):
    existing = tmp_path / "x.png"
    existing.write_bytes(b"1")
    with pytest.raises(ConfigError, match=r"x\.png: output already exists.*--overwrite"):
        ensure_new(existing)
    assert ensure_new(existing, overwrite=True) == existing
    assert ensure_new(tmp_path / "new.png") == tmp_path / "new.png"
