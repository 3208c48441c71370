"""simlab's dataclass-to-argparse layer against tyro and simple-parsing.

Every ``simlab`` command, and ``--help``, pays the import of the layer that builds its
options and the building of its parser. The script prints, median of 5 fresh interpreters,
the import time of ``argparse``, ``simlab.base.options`` (which imports argparse), ``tyro``
and ``simple_parsing``, then the time to build a parser for one 6-field config and parse a
command line with each (in this process, best of 3 x 50).

Libraries that are not installed are reported as such; to measure them without adding them
to the environment: ``pip install --target /tmp/cliparse tyro simple-parsing`` and
``python benchmarks/cli_parsers.py /tmp/cliparse``.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import os
import statistics
import subprocess
import sys
import timeit
from pathlib import Path

from simlab.base.options import CommandConfig, option

_IMPORT = ("import time; t = time.perf_counter(); import {module}; "
           "print(time.perf_counter() - t)")
ARGV = ["data", "--out", "m.npz", "--episodes", "12", "--gamma", "0.9", "--no-plot"]


def import_seconds(module: str, extra: str | None, repeats: int = 5) -> float | None:
    """Median seconds of ``import module`` in a fresh interpreter (None: not installed)."""
    env = dict(os.environ)
    if extra:
        env["PYTHONPATH"] = os.pathsep.join(p for p in (extra, env.get("PYTHONPATH")) if p)
    times = []
    for _ in range(repeats):
        res = subprocess.run([sys.executable, "-c", _IMPORT.format(module=module)],
                             capture_output=True, text=True, env=env)
        if res.returncode != 0:
            return None
        times.append(float(res.stdout))
    return statistics.median(times)


@dataclasses.dataclass(frozen=True, kw_only=True)
class OursConfig(CommandConfig):
    """A config as simlab's commands spell theirs."""

    COMMAND = "bench"
    dataset: Path = option(help="dataset directory", positional=True)
    out: Path = option(help="model file")
    episodes: int = option(10, "episodes per run")
    gamma: float = option(0.95, "discount")
    plot: bool = option(True, "write the plot")
    tag: str | None = option(None, "a label")


@dataclasses.dataclass(frozen=True)
class PlainConfig:
    """The same fields as a plain dataclass (what tyro and simple-parsing read)."""

    dataset: Path
    out: Path
    episodes: int = 10
    gamma: float = 0.95
    plot: bool = True
    tag: str | None = None


def _ours() -> object:
    import argparse

    parser = argparse.ArgumentParser()
    OursConfig.add_arguments(parser)
    return OursConfig.from_args(parser.parse_args(ARGV))


def _tyro() -> object:
    import tyro

    argv = ["--dataset", "data", "--out", "m.npz", "--episodes", "12", "--gamma", "0.9",
            "--no-plot"]
    return tyro.cli(PlainConfig, args=argv)


def _simple_parsing() -> object:
    import simple_parsing

    argv = ["--dataset", "data", "--out", "m.npz", "--episodes", "12", "--gamma", "0.9",
            "--plot", "false"]
    return simple_parsing.parse(PlainConfig, args=argv)


def main() -> None:
    extra = sys.argv[1] if len(sys.argv) > 1 else None
    for module in ("argparse", "simlab.base.options", "tyro", "simple_parsing"):
        t = import_seconds(module, extra)
        print(f"import {module:22s} " + ("not installed" if t is None else f"{t * 1e3:7.1f} ms"))
    if extra:
        sys.path.insert(0, extra)
    for name, fn, module in (("simlab.base.options", _ours, None), ("tyro", _tyro, "tyro"),
                             ("simple_parsing", _simple_parsing, "simple_parsing")):
        if module is not None and importlib.util.find_spec(module) is None:
            continue
        fn()  # the first call pays the import
        n = 50
        t = min(timeit.repeat(fn, number=n, repeat=3)) / n
        print(f"build + parse, {name:20s} {t * 1e3:7.2f} ms")


if __name__ == "__main__":
    main()
