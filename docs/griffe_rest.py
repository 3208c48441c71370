"""Griffe extension of the documentation site: simlab's docstrings use a few reST
constructs (Sphinx roles such as ``:func:`simlab.agents.greedy``` and ``::`` before a
literal block); rendered as Markdown they would show the role's markup.

A role whose target the site renders (a public module, or a public object with a
docstring, of the package being loaded, outside the hand-made pages of
:data:`simlab_docs.CURATED`) becomes a cross-reference link that mkdocs-autorefs resolves
(``[`greedy`][simlab.agents.policy.greedy]``: re-exports are linked to where the object is
defined; a name without dots is looked up in the docstring's own module, then the
package); any other role becomes a code span. ``~a.b.C`` shows ``C``, as in Sphinx, and
``::`` becomes a colon.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

_ROLE = re.compile(r":(?:py:)?(?:func|class|mod|meth|attr|data|exc|obj|ref|const):`([^`]+)`")
_LITERAL = re.compile(r"(\S)::\n")
#: Packages whose objects are rendered on hand-made pages only (simlab_docs.CURATED).
_CURATED = ("simlab.envs",)


def _display(target: str) -> str:
    return target[1:].rsplit(".", 1)[-1] if target.startswith("~") else target


def markdown_of(text: str, resolve: Any = None) -> str:
    """``text`` (a docstring) with roles as links (where ``resolve(target)`` gives the
    rendered object's path) or code spans, and ``word::`` as ``word:``."""

    def role(match: re.Match[str]) -> str:
        target = match.group(1)
        shown = _display(target)
        path = resolve(target.lstrip("~")) if resolve is not None else None
        return f"[`{shown}`][{path}]" if path else f"`{shown}`"

    return _LITERAL.sub(r"\1:\n", _ROLE.sub(role, text))


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
