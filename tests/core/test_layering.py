"""The layering of simlab, checked on the AST of every module.

ONE declared table (:data:`LAYERS`, lowest first) says which package may use which: a
module may use modules of its own layer and of lower layers, never of a higher one.
"Use" is any of

* an import, wherever it is (module level, inside a function — lazy imports —, or under
  ``if TYPE_CHECKING``);
* a string naming a module (``"simlab.x.y"`` or ``"simlab.x.y:attr"``: importlib, entry
  points, lazy-export tables, plugin registries);
* a read of another module's private name (``mod._x`` on an imported module, or
  ``from simlab.x import _y``), whatever the layers.

Declared exceptions: :data:`ALLOWED` (permanent, with the reason) and :data:`PENDING`
(violations another change is removing; the test fails once one is gone, so the entry is
deleted with the fix).
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("simlab", "discretize")

#: The layers, lowest first. A module belongs to the entry that is the longest prefix of
#: its dotted name; ``simlab`` alone (the package's ``__init__``: version, docs) is base.
#: Decisions: ``discretize`` (maps and Voronoi states, numpy only) sits below the physics
#: that reads its maps; ``simlab.agents`` (tabular RL on arrays, nothing of simlab above
#: the base) sits below ``simlab.data``, whose empirical MDP is solved with its planners.
#: Packages of one layer may use each other (the Gymnasium registration table of
#: ``simlab.envs`` names ``simlab.visitlab.envs:...`` classes: same layer, allowed).
LAYERS: tuple[tuple[str, ...], ...] = (
    ("simlab", "simlab.base"),
    ("discretize",),
    ("simlab.physics",),
    ("simlab.localization",),
    ("simlab.agents",),
    ("simlab.data",),
    ("simlab.training",),
    ("simlab.envs", "simlab.replay", "simlab.visitlab", "simlab.social"),
    ("simlab.orchestration", "simlab.experiments", "simlab.calibration", "simlab.ros",
     "simlab.online"),
    ("simlab.cli", "simlab.commands", "simlab.__main__"),
)

#: Entries that name one module only (the ``simlab`` package's ``__init__``), not a
#: package and everything below it.
PACKAGES_EXACT = ("simlab",)

#: (module, kind, target) uses that are allowed, with why.
ALLOWED: dict[tuple[str, str, str], str] = {
    ("simlab", "import", "simlab.envs"): "``import simlab`` registers the Gymnasium env ids "
                                         "(gymnasium.make('simlab/...') works after it)",
    ("simlab.base._numba_cache", "string", "discretize"): "names the discretize package's folder "
                                                       "to fingerprint its sources; imports "
                                                       "nothing from it",
    ("simlab.base.errors", "string", "discretize"): "names the discretize package's folder so "
                                               "that warn() skips its frames; imports "
                                               "nothing from it",
}

#: Violations on main that another engineer's change removes (issue 16); delete the entry
#: with that change.
PENDING: set[tuple[str, str, str]] = set()


@dataclass(frozen=True)
class Use:
    module: str  # the module that uses
    kind: str  # "import" | "string" | "private"
    target: str  # the module used (for "private": "module._name")
    line: int


def layer_of(module: str) -> int | None:
    """Index in :data:`LAYERS` of ``module`` (None: not simlab's)."""
    best, best_len = None, -1
    for i, entries in enumerate(LAYERS):
        for e in entries:
            inside = module == e or (e not in PACKAGES_EXACT and module.startswith(e + "."))
            if inside and len(e) > best_len:
                best, best_len = i, len(e)
    return best


def module_name(path: Path, root: Path = ROOT) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def all_modules(root: Path = ROOT) -> dict[str, Path]:
    out = {}
    for pkg in PACKAGES:
        for p in sorted((root / pkg).rglob("*.py")):
            out[module_name(p, root)] = p
    return out


_STRING_REF = re.compile(r"^((?:simlab|discretize)(?:\.[A-Za-z_]\w*)*)(?::[A-Za-z_]\w*)?$")


def _ours(name: str) -> bool:
    return name.split(".")[0] in PACKAGES


def _resolve_from(module: str, is_pkg: bool, node: ast.ImportFrom) -> str:
    if not node.level:
        return node.module or ""
    base = module.split(".") if is_pkg else module.split(".")[:-1]
    base = base[:len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def uses(module: str, source: str, known: Iterable[str], is_pkg: bool = False) -> list[Use]:
    """Every use (imports anywhere, module strings, private reads) in ``source``."""
    known = set(known)
    tree = ast.parse(source)
    found: list[Use] = []
    aliases: dict[str, str] = {}  # local name -> module, for private attribute reads
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if _ours(a.name):
                    found.append(Use(module, "import", a.name, node.lineno))
                    aliases[a.asname or a.name.split(".")[0]] = a.name if a.asname else \
                        a.name.split(".")[0]
        elif isinstance(node, ast.ImportFrom):
            src = _resolve_from(module, is_pkg, node)
            if not _ours(src):
                continue
            for a in node.names:
                sub = f"{src}.{a.name}"
                target = sub if sub in known else src
                found.append(Use(module, "import", target, node.lineno))
                if sub in known:
                    aliases[a.asname or a.name] = sub
                elif a.name.startswith("_") and not a.name.startswith("__") and src != module:
                    found.append(Use(module, "private", f"{src}.{a.name}", node.lineno))
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            m = _STRING_REF.match(node.value)
            if m and m.group(1) in known:  # a module, not a name like "simlab.transitions"
                found.append(Use(module, "string", m.group(1), node.lineno))
    for node in ast.walk(tree):
        if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                and node.value.id in aliases and node.attr.startswith("_")
                and not node.attr.startswith("__") and aliases[node.value.id] != module):
            found.append(Use(module, "private", f"{aliases[node.value.id]}.{node.attr}",
                             node.lineno))
    return found


def violations(found: Iterable[Use]) -> list[Use]:
    """The uses that break the layering (a higher layer, or a private name)."""
    bad = []
    for u in found:
        if u.kind == "private":
            bad.append(u)
            continue
        mine, theirs = layer_of(u.module), layer_of(u.target)
        if mine is None:
            continue
        if theirs is None:
            bad.append(u)  # a simlab module the table does not place
        elif theirs > mine:
            bad.append(u)
    return bad


def tree_violations() -> list[Use]:
    mods = all_modules()
    out = []
    for name, path in mods.items():
        out += violations(uses(name, path.read_text(), mods, path.name == "__init__.py"))
    return out


def _matches(u: Use, entries: Iterable[tuple[str, str, str]]) -> bool:
    return any(u.module == m and u.kind == k and (u.target == t or u.target.startswith(t + "."))
               for m, k, t in entries)


# --------------------------------------------------------------------------- the tree


def test_every_module_has_a_layer() -> None:
    unplaced = [m for m in all_modules() if layer_of(m) is None]
    assert not unplaced, f"add these modules to LAYERS: {unplaced}"


def test_the_tree_respects_the_layers() -> None:
    bad = [u for u in tree_violations() if not _matches(u, ALLOWED) and not _matches(u, PENDING)]
    assert not bad, "layering violations:\n" + "\n".join(
        f"  {u.module}:{u.line} {u.kind} {u.target}" for u in bad)


def test_declared_exceptions_are_still_needed() -> None:
    found = tree_violations()
    gone = [p for p in [*PENDING, *ALLOWED] if not any(_matches(u, [p]) for u in found)]
    assert not gone, f"no longer violated: delete from PENDING/ALLOWED {gone}"


# --------------------------------------------------------------------------- planted faults

KNOWN = {"simlab.data", "simlab.data.walkers", "simlab.replay", "simlab.replay.replay",
         "simlab.replay.localization",
         "simlab.physics", "simlab.physics.motion", "simlab.base.errors", "simlab.cli"}


@pytest.mark.parametrize("source, kind, target", [
    ("from simlab.replay.replay import replay\n", "import", "simlab.replay.replay"),
    ("def f():\n    import simlab.replay.replay\n", "import", "simlab.replay.replay"),
    ("def f():\n    from simlab.replay import replay\n", "import", "simlab.replay.replay"),
    ("from ..replay import replay\n", "import", "simlab.replay.replay"),
    ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from simlab.cli import x\n",
     "import", "simlab.cli"),
    ("SOURCES = {'mcl': 'simlab.replay.localization:make_pose_source'}\n", "string",
     "simlab.replay.localization"),
    ("import importlib\nm = importlib.import_module('simlab.replay.replay')\n", "string",
     "simlab.replay.replay"),
    ("from simlab.physics import motion\nx = motion._table\n", "private",
     "simlab.physics.motion._table"),
    ("import simlab.physics.motion as pm\nx = pm._table\n", "private",
     "simlab.physics.motion._table"),
    ("from simlab.physics.motion import _table\n", "private", "simlab.physics.motion._table"),
])
def test_a_planted_violation_is_caught(source: str, kind: str, target: str) -> None:
    bad = violations(uses("simlab.data.walkers", source, KNOWN))
    assert [(u.kind, u.target) for u in bad] == [(kind, target)]


def test_allowed_uses_are_not_flagged() -> None:
    src = ("from simlab.physics.motion import drive\n"  # a lower layer
           "from simlab.data import walkers\n"  # the same layer
           "x = walkers.public\n"
           "doc = 'see simlab.replay.replay for the loop'\n"  # prose, not a reference
           "y = '_stage.json'\n"
           "fmt = 'simlab.transitions'\n")  # a format name, not a module
    assert violations(uses("simlab.data.collect", src, KNOWN)) == []


def test_layer_table_orders_the_examples() -> None:
    assert layer_of("simlab.base.errors") < layer_of("discretize.voronoi") < layer_of(
        "simlab.physics.motion") < layer_of("simlab.data.collect") < layer_of(
        "simlab.replay.replay") < layer_of("simlab.experiments.visitlab.runs") < layer_of(
        "simlab.cli.replay")
    assert layer_of("numpy") is None
    assert layer_of("simlab.newthing") is None  # a new top-level module must be placed


def test_the_folder_tree_shows_the_layers() -> None:
    """Every layer entry is a folder (a package), so the tree reads as the table: the only
    modules at the top of ``simlab/`` are its ``__init__``, ``__main__`` and the public face
    ``commands`` (every command as a function, for scripts and notebooks)."""
    top = sorted(p.stem for p in (ROOT / "simlab").glob("*.py"))
    assert top == ["__init__", "__main__", "commands"]
    for layer in LAYERS:
        for entry in layer:
            if entry in PACKAGES_EXACT or entry in ("simlab.commands", "simlab.__main__"):
                continue
            folder = ROOT.joinpath(*entry.split("."))
            assert (folder / "__init__.py").is_file(), f"{entry} is not a package folder"
