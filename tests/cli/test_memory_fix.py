"""The out-of-memory line tells the user how to ask the command for less: every option it
names is one of that command's own options."""

from __future__ import annotations

import argparse
import re

from simlab.cli import build_parser


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def test_every_memory_fix_names_only_the_commands_own_options() -> None:
    named = 0
    for name, sub in _subparsers(build_parser()).items():
        fix = sub.get_default("_memory_fix")
        assert isinstance(fix, str) and fix, name
        flags = set(re.findall(r"--[a-z][a-z0-9-]*", fix))
        named += len(flags)
        own = {s for a in sub._actions for s in a.option_strings}
        assert flags <= own, f"simlab {name}: the memory fix names {sorted(flags - own)}"
    assert named >= 4  # online's and transfer's fixes name their options
