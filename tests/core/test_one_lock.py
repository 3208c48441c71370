"""One lock mechanism: filelock. The output directory's lock (simlab.base.io) alone takes
``flock`` itself, for the reason its docstring measures (filelock cannot lock a directory)."""

from __future__ import annotations

import threading
from pathlib import Path

from filelock import FileLock

import simlab
from simlab.orchestration.cache import file_lock

ALLOWED = {Path("base/io.py")}


def test_only_the_output_directory_lock_takes_flock_itself() -> None:
    root = Path(simlab.__file__).parent
    users = {p.relative_to(root) for p in root.rglob("*.py")
             if "import fcntl" in p.read_text(encoding="utf-8")}
    assert users <= ALLOWED, sorted(map(str, users - ALLOWED))


def test_the_stage_lock_waits_for_a_filelock_holder(tmp_path: Path) -> None:
    path = tmp_path / ".stage.lock"
    order: list[str] = []
    holder = FileLock(path)
    holder.acquire()

    def build() -> None:
        with file_lock(path):
            order.append("stage")

    worker = threading.Thread(target=build)
    worker.start()
    worker.join(timeout=0.5)
    order.append("released")
    holder.release()
    worker.join()
    assert order == ["released", "stage"]
