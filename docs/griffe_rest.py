"""Griffe extension of the documentation site: simlab's docstrings use a few reST
constructs (Sphinx roles such as ``:func:`simlab.agents.greedy``` and ``::`` before a
literal block); rendered as Markdown they would show the role's markup. Roles become code
spans (``~a.b.C`` shows ``C``, as in Sphinx) and ``::`` a colon."""

from __future__ import annotations

import re
from typing import Any

import griffe

_ROLE = re.compile(r":(?:py:)?(?:func|class|mod|meth|attr|data|exc|obj|ref|const):`([^`]+)`")
_LITERAL = re.compile(r"(\S)::\n")


def _role(match: re.Match[str]) -> str:
    target = match.group(1)
    if target.startswith("~"):
        target = target[1:].rsplit(".", 1)[-1]
    return f"`{target}`"


def markdown_of(text: str) -> str:
    """``text`` (a docstring) with roles as code spans and ``word::`` as ``word:``."""
    return _LITERAL.sub(r"\1:\n", _ROLE.sub(_role, text))


class RestToMarkdown(griffe.Extension):
    def on_instance(self, *, obj: Any, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = markdown_of(obj.docstring.value)
