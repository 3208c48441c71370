"""Every CLI subcommand is also a Python function (simlab.commands)."""

from __future__ import annotations

import pytest

import simlab.commands as commands
from simlab.cli import SUBCOMMANDS, build_parser

#: CLI name -> function name where it is not the name with "-" as "_".
FUNCTION_OF = {"visitlab": "visitlab_train"}


def _function_name(cli_name: str) -> str:
    return FUNCTION_OF.get(cli_name, cli_name.replace("-", "_"))


def test_every_subcommand_has_a_python_function():
    for name in SUBCOMMANDS:
        function = getattr(commands, _function_name(name))
        assert callable(function), name
    assert set(dir(commands)) >= {_function_name(n) for n in SUBCOMMANDS}


def test_every_subcommand_function_takes_its_config():
    """Each command's options are one CommandConfig (simlab.base.options): the function takes
    the config or its fields, and the CLI reads --config files of the same names."""
    from simlab.base.options import CommandConfig

    for name in SUBCOMMANDS:
        function = getattr(commands, _function_name(name))
        assert issubclass(getattr(function, "config_class", type), CommandConfig), name


def test_every_subcommand_is_registered_in_the_parser():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    assert set(sub.choices) == set(SUBCOMMANDS)


def _failing_run(exc):
    def run(args):
        raise exc
    return run


def _drive_runs(monkeypatch, run) -> None:
    """``simlab drive`` runs ``run`` instead (the CLI's error boundary under test)."""
    import simlab.cli as cli

    real = cli.build_parser

    def parser():
        p = real()
        sub = next(a for a in p._actions if a.dest == "command")
        sub.choices["drive"].set_defaults(_run=run)
        return p

    monkeypatch.setattr(cli, "build_parser", parser)


def test_os_errors_become_one_line_and_exit_2(monkeypatch, capsys):
    import errno

    import simlab.cli as cli

    cases = [
        (OSError(errno.ENOSPC, "No space left on device", "/data/out/q.npz"),
         "No space left on device: /data/out/q.npz (free some space"),
        (OSError(errno.EROFS, "Read-only file system", "/ro/x"), "writable file system"),
        (FileExistsError(errno.EEXIST, "File exists", "/tmp/out"), "File exists: /tmp/out"),
        (MemoryError(), "out of memory"),
    ]
    for exc, expected in cases:
        _drive_runs(monkeypatch, _failing_run(exc))
        assert cli.main(["drive"]) == 2
        err = capsys.readouterr().err
        assert err.startswith("simlab drive: error: ") and expected in err, err
        assert err.count("\n") == 1 and "Traceback" not in err


def test_interrupt_is_exit_130(monkeypatch, capsys):
    import simlab.cli as cli

    _drive_runs(monkeypatch, _failing_run(KeyboardInterrupt()))
    assert cli.main(["drive"]) == 130
    assert capsys.readouterr().err == "simlab drive: interrupted\n"


def test_interrupt_inside_compiled_code_is_exit_130(monkeypatch, capsys):
    """A SIGINT that lands inside a numba call surfaces as a SystemError caused by the
    KeyboardInterrupt (CPython's "returned a result with an exception set")."""
    import simlab.cli as cli

    def interrupted_in_numba(args):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as k:
            raise SystemError("<numba function> returned a result with an exception set") from k

    _drive_runs(monkeypatch, interrupted_in_numba)
    assert cli.main(["drive"]) == 130
    assert capsys.readouterr().err == "simlab drive: interrupted\n"


@pytest.mark.parametrize("received", [True, False])
def test_an_error_after_ctrl_c_is_the_interrupt(monkeypatch, capsys, received):
    """A KeyboardInterrupt raised inside numba's compiler can come back as an unrelated
    RuntimeError with no cause chain ("no compiled object yet for <Library ...>"): once the
    program's SIGINT handler has run, that is exit 130; with no SIGINT it stays a bug (1)."""
    import simlab.cli as cli

    def cut_off_compile(args):
        raise RuntimeError("no compiled object yet for <Library 'social_reset'>")

    _drive_runs(monkeypatch, cut_off_compile)
    monkeypatch.setattr(cli, "_sigint_received", received)
    err_code = cli.main(["drive"])
    err = capsys.readouterr().err
    if received:
        assert (err_code, err) == (130, "simlab drive: interrupted\n")
    else:
        assert err_code == 1 and "internal error: RuntimeError" in err, err
