"""Every CLI subcommand is also a Python function (simlab.commands)."""

from __future__ import annotations

import simlab.commands as commands
from simlab.cli import SUBCOMMANDS, build_parser

#: CLI name -> function name where they differ.
FUNCTION_OF = {"export-minari": "export_minari", "visitlab": "visitlab_train"}


def test_every_subcommand_has_a_python_function():
    for name in SUBCOMMANDS:
        function = getattr(commands, FUNCTION_OF.get(name, name))
        assert callable(function), name
    assert set(dir(commands)) >= {FUNCTION_OF.get(n, n) for n in SUBCOMMANDS}


def test_every_subcommand_is_registered_in_the_parser():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    assert set(sub.choices) == set(SUBCOMMANDS)
