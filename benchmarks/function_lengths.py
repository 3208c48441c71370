"""The longest library functions: lines and parameter counts.

Usage: ``python benchmarks/function_lengths.py [--top 15] [--root simlab] [PATH ...]``

Walks every ``*.py`` under ``--root`` (or the given files/directories) with :mod:`ast` and
prints the ``--top`` longest functions and methods (nested ones included, each counted on
its own lines ``lineno..end_lineno``, decorators excluded), with their parameter count
(positional, keyword-only, ``*args``/``**kwargs``; ``self``/``cls`` not counted), and how
many exceed 80 lines or 10 parameters (the house limits: a function past them wants splitting,
or a record for parameters that travel together).
"""

from __future__ import annotations

import argparse
import ast
from pathlib import Path

MAX_LINES = 80
MAX_PARAMS = 10


def _params(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    a = node.args
    names = [p.arg for p in (*a.posonlyargs, *a.args, *a.kwonlyargs)]
    if names and names[0] in ("self", "cls"):
        names = names[1:]
    return len(names) + (a.vararg is not None) + (a.kwarg is not None)


def functions(paths: list[Path]) -> list[tuple[int, int, str]]:
    """``(lines, parameters, "file:qualified.name")`` for every function in ``paths``."""
    rows: list[tuple[int, int, str]] = []
    for path in paths:
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))

        def visit(node: ast.AST, prefix: str, path: Path = path) -> None:
            for child in ast.iter_child_nodes(node):
                if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                    name = prefix + child.name
                    lines = child.end_lineno - child.lineno + 1  # type: ignore[operator]
                    rows.append((lines, _params(child), f"{path}:{name}"))
                    visit(child, name + ".")
                elif isinstance(child, ast.ClassDef):
                    visit(child, prefix + child.name + ".")
                else:
                    visit(child, prefix)

        visit(tree, "")
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("paths", nargs="*", type=Path, help="files or directories "
                        "(default: --root)")
    parser.add_argument("--root", type=Path, default=Path("simlab"),
                        help="package directory (default simlab)")
    parser.add_argument("--top", type=int, default=15, help="rows to print (default 15)")
    args = parser.parse_args()
    targets = args.paths or [args.root]
    files = sorted({f for t in targets for f in ([t] if t.is_file() else t.rglob("*.py"))})
    rows = sorted(functions(files), key=lambda r: (-r[0], -r[1], r[2]))
    print(f"{'lines':>5} {'params':>6}  function")
    for lines, params, name in rows[:args.top]:
        print(f"{lines:>5} {params:>6}  {name}")
    long_ = sum(r[0] > MAX_LINES for r in rows)
    wide = sum(r[1] > MAX_PARAMS for r in rows)
    print(f"{len(rows)} functions in {len(files)} files; {long_} over {MAX_LINES} lines, "
          f"{wide} over {MAX_PARAMS} parameters")


if __name__ == "__main__":
    main()
