"""Griffe extension of the documentation site: simlab's docstrings use a few reST
constructs (Sphinx roles such as ``:func:`simlab.agents.greedy```, ``::`` before a
literal block, and tables); rendered as Markdown they would show the role's markup, and a
table would be one run-on paragraph with its ``=====`` rows in it.

Tables (:func:`tables_to_markdown`, before the roles, whose markup would change the
columns' widths): a reST *simple table* (``=====  =====`` borders; docutils' "Simple
Tables": a line whose first column is blank continues the row above, text of the last
column may run past its border, the rows above the second border are the header) and a
*grid table* (``+-----+`` borders, ``+=====+`` under the header; no spanning cells) become
Markdown pipe tables; a table without a header gets an empty one (Markdown needs it).

A role whose target the site renders (a public module, or a public object with a
docstring, of the package being loaded, outside the hand-made pages of
:data:`simlab_docs.CURATED`) becomes a cross-reference link that mkdocs-autorefs resolves
(``[`greedy`][simlab.agents.policy.greedy]``: re-exports are linked to where the object is
defined; a name without dots is looked up in the docstring's own module, then the
package); any other role becomes a code span. ``~a.b.C`` shows ``C``, as in Sphinx, and
``::`` becomes a colon.
"""

from __future__ import annotations

import itertools
import re
from typing import Any

import griffe

_ROLE = re.compile(r":(?:py:)?(?:func|class|mod|meth|attr|data|exc|obj|ref|const):`([^`]+)`")
_LITERAL = re.compile(r"(\S)::\n")
#: Packages whose objects are rendered on hand-made pages only (simlab_docs.CURATED).
_CURATED = ("simlab.envs",)


_SIMPLE_BORDER = re.compile(r"^( *)(=+(?: +=+)+) *$")
_GRID_BORDER = re.compile(r"^( *)\+(?:[-=]+\+)+ *$")


def _columns(border: str) -> list[int]:
    """Start offsets of the columns of a simple table's border (runs of ``=``)."""
    return [m.start() for m in re.finditer(r"=+", border)]


def _split_simple(line: str, starts: list[int]) -> list[str]:
    """The cells of one line of a simple table: cut at the columns' starts, unless text
    runs across a start (then at the next gap of two spaces: overflowing text stays in
    its cell, as docutils reads it)."""
    cells, begin = [], starts[0]
    for nxt in [*starts[1:], None]:
        end = len(line) if nxt is None else nxt
        if nxt is not None and 0 < end < len(line) and line[end - 1] != " " \
                and line[end] != " ":
            gap = line.find("  ", end)
            end = len(line) if gap < 0 else gap
        cells.append(line[begin:end].strip())
        begin = max(end, begin)
    return cells


def _joined(above: str, below: str) -> str:
    """A cell's text continued on the next line (a path or word cut after ``/`` is
    joined without a space)."""
    if not below:
        return above
    if not above:
        return below
    return above + below if above.endswith("/") else f"{above} {below}"


def _pipe_table(indent: str, header: list[str] | None, rows: list[list[str]]) -> list[str]:
    """Markdown pipe-table lines (``|`` in a cell escaped; no header: an empty one)."""
    n = max([len(header or [])] + [len(r) for r in rows])

    def line(cells: list[str]) -> str:
        cells = [c.replace("|", "\\|") for c in cells] + [""] * (n - len(cells))
        return indent + "| " + " | ".join(cells) + " |"

    return [line(header or [""] * n), indent + "|" + "---|" * n, *(line(r) for r in rows)]


def _simple_table(lines: list[str], i: int) -> tuple[list[str], int] | None:
    """The simple table whose top border is ``lines[i]``: ``(Markdown lines, index after
    the table)``, or None when it is not one (no closing border)."""
    m = _SIMPLE_BORDER.match(lines[i])
    if m is None:
        return None
    indent, border = m.group(1), m.group(2)
    starts = [len(indent) + c for c in _columns(border)]
    borders = [i]
    j = i + 1
    while j < len(lines):
        if _SIMPLE_BORDER.match(lines[j]) and lines[j].strip() == border:
            borders.append(j)
            if j + 1 >= len(lines) or not lines[j + 1].strip():
                break
        j += 1
    if len(borders) < 2 or borders[-1] != j:
        return None

    def rows_of(a: int, b: int) -> list[list[str]]:
        rows: list[list[str]] = []
        for line in lines[a:b]:
            if not line.strip() or _SIMPLE_BORDER.match(line):
                continue
            cells = _split_simple(line, starts)
            if rows and not cells[0]:  # a blank first column continues the row above
                rows[-1] = [_joined(old, new) for old, new in zip(rows[-1], cells,
                                                                  strict=True)]
            else:
                rows.append(cells)
        return rows

    header = None
    if len(borders) >= 3:
        header = [" ".join(cells) for cells in zip(*rows_of(i + 1, borders[1]), strict=True)]
        header = [" ".join(c.split()) for c in header]
        body = rows_of(borders[1] + 1, j)
    else:
        body = rows_of(i + 1, j)
    return _pipe_table(indent, header, body), j + 1


def _grid_table(lines: list[str], i: int) -> tuple[list[str], int] | None:
    """The grid table whose top border is ``lines[i]`` (no spanning cells): ``(Markdown
    lines, index after the table)``, or None when it is not one."""
    m = _GRID_BORDER.match(lines[i])
    if m is None:
        return None
    indent = m.group(1)
    top = lines[i].rstrip()
    cuts = [k for k, ch in enumerate(top) if ch == "+"]
    rows: list[list[str]] = []
    header_rows = 0
    current: list[str] | None = None
    j = i + 1
    while j < len(lines):
        line = lines[j].rstrip()
        if _GRID_BORDER.match(line):
            if current is not None:
                rows.append([" ".join(c.split()) for c in current])
                current = None
            if "=" in line:
                header_rows = len(rows)
            if j + 1 >= len(lines) or not lines[j + 1].strip().startswith("|"):
                break
        elif line.strip().startswith("|") and len(line) >= cuts[-1] + 1:
            cells = [line[a + 1:b].strip() for a, b in itertools.pairwise(cuts)]
            current = cells if current is None else [
                _joined(old, new) for old, new in zip(current, cells, strict=True)]
        else:
            return None
        j += 1
    if j >= len(lines) or not rows:
        return None
    header = None
    if header_rows:
        header = [" ".join(" ".join(c).split()) for c in zip(*rows[:header_rows],
                                                             strict=True)]
    return _pipe_table(indent, header, rows[header_rows:]), j + 1


def tables_to_markdown(text: str) -> str:
    """``text`` with its reST simple and grid tables as Markdown pipe tables (module
    docstring); a blank line is kept or put before and after each table."""
    lines = text.split("\n")
    out: list[str] = []
    i = 0
    while i < len(lines):
        found = _simple_table(lines, i) or _grid_table(lines, i)
        if found is None:
            out.append(lines[i])
            i += 1
            continue
        table, i = found
        if out and out[-1].strip():
            out.append("")
        out += table
        if i < len(lines) and lines[i].strip():
            out.append("")
    return "\n".join(out)


def _display(target: str) -> str:
    return target[1:].rsplit(".", 1)[-1] if target.startswith("~") else target


def markdown_of(text: str, resolve: Any = None) -> str:
    """``text`` (a docstring) with its tables as Markdown tables, roles as links (where
    ``resolve(target)`` gives the rendered object's path) or code spans, and ``word::``
    as ``word:``."""

    def role(match: re.Match[str]) -> str:
        target = match.group(1)
        shown = _display(target)
        path = resolve(target.lstrip("~")) if resolve is not None else None
        return f"[`{shown}`][{path}]" if path else f"`{shown}`"

    return _LITERAL.sub(r"\1:\n", _ROLE.sub(role, tables_to_markdown(text)))


def _rendered(obj: Any) -> bool:
    """Whether mkdocstrings renders ``obj`` (public, documented, its parents too)."""
    path = obj.path
    if any(part.startswith("_") for part in path.split(".")):
        return False
    if any(path == c or path.startswith(c + ".") for c in _CURATED):
        return False
    node = obj
    while node is not None and not node.is_module:
        if not node.docstring:
            return False
        node = node.parent
    return True


def _lookup(pkg: Any, path: str) -> Any:
    """The object at dotted ``path`` inside ``pkg`` (aliases followed), or None."""
    if path == pkg.path:
        return pkg
    if not path.startswith(pkg.path + "."):
        return None
    try:
        obj = pkg[path[len(pkg.path) + 1:]]
        return obj.final_target if obj.is_alias else obj
    except Exception:  # a missing member, an alias that cannot be resolved
        return None


class RestToMarkdown(griffe.Extension):
    def on_package(self, *, pkg: Any, **kwargs: Any) -> None:
        for obj in _walk(pkg):
            if obj.docstring is None:
                continue
            module = obj if obj.is_module else obj.module

            def resolve(target: str, module: Any = module) -> str | None:
                for path in (target, f"{module.path}.{target}", f"{pkg.path}.{target}"):
                    found = _lookup(pkg, path)
                    if found is not None and _rendered(found):
                        return str(found.path)
                return None

            obj.docstring.value = markdown_of(obj.docstring.value, resolve)


def _walk(obj: Any) -> Any:
    """``obj`` and every object defined under it (aliases skipped)."""
    yield obj
    for member in list(obj.members.values()):
        if not member.is_alias:
            yield from _walk(member)
