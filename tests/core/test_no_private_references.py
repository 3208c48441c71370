"""No reference a reader outside the project cannot follow.

A user has the package, the thesis and the papers, not the project's issue tracker or its
internal spec: code, docstrings, comments, the README and every ``--help`` text state the
decision where it is made and cite the public source ("thesis 2.1.2, Table 2.3";
"Chartouny et al. 2024, sec. 3"), never "issue 18, item 4" or "SPEC A9".
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

#: What a private reference looks like: an issue number ("issue 12", "Issue-12",
#: "issue #12", "issues 12"), the internal spec by name ("SPEC A9", "SPEC C": upper case,
#: so ``load_robot_spec`` and "the spec" in prose pass), and an issue named without its
#: number ("the issue's acceptance", "the issue left it open").
PRIVATE = re.compile(
    r"\bissues?[ -]?#?\d+"
    r"|\b(?:the|this|that) issue(?:'s\b| left\b)"
    r"|(?-i:\bSPEC\b)",
    re.IGNORECASE,
)


def private_references(text: str) -> list[str]:
    """The lines of ``text`` that hold a private reference, numbered from 1."""
    return [f"{i}: {line.strip()}" for i, line in enumerate(text.splitlines(), 1)
            if PRIVATE.search(line)]


@pytest.mark.parametrize("text", [
    "Constraints (issue 12), keyword arguments",
    "(issue 18, item 4)",
    "Issue-17's benchmark",
    "see issue #3",
    "the train command (SPEC A9, thesis 4.5)",
    "Agents (SPEC C).",
    "Decisions (the issue left them open):",
    "the issue's headline number",
])
def test_the_pattern_finds_private_references(text: str) -> None:
    assert private_references(text) == [f"1: {text}"]


@pytest.mark.parametrize("text", [
    "thesis 2.1.2, Table 2.3; Chartouny et al. 2024, sec. 3",
    "robot = load_robot_spec(path)",
    "the spec of the URDF",
    "reissue 12 requests",
    "a known issue with PyBullet's rayTestBatch",
])
def test_the_pattern_passes_public_text(text: str) -> None:
    assert private_references(text) == []


def _source_files() -> list[Path]:
    files = [p for d in ("simlab", "discretize", "benchmarks")
             for p in sorted((ROOT / d).rglob("*.py"))]
    assert len(files) > 100  # the walk found the package, not an empty folder
    return files


def test_no_private_references_in_the_code() -> None:
    found = {str(p.relative_to(ROOT)): hits for p in _source_files()
             if (hits := private_references(p.read_text(encoding="utf-8")))}
    assert found == {}


def test_no_private_references_in_the_readme() -> None:
    assert private_references((ROOT / "README.md").read_text(encoding="utf-8")) == []


def test_no_private_references_in_the_experiments_and_docs() -> None:
    """The experiment files (their comments, references and claims reach the reports) and
    the documentation pages."""
    files = [*sorted((ROOT / "experiments").glob("*.toml")),
             *sorted((ROOT / "docs").rglob("*.md"))]
    assert len(files) > 10
    found = {str(p.relative_to(ROOT)): hits for p in files
             if (hits := private_references(p.read_text(encoding="utf-8")))}
    assert found == {}


def _help_texts(parser: argparse.ArgumentParser, prog: str) -> list[tuple[str, str]]:
    """``(where, text)`` of a parser's description, epilog and every option's and
    subcommand's help, recursing into subparsers."""
    texts = [(prog, parser.description or ""), (prog, parser.epilog or "")]
    for action in parser._actions:
        texts.append((f"{prog} {'/'.join(action.option_strings) or action.dest}",
                      action.help or ""))
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                texts.append((f"{prog} {choice.dest}", choice.help or ""))
            for name, sub in action.choices.items():
                texts.extend(_help_texts(sub, f"{prog} {name}"))
    return texts


def test_no_private_references_in_help() -> None:
    from simlab.cli import SUBCOMMANDS, build_parser

    texts = _help_texts(build_parser(), "simlab")
    # every registered subcommand was walked (not only the top-level parser)
    walked = {where.split()[1] for where, _ in texts if len(where.split()) > 1}
    assert set(SUBCOMMANDS) <= walked
    assert [(where, text) for where, text in texts if PRIVATE.search(text)] == []
