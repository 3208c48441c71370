"""Refactoring guard: same seeds give byte-identical results before and after a redesign.

The digests in ``fixtures/refactor_digests.json`` were produced by this module on the code
*before* the round-3 house redesign (issue 16: command configs, replay package, one cache,
one parallel layer, one agent core through the Visit-the-lab loops) and must not change
with it. They are SHA-256 digests of *content* — the dataset's rows column by column, every
array of ``mdp.npz`` and of each Q-table, the replay's logged runs, the Visit-the-lab learning
curves and Q-tables — never of file bytes, paths or wall-clock fields, so moving a file or
renaming a module keeps them, and changing one number anywhere does not.

A change that is meant to alter results (a bug fix, a new default) regenerates the file
on purpose and says so in its commit:

    python tests/integration/test_refactor_digests.py --write
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

FIXTURE = Path(__file__).parent / "fixtures" / "refactor_digests.json"

#: The tiny physics chain (the pipeline test's budget): map, states, 0.3 h walk, MDP, the
#: 9 goals trained, a 0.15 h replay with the random baseline beside it.
PIPELINE_ARGS = ["--map-minutes", "2", "--hours", "0.6", "--workers", "1", "--episodes", "60",
                 "--runs", "1", "--replay-hours", "0.15", "--pose-source", "truth",
                 "--no-video", "--no-progress"]

#: replay.json result keys that are wall-clock, not results
_WALL_KEYS = {"wall_seconds", "elapsed", "seconds_wall", "wall"}


def _h(*parts: Any) -> str:
    h = hashlib.sha256()
    for part in parts:
        a = np.ascontiguousarray(part)
        if a.dtype == object:  # strings from Parquet: their text, never their addresses
            a = np.asarray([json.dumps(x, sort_keys=True, default=str) for x in a.ravel()])
        h.update(str((a.dtype.str, a.shape)).encode())
        h.update(a.tobytes() if a.dtype.kind != "U" else "\x00".join(a.ravel()).encode())
    return h.hexdigest()[:24]


def _npz(path: Path) -> dict[str, str]:
    with np.load(path, allow_pickle=False) as z:
        return {f"{path.name}:{k}": _h(z[k]) for k in sorted(z.files)
                if k not in ("meta_json", "meta")}


def _numbers(obj: Any, prefix: str = "") -> dict[str, Any]:
    """Flatten a JSON document's numbers (wall-clock keys left out)."""
    out: dict[str, Any] = {}
    if isinstance(obj, dict):
        for k, v in obj.items():
            if k not in _WALL_KEYS and "wall" not in k and "time" not in k:
                out.update(_numbers(v, f"{prefix}{k}."))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            out.update(_numbers(v, f"{prefix}{i}."))
    elif isinstance(obj, int | float) and not isinstance(obj, bool):
        out[prefix.rstrip(".")] = round(float(obj), 9)
    return out


def physics_digests(out: Path) -> dict[str, str]:
    """Digests of a finished pipeline folder's results."""
    from simlab.data.dataset import read_dataset

    d: dict[str, str] = {}
    d["map:pgm"] = hashlib.sha256((out / "map" / "map.pgm").read_bytes()).hexdigest()[:24]
    states = json.loads((out / "states" / "states.json").read_text())
    d["states:centres"] = _h(np.asarray(states["centres"], dtype=np.float64))
    table = read_dataset(out / "dataset" / "data")
    for name in table.column_names:
        d[f"dataset:{name}"] = _h(table.column(name).to_numpy(zero_copy_only=False))
    d.update(_npz(out / "mdp" / "mdp.npz"))
    for q in sorted((out / "qtables").glob("q_*.npz")):
        d.update(_npz(q))
    replay = json.loads((out / "replay" / "replay.json").read_text())
    d["replay:result"] = _h(np.asarray(json.dumps(_numbers(replay.get("result", {})),
                                                  sort_keys=True)))
    for f in sorted((out / "replay").glob("*.npz")):
        d.update({f"replay/{k}": v for k, v in _npz(f).items()})
    for f in sorted((out / "replay").glob("*.parquet")):
        import pyarrow.parquet as pq

        t = pq.read_table(f)
        for name in t.column_names:
            d[f"replay/{f.name}:{name}"] = _h(t.column(name).to_numpy(zero_copy_only=False))
    return d


def visitlab_digests() -> dict[str, str]:
    """Learning curves and Q-tables of every agent on the three tasks, both variants, and
    the combined architecture run from trained modules."""
    from simlab.visitlab.combined import CombinedTask, Modules, evaluate
    from simlab.visitlab.training import seed_generators, train

    d: dict[str, str] = {}
    qs: dict[str, np.ndarray] = {}
    for task, trials in (("nav", 60), ("social", 120), ("gotohuman", 60)):
        for variant in ("thesis", "paper"):
            for agent in ("q-learning", "q-softmax", "mb-egreedy", "vi-softmax", "rmax"):
                r = train(task, agent, trials=trials, seeds=2, seed=11, variant=variant,
                          progress=False)
                d[f"visitlab:{task}:{variant}:{agent}"] = _h(r.returns, r.q)
                if variant == "thesis" and agent == "mb-egreedy":
                    qs[task] = r.q[0]
    task = CombinedTask()
    run = evaluate(task, Modules(qs["nav"], qs["social"], qs["gotohuman"]), 20,
                   seed_generators(5, 1)[0])
    d["visitlab:combined:goals"] = _h(np.asarray(run.goals))
    return d


def mcl_replay_digests(pipeline_out: Path, out: Path) -> dict[str, str]:
    """A second replay of the same Q-tables: MCL pose, epsilon, return-to-start, 2 goals."""
    import pyarrow.parquet as pq

    from simlab.cli import main

    argv = ["replay", "--states", str(pipeline_out / "states" / "states.json"),
            "--qtables", str(pipeline_out / "qtables"), "--hours", "0.06",
            "--pose-source", "mcl", "--goals", "C,NE", "--seed", "3", "--epsilon", "0.1",
            "--return-to-start", "--baseline-hours", "0.01", "--no-progress",
            "--out", str(out)]
    if main(argv) != 0:
        raise RuntimeError("replay failed")
    d: dict[str, str] = {}
    for f in sorted(out.glob("*.parquet")):
        t = pq.read_table(f)
        for name in t.column_names:
            d[f"mcl/{f.name}:{name}"] = _h(t.column(name).to_numpy(zero_copy_only=False))
    replay = json.loads((out / "replay.json").read_text())
    d["mcl:result"] = _h(np.asarray(json.dumps(_numbers(replay.get("result", {})),
                                               sort_keys=True)))
    return d


def compute(tmp: Path) -> dict[str, str]:
    from simlab.cli import main

    out = tmp / "pipeline"
    if main(["pipeline", "--out", str(out), *PIPELINE_ARGS]) != 0:
        raise RuntimeError("pipeline failed")
    return {**physics_digests(out), **mcl_replay_digests(out, tmp / "mcl"),
            **visitlab_digests()}


@pytest.mark.slow
def test_results_are_byte_identical_to_before_the_redesign(tmp_path: Path) -> None:
    expected = json.loads(FIXTURE.read_text())
    got = compute(tmp_path)
    changed = sorted(k for k in expected if got.get(k) != expected[k])
    missing = sorted(set(expected) - set(got))
    assert not changed and not missing, (
        f"{len(changed)} result(s) changed: {changed[:12]}; missing: {missing[:12]} "
        "(regenerate only for an intended change: python "
        "tests/integration/test_refactor_digests.py --write)")


if __name__ == "__main__":
    import tempfile

    if sys.argv[1:] != ["--write"]:
        sys.exit("usage: python tests/integration/test_refactor_digests.py --write")
    with tempfile.TemporaryDirectory() as tmp:
        digests = compute(Path(tmp))
    FIXTURE.parent.mkdir(parents=True, exist_ok=True)
    FIXTURE.write_text(json.dumps(digests, indent=1, sort_keys=True) + "\n")
    print(f"wrote {len(digests)} digests to {FIXTURE}")
