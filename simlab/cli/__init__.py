"""The ``simlab`` command line.

Each subcommand lives in its own module ``simlab/cli/<name>.py`` defining

* ``HELP`` — one line for ``simlab --help``;
* ``add_arguments(parser)`` — its options (no heavy imports here, so ``--help``
  stays fast);
* ``run(args) -> int | None`` — calls the library function (the same one exposed
  in :mod:`simlab.commands`) and prints a short summary.

Library code raises; this module alone turns :class:`~simlab.errors.SimlabError`
(and the file errors people cause: missing files, permissions) into one line on
stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from simlab.errors import SimlabError

#: Subcommand name -> module under simlab.cli. Order is the order of --help.
SUBCOMMANDS: dict[str, str] = {
    "drive": "drive",
    "map": "map",
    "discretize": "discretize",
    "collect": "collect",
    "estimate": "estimate",
    "export-minari": "export_minari",
    "train": "train",
    "replay": "replay",
    "calibrate": "calibrate",
    "pipeline": "pipeline",
    "visitlab": "visitlab",
    "reproduce": "reproduce",
}


def _load(module: str):
    return importlib.import_module(f"simlab.cli.{module}")


def build_parser() -> argparse.ArgumentParser:
    from simlab import __version__

    parser = argparse.ArgumentParser(
        prog="simlab",
        description="Robot reinforcement learning for social navigation (physics arena "
        "and Visit-the-lab simulation).",
    )
    parser.add_argument("--version", action="version", version=f"simlab {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, module_name in SUBCOMMANDS.items():
        try:
            module = _load(module_name)
        except ModuleNotFoundError as exc:  # a subcommand not built yet
            if exc.name != f"simlab.cli.{module_name}":
                raise
            continue
        p = sub.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(p)
        p.set_defaults(_run=module.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "_run", None) is None:
        parser.print_help()
        return 2
    try:
        code = args._run(args)
    except SimlabError as exc:
        print(f"simlab {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except (FileNotFoundError, IsADirectoryError, NotADirectoryError, PermissionError) as exc:
        print(f"simlab {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"simlab {args.command}: interrupted", file=sys.stderr)
        return 130
    return 0 if code is None else int(code)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
