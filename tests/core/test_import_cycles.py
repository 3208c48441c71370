"""No two modules of simlab or discretize import each other, directly or around a circle.

A circle says a concept sits in the wrong module: the shared part belongs where both
can use it. Imports are read from the AST as the layering test reads them (module
level, inside functions, under ``TYPE_CHECKING``: a lazy import is an import), so a
function-level import does not hide a circle.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

_LAYERING = Path(__file__).with_name("test_layering.py")
_spec = importlib.util.spec_from_file_location("_layering_for_cycles", _LAYERING)
assert _spec is not None and _spec.loader is not None
layering = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = layering  # its dataclasses look their module up
_spec.loader.exec_module(layering)


def import_graph(sources: dict[str, tuple[str, bool]]) -> dict[str, set[str]]:
    """``module -> modules it imports`` among ``sources`` (``name -> (source,
    is_package)``); a module importing itself or a module outside ``sources`` is left
    out."""
    graph: dict[str, set[str]] = {name: set() for name in sources}
    for name, (source, is_pkg) in sources.items():
        for use in layering.uses(name, source, sources, is_pkg):
            if use.kind == "import" and use.target in sources and use.target != name:
                graph[name].add(use.target)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm,
    iterative), each sorted; sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                elif w in on_stack:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    x = stack.pop()
                    on_stack.discard(x)
                    comp.append(x)
                    if x == v:
                        break
                if len(comp) > 1:
                    found.append(sorted(comp))
    return sorted(found)


def test_cycles_finds_a_circle_through_a_lazy_import() -> None:
    sources = {
        "simlab.a": ("from simlab.b import f\n", False),
        "simlab.b": ("def f():\n    from simlab.c import g\n", False),
        "simlab.c": ("import simlab.a\n", False),
        "simlab.d": ("from simlab.a import f\n", False),
    }
    assert cycles(import_graph(sources)) == [["simlab.a", "simlab.b", "simlab.c"]]


def test_cycles_passes_a_chain_and_a_self_import() -> None:
    sources = {
        "simlab.a": ("from simlab.b import f\nfrom simlab.a import x\n", False),
        "simlab.b": ("from simlab.c import g\n", False),
        "simlab.c": ("import numpy\n", False),
    }
    assert cycles(import_graph(sources)) == []


def test_no_import_cycle_in_the_tree() -> None:
    modules = layering.all_modules()
    assert "discretize.voronoi" in modules and "simlab.visitlab.training" in modules
    sources = {name: (path.read_text(encoding="utf-8"), path.name == "__init__.py")
               for name, path in modules.items()}
    assert cycles(import_graph(sources)) == []
