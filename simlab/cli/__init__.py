"""The ``simlab`` command line.

Each subcommand lives in its own module ``simlab/cli/<name>.py`` defining

* ``HELP`` — one line for ``simlab --help``;
* ``add_arguments(parser)`` — its options (no heavy imports here, so ``--help``
  stays fast);
* ``run(args) -> int | None`` — calls the library function (the same one exposed
  in :mod:`simlab.commands`) and prints a short summary.
* ``MEMORY_FIX`` (optional) — how to ask that command for less when it runs out of
  memory, in its own options.

Library code raises; this module alone turns :class:`~simlab.base.errors.SimlabError`,
the operating system's errors (missing files, permissions, a full disk, a read-only
file system, an ``--out`` that is a file) and running out of memory into one line on
stderr and exit code 2; Ctrl-C is ``simlab X: interrupted`` and exit code 130; any other
exception is a bug: one line ``internal error`` and exit code 1 (``-vv`` shows the
traceback). Warnings are one line each (``simlab X: warning: ...``; ``-q`` hides them).
"""

from __future__ import annotations

import argparse
import errno
import importlib
import os
import sys
from collections.abc import Sequence
from typing import Any

from simlab.base.errors import (
    WARNING_PREFIX_ENV,
    WARNINGS_SHOWN_ENV,
    SimlabError,
    show_warnings_as,
)

#: How to ask for less when a command runs out of memory; a subcommand module may define its
#: own ``MEMORY_FIX`` naming its options.
MEMORY_FIX = "fewer hours, trials, states or a coarser grid"

#: Set by the program's SIGINT handler (:func:`console_main`) when Ctrl-C arrives: from then
#: on an unexpected exception is the interrupt's doing, not a bug (see :func:`_run`).
_sigint_received = False

#: Subcommand name -> module under simlab.cli. Order is the order of --help.
SUBCOMMANDS: dict[str, str] = {
    "drive": "drive",
    "map": "map",
    "arena-from-map": "arena",
    "discretize": "discretize",
    "collect": "collect",
    "import-log": "import_log",
    "estimate": "estimate",
    "export-minari": "export_minari",
    "export-bag": "export_bag",
    "import-bag": "import_bag",
    "train": "train",
    "replay": "replay",
    "calibrate": "calibrate",
    "calibrate-pool": "calibrate_pool",
    "transfer": "transfer",
    "pipeline": "pipeline",
    "social-pipeline": "social_pipeline",
    "visitlab": "visitlab",
    "reproduce": "reproduce",
    "online": "online",
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
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="more messages (-v: progress notes, -vv: debug and the traceback "
                        "of an internal error)")
    parser.add_argument("-q", "--quiet", action="count", default=0,
                        help="fewer messages (-q: no warnings, errors only)")
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
        p.set_defaults(_run=module.run, _memory_fix=getattr(module, "MEMORY_FIX", MEMORY_FIX))
    return parser


#: errno -> what to do about it, for the one-line message of an OSError.
_OS_FIXES: dict[int, str] = {
    errno.ENOSPC: "free some space and run again; finished outputs were not replaced",
    errno.EDQUOT: "free some space and run again; finished outputs were not replaced",
    errno.EROFS: "choose an --out on a writable file system",
    errno.EACCES: "check the permissions or choose another path",
    errno.EPERM: "check the permissions or choose another path",
    errno.EEXIST: "choose another path, or remove the file in the way",
    errno.ENOTDIR: "a directory was expected here, or in the path above it, and a file "
                   "is in the way: choose another path",
    errno.EISDIR: "expected a file here, found a directory",
    errno.ENOENT: "check the path",
    errno.ENAMETOOLONG: "choose a shorter path",
}


def describe_os_error(exc: OSError) -> str:
    """One line for an operating-system error: what failed, on which file, and the fix."""
    what = exc.strerror or exc.__class__.__name__
    files = [str(f) for f in (exc.filename, exc.filename2) if f is not None]
    line = f"{what}: {' -> '.join(files)}" if files else what
    fix = _OS_FIXES.get(exc.errno or -1)
    return f"{line} ({fix})" if fix else line


def configure_output(command: str, verbosity: int) -> None:
    """Messages of one run: :mod:`logging` at a level set by ``-v``/``-q`` (default
    WARNING), and every Python warning as one line ``simlab X: warning: ...`` (no source
    line; ``-q`` hides them)."""
    import logging

    level = {-1: logging.ERROR, 0: logging.WARNING, 1: logging.INFO}.get(
        max(-1, min(verbosity, 2)), logging.DEBUG)
    # the "simlab" logger only: the root logger (and a host program's handlers) stay as is
    logger = logging.getLogger("simlab")
    logger.setLevel(level)
    handler = next((h for h in logger.handlers if getattr(h, "simlab_cli", False)), None)
    if handler is None:
        handler = logging.StreamHandler()
        handler.simlab_cli = True  # type: ignore[attr-defined]
        logger.addHandler(handler)
    handler.setFormatter(logging.Formatter(f"simlab {command}: %(levelname)s: %(message)s"))

    # the same in the worker processes the command starts (simlab.base.parallel reads it)
    prefix = f"simlab {command}" if verbosity >= 0 else None
    show_warnings_as(prefix)
    os.environ[WARNING_PREFIX_ENV] = prefix or ""


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "_run", None) is None:
        parser.print_help()
        return 2
    verbosity = args.verbose - args.quiet
    import shutil
    import tempfile
    import warnings

    saved_showwarning = warnings.showwarning
    saved_env = {k: os.environ.get(k) for k in (WARNING_PREFIX_ENV, WARNINGS_SHOWN_ENV)}
    # the warnings this command and its workers printed (each once: see WARNINGS_SHOWN_ENV);
    # the folder is made by the first warning, so a command that warns of nothing makes none
    shown = os.path.join(tempfile.gettempdir(),
                         f"simlab-warnings-{os.getpid()}-{os.urandom(6).hex()}")
    os.environ[WARNINGS_SHOWN_ENV] = shown
    configure_output(args.command, verbosity)
    try:
        return _run(args, verbosity)
    finally:
        warnings.showwarning = saved_showwarning
        for key, value in saved_env.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
        shutil.rmtree(shown, ignore_errors=True)


def console_main() -> int:
    """The ``simlab`` program (console script and ``python -m simlab``): :func:`main`, with
    Ctrl-C reported in one line and exit code 130 wherever it lands.

    * A KeyboardInterrupt that escapes :func:`main` (Ctrl-C during the imports a command
      makes before it runs) is ``simlab: interrupted``, exit code 130.
    * Once Ctrl-C has arrived, the destructors of objects it left half-made print nothing
      (a PyBullet client cut off inside ``connect``, an llvmlite pass of a numba compile):
      Python would report each as an ignored exception with a traceback after the line
      that already says what happened.
    * Once the command has returned, its exit code stands: SIGINT is ignored from then on.
      A SIGINT that lands inside compiled (numba) code can surface again during shutdown,
      and Python restores the default action of SIGINT while it finalizes (a handler of
      our own is dropped then; only ``SIG_IGN`` is kept), so a Ctrl-C in the last moments
      killed the process by the signal (exit -2, nothing printed) even after the export
      it interrupted had been reported, or had finished. Switching to ``SIG_IGN`` while a
      caught signal is pending makes Python report ``Signal 2 ignored due to race
      condition``: that report is dropped with the others.

    Only the program does this: in-process callers of :func:`main` (tests, notebooks) keep
    their handlers and hooks."""
    import signal

    global _sigint_received
    interrupted = False
    _sigint_received = False

    def on_sigint(signum: int, frame: object) -> None:
        global _sigint_received
        nonlocal interrupted
        interrupted = _sigint_received = True
        raise KeyboardInterrupt

    report_unraisable = sys.unraisablehook

    def unraisable(args: Any) -> None:
        race = isinstance(args.exc_value, OSError) and "race condition" in str(args.exc_value)
        if not (interrupted or race):
            report_unraisable(args)

    signal.signal(signal.SIGINT, on_sigint)
    sys.unraisablehook = unraisable
    try:
        code = main()
    except KeyboardInterrupt:
        print("simlab: interrupted", file=sys.stderr)
        code = 130
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _sigint_received = False  # a later in-process main() reports its own errors again
    _forget_unhandled_interrupt()
    return code


def _forget_unhandled_interrupt() -> None:
    """Clear CPython's note that a KeyboardInterrupt went unhandled, so the exit code
    :func:`console_main` returns is the one the process exits with.

    CPython notes an interrupt that escapes code run through its string-eval API (the
    flag ``_Py_UnhandledKeyboardInterrupt``, pythonrun.c), even when Python code further
    up then handles it, and after ``python -m`` returns it exits by SIGINT (-2) whenever
    the note is set: a Ctrl-C that ``simlab train`` reported did exit -2 in about 1 run in
    10. (The installed program exits through ``Py_Exit`` on ``SystemExit``, before the
    note is read, so it never did.) Running an empty string through that API clears the
    note (``run_eval_code_obj`` resets it first): public C API, where ctypes can reach it.
    """
    try:
        import ctypes

        ctypes.pythonapi.PyRun_SimpleString(b"")
    except (ImportError, AttributeError, OSError):  # no ctypes, or a Python without it
        pass


def _caused_by_interrupt(exc: BaseException) -> bool:
    """True when Ctrl-C is behind ``exc``: a SIGINT that lands inside a numba-compiled call
    surfaces as ``SystemError: ... returned a result with an exception set`` whose cause is
    the KeyboardInterrupt."""
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        if isinstance(e, KeyboardInterrupt):
            return True
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return False


def _run(args: argparse.Namespace, verbosity: int) -> int:
    """Run the subcommand; the error boundary (module docstring)."""
    try:
        code = args._run(args)
    except SimlabError as exc:
        print(f"simlab {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"simlab {args.command}: error: {describe_os_error(exc)}", file=sys.stderr)
        return 2
    except MemoryError:
        fix = getattr(args, "_memory_fix", MEMORY_FIX)
        print(f"simlab {args.command}: error: out of memory (ask for less: {fix})",
              file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"simlab {args.command}: interrupted", file=sys.stderr)
        return 130
    except RecursionError:
        print(f"simlab {args.command}: error: an input is nested too deeply to read",
              file=sys.stderr)
        return 2
    except Exception as exc:  # a bug: one line (exit 1), the traceback with -vv
        # After Ctrl-C, whatever the interrupt cut off is reported as the interrupt: a
        # KeyboardInterrupt raised inside numba's compiler can come back as a RuntimeError
        # ("no compiled object yet for <Library ...>") with nothing linking it to the signal
        if _sigint_received or _caused_by_interrupt(exc):
            print(f"simlab {args.command}: interrupted", file=sys.stderr)
            return 130
        if verbosity >= 2:
            raise
        print(f"simlab {args.command}: internal error: {type(exc).__name__}: "
              f"{' '.join(str(exc).split())[:300]} (a bug in simlab: please report it; "
              "run with -vv for the traceback)", file=sys.stderr)
        return 1
    return 0 if code is None else int(code)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(console_main())
