"""Every subcommand has fault cases: this test lists ``simlab.cli.SUBCOMMANDS`` and fails
for each one that no file of ``tests/faults/`` runs.

The mechanism, for whoever adds a command or a fault file: a fault case runs the command
through :func:`tests.faults.conftest.run_cli` or :func:`simlab.cli.main` with an argv whose
first word is the subcommand's name, written in the test's source as a string that starts
with it (``"drive --seed -5 ..."``, ``f"train --mdp {w}/mdp.npz ..."``) or as the first item
of a list (``["export-bag", str(src), ...]``). The scan reads the source of every
``tests/faults/test_*.py`` (a new file joins by existing), so no registry is kept in step.
"""

from __future__ import annotations

import re
from pathlib import Path

from simlab.cli import SUBCOMMANDS

HERE = Path(__file__).resolve().parent


def commands_with_fault_cases(sources: list[str]) -> set[str]:
    """The subcommands that some source runs: a string literal (plain or f-string) whose
    text starts with the name (after optional ``-q``/``-v`` flags), followed by a space or
    the closing quote."""
    found = set()
    for name in SUBCOMMANDS:
        pattern = re.compile(r"""(?<![\w-])[fr]?["'](?:-[qv]+\s+)*""" + re.escape(name)
                             + r"""(?=[\s"'])""")
        if any(pattern.search(text) for text in sources):
            found.add(name)
    return found


def test_the_scan_recognises_the_ways_a_case_is_written() -> None:
    sources = ['run_cli(f"train --mdp {w}/mdp.npz".split(), capsys)',
               'main(["export-bag", str(src)])', '"-q estimate {w}/data"',
               '"map": "nothing"',  # a key that is also a command name: counted, harmless
               '"import-log-overwrite"', 'x = "replayed"']  # names inside longer words: not
    assert commands_with_fault_cases(sources) == {"train", "export-bag", "estimate", "map"}


def test_every_subcommand_has_a_fault_case() -> None:
    sources = [p.read_text(encoding="utf-8") for p in sorted(HERE.glob("test_*.py"))
               if p.name != Path(__file__).name]
    missing = sorted(set(SUBCOMMANDS) - commands_with_fault_cases(sources))
    assert not missing, (f"subcommands without a fault case in tests/faults/: {missing} "
                         "(add one: see this module's docstring)")
