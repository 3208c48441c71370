"""Pages of the documentation site generated from the code, and the check of its examples.

Used by ``docs/hooks.py`` during ``mkdocs build`` (and by ``tests/docs``):

* :func:`commands_markdown` — every subcommand of ``simlab.cli.SUBCOMMANDS`` with every
  option of its parser, the option's default and help taken from the command's
  ``CommandConfig`` field (a renamed or removed option changes this page);
* :func:`envs_markdown` — every registered Gymnasium id with its env card (the class
  docstring, shown by mkdocstrings);
* :func:`dataset_markdown` — the dataset's Parquet columns (unit, meaning) and manifest
  fields, from ``simlab.data.schema`` and ``simlab.data.manifest``;
* :func:`check_command_lines` — every ``simlab ...`` line in a page's code blocks names an
  existing subcommand and existing options, so an example cannot outlive a rename;
* :func:`make_figures` — the guide's figures, made by the commands the guide shows;
* :func:`api_markdown` — an API page: every public module of a package, for mkdocstrings.

The command reference reads the parsers' ``_actions`` (and a sub-parser action's
``_choices_actions`` for the one-line helps): argparse has no public way to list a parser's
arguments, and the parsers are what users run, so reading them keeps the page true to the
command line even for the arguments a command adds beside its ``CommandConfig``. Those
attributes have kept their names and types since argparse entered the standard library
(Python 3.2); ``tests/docs`` builds the page from them, so a change there fails a test, not
the site. Packaged generators of argparse docs (``sphinx-argparse`` for Sphinx) read the same
attributes, so a library would move the reading, not remove it, and would not take each
option's default and help from its ``CommandConfig`` field as this page does.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import importlib
import re
import shlex
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

__all__ = ["API_PAGES", "FIGURES", "api_markdown", "check_command_lines", "command_parsers",
           "commands_markdown", "dataset_markdown", "envs_markdown", "make_figures",
           "public_modules"]


# -- the command line, read from its own parsers -----------------------------------------

@dataclasses.dataclass
class ParsedCommand:
    """One (sub)command: its name (``"visitlab train"``), one-line help, parser and the
    config class whose fields generate its options (None for hand-written options)."""

    name: str
    help: str
    parser: argparse.ArgumentParser
    configs: list[type]


@contextlib.contextmanager
def _recording(seen: list[tuple[argparse.ArgumentParser, type]]) -> Iterator[None]:
    """Record which ``CommandConfig`` generates the options of which parser."""
    from simlab.base.options import CommandConfig

    original = CommandConfig.__dict__["add_arguments"]

    def add_arguments(cls: type, parser: argparse.ArgumentParser, **kw: Any) -> None:
        seen.append((parser, cls))
        original.__func__(cls, parser, **kw)

    CommandConfig.add_arguments = classmethod(add_arguments)  # type: ignore[method-assign]
    try:
        yield
    finally:
        CommandConfig.add_arguments = original  # type: ignore[method-assign]


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, tuple[str, argparse.ArgumentParser]]:
    out: dict[str, tuple[str, argparse.ArgumentParser]] = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {a.dest: a.help or "" for a in action._choices_actions}
            for name, sub in action.choices.items():
                out[name] = (helps.get(name, ""), sub)
    return out


def command_parsers() -> list[ParsedCommand]:
    """Every subcommand (and sub-action, ``visitlab train``) with its parser, in the order
    of ``simlab --help``."""
    from simlab.cli import SUBCOMMANDS

    seen: list[tuple[argparse.ArgumentParser, type]] = []
    out: list[ParsedCommand] = []
    with _recording(seen):
        for name, module_name in SUBCOMMANDS.items():
            try:
                module = importlib.import_module(f"simlab.cli.{module_name}")
            except ModuleNotFoundError as exc:  # as `simlab --help`: a command not built yet
                if exc.name != f"simlab.cli.{module_name}":
                    raise
                continue
            parser = argparse.ArgumentParser(prog=f"simlab {name}", description=module.HELP)
            module.add_arguments(parser)
            subs = _subparsers(parser)
            if not subs:
                out.append(ParsedCommand(name, module.HELP, parser, []))
            for sub_name, (sub_help, sub) in subs.items():
                out.append(ParsedCommand(f"{name} {sub_name}", sub_help, sub, []))
    for cmd in out:
        cmd.configs = [cls for p, cls in seen if p is cmd.parser]
    return out


def _default_text(value: Any) -> str:
    if value is dataclasses.MISSING:
        return "required"
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, tuple):
        return ", ".join(map(str, value)) or "()"
    return str(value)


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ").strip()


def _python_functions() -> dict[type, str]:
    """Config class -> the ``simlab.commands`` function that takes it."""
    import simlab.commands

    out: dict[type, str] = {}
    for name in simlab.commands.__all__:
        cls = getattr(getattr(simlab.commands, name), "config_class", None)
        if cls is not None:
            out.setdefault(cls, f"simlab.commands.{name}")
    return out


def commands_markdown() -> str:
    """The reference of every command's options (Markdown)."""
    functions = _python_functions()
    lines = ["Generated from the commands' parsers and config dataclasses at build time: "
             "each option's default and meaning are the ones `--help` prints.", ""]
    for cmd in command_parsers():
        lines += [f"## `simlab {cmd.name}`", "", _cell(cmd.help) + ".", ""]
        fields: dict[str, dataclasses.Field[Any]] = {}
        for cls in cmd.configs:
            path = f"{cls.__module__}.{cls.__qualname__}"
            fn = functions.get(cls)
            where = f" Python: `{fn}(...)` takes it or the same names as keywords." if fn else ""
            lines += [f"Options are the fields of `{path}`; `--config FILE` reads them from "
                      f"a TOML file.{where}", ""]
            fields.update({f.name: f for f in dataclasses.fields(cls)})
        lines += ["| option | default | meaning |", "|---|---|---|"]
        shown: set[str] = set()
        for action in cmd.parser._actions:
            if isinstance(action, argparse._HelpAction | argparse._SubParsersAction):
                continue
            flag = ", ".join(f"`{s}`" for s in action.option_strings) or f"`{action.dest}`"
            f = fields.get(action.dest)
            if f is not None and action.dest not in shown:
                default = _default_text(f.default)
                meaning = f.metadata.get("help", "")
                if f.metadata.get("choices"):
                    meaning += " (one of " + ", ".join(map(str, f.metadata["choices"])) + ")"
                shown.add(action.dest)
            else:
                suppressed = action.default in (None, argparse.SUPPRESS, [], False)
                default = "" if suppressed else _default_text(action.default)
                meaning = action.help or ""
            lines.append(f"| {flag} | {_cell(default)} | {_cell(meaning)} |")
        hidden = [f for f in fields.values() if not f.metadata.get("cli", True)]
        if hidden:
            lines += ["", "Settable from Python and TOML only: " + "; ".join(
                f"`{f.name}` (default {_default_text(f.default)}): {f.metadata.get('help', '')}"
                for f in hidden)]
        lines.append("")
    return "\n".join(lines)


# -- checking the examples of the pages ---------------------------------------------------

_FENCE = re.compile(r"^```[^\n]*\n(.*?)^```", re.S | re.M)


def _command_lines(markdown: str) -> Iterator[str]:
    """``simlab ...`` command lines of the fenced code blocks (continuations joined)."""
    for block in _FENCE.findall(markdown):
        block = re.sub(r"\\\n\s*", " ", block)
        for line in block.splitlines():
            line = line.split(" #", 1)[0].strip()
            line = re.sub(r"^(?:\$\s*)?(?:pip install \S+ && )?", "", line)
            if line.startswith("simlab ") and not line.startswith("simlab."):
                yield " ".join(line.split())


def check_command_lines(markdown: str, commands: list[ParsedCommand] | None = None
                        ) -> list[str]:
    """Problems of the ``simlab ...`` lines of ``markdown``'s code blocks: an unknown
    subcommand or an option its parser does not have. Empty when all is well."""
    commands = command_parsers() if commands is None else commands
    by_name = {c.name: c for c in commands}
    problems = []
    for line in _command_lines(markdown):
        try:
            words = shlex.split(line.replace("[", " ").replace("]", " "))
        except ValueError:
            words = line.split()
        words = [w for w in words[1:] if not w.startswith("-v") and w not in ("-q",)]
        name = " ".join(words[:2]) if " ".join(words[:2]) in by_name else (
            words[0] if words else "")
        if name not in by_name:
            problems.append(f"unknown command in `{line}`")
            continue
        known = {s for a in by_name[name].parser._actions for s in a.option_strings}
        for w in words:
            flag = w.split("=", 1)[0]
            if flag.startswith("--") and flag not in known:
                problems.append(f"`simlab {name}` has no option {flag} (in `{line}`)")
    return problems


# -- environments and the dataset ---------------------------------------------------------

def envs_markdown() -> str:
    """One section per registered id, its card rendered by mkdocstrings."""
    from simlab.envs import ENV_ENTRY_POINTS, ENV_LIMITS

    lines = ["Every id is also `simlab:<id>` (Gymnasium imports `simlab` first), the form to "
             "use in fresh processes such as `AsyncVectorEnv(..., context=\"spawn\")` "
             "workers. Generated from `simlab.envs.ENV_ENTRY_POINTS`.", ""]
    for env_id, entry in ENV_ENTRY_POINTS.items():
        module_name, cls_name = entry.split(":")
        module = importlib.import_module(module_name)
        cls = getattr(module, cls_name)
        limit = ENV_LIMITS.get(env_id, (None, {}))[0]
        # the card: the class docstring, or the module's when the class has one line only
        class_doc = (cls.__doc__ or "").strip().splitlines()
        target = (f"{cls.__module__}.{cls.__qualname__}" if len(class_doc) > 1
                  else cls.__module__)
        lines += [f"## `{env_id}`", "",
                  f"```python\nenv = gym.make(\"simlab:{env_id}\")"
                  f"  # {cls.__module__}.{cls.__qualname__}"
                  + (f", max_episode_steps={limit}" if limit else "") + "\n```", "",
                  f"::: {target}", "    options:", "      show_root_heading: false",
                  "      members: false", ""]
    return "\n".join(lines)


def dataset_markdown() -> str:
    """The Parquet columns and manifest fields of a transition dataset (Markdown tables)."""
    from simlab.data import manifest, schema

    table = schema.transition_schema("odometry", twin_member=True)
    lines = ["| column | Arrow type | unit | meaning |", "|---|---|---|---|"]
    for f in table:
        unit, meaning = schema.COLUMN_DOCS.get(f.name, ("", ""))
        lines.append(f"| `{f.name}` | {f.type} | {unit} | {_cell(meaning)} |")
    lines += ["", "The `x_true` ... columns exist only for the simulated pose sources "
              f"({', '.join(s for s in schema.POSE_SOURCE_NAMES if s not in schema.NO_TRUTH_SOURCES)}); "
              "`twin_member` only in a dataset of `simlab collect --ensemble` (its manifest's "
              "`parameters.ensemble` holds the members' records and the member of each walk).",
              "", "Manifest `_manifest.json` fields (checked on read):", "",
              "| field | JSON type | required |", "|---|---|---|"]
    for required, fields in ((True, manifest.MANIFEST_SCHEMA), (False, manifest.OPTIONAL_SCHEMA)):
        for name, types in fields.items():
            kinds = " or ".join("null" if t is type(None) else
                                {"dict": "object", "list": "array", "str": "string",
                                 "int": "integer", "float": "number", "bool": "boolean"}
                                .get(t.__name__, t.__name__) for t in types)
            lines.append(f"| `{name}` | {kinds} | {'yes' if required else 'no'} |")
    lines += ["", "Every entry of `parts`: " + ", ".join(
        f"`{k}`" for k in manifest.PART_SCHEMA) + "."]
    return "\n".join(lines)


# -- figures made by the commands the guide shows ------------------------------------------

#: figure file -> the command lines that make it (run in order, in one scratch folder)
FIGURES: dict[str, list[list[str]]] = {
    "drive.png": [["drive", "--arena", "table", "--steps", "100", "--seed", "0",
                   "--png", "drive.png", "--no-progress"]],
    "states.png": [["map", "--arena", "table", "--minutes", "3", "--seed", "0", "--out", "map",
                    "--no-progress"],
                   ["discretize", "--map", "map/map.yaml", "--states", "41", "--out",
                    "states.json", "--png", "states.png", "--no-progress"]],
    "visitlab_show.txt": [["visitlab", "show", "--task", "gotohuman", "--steps", "1"]],
}


class FigureError(RuntimeError):
    """A command of :data:`FIGURES` failed (its message is the command's own line)."""


def make_figures(folder: Path) -> dict[str, Path]:
    """Run :data:`FIGURES`'s commands in ``folder`` (``python -m simlab``); ``{name: file}``.

    The figures' command chains run side by side (each chain in order); text outputs
    (``.txt``) are the command's standard output. The commands' temporary files (the
    merged robot URDF simlab caches in the temporary directory) go to ``folder/tmp``, so
    that removing ``folder`` leaves nothing behind. A command that fails raises
    :class:`FigureError` with its own one-line message.
    """
    import os
    from concurrent.futures import ThreadPoolExecutor

    folder.mkdir(parents=True, exist_ok=True)
    tmp = folder / "tmp"
    tmp.mkdir(exist_ok=True)
    env = {**os.environ, "TMPDIR": str(tmp)}

    def chain(name: str) -> Path:
        for argv in FIGURES[name]:
            done = subprocess.run([sys.executable, "-m", "simlab", "-q", *argv], cwd=folder,
                                  capture_output=True, text=True, env=env)
            if done.returncode != 0:
                raise FigureError(f"simlab {' '.join(argv)} failed: "
                                  f"{' '.join(done.stderr.split())}")
            if name.endswith(".txt"):
                (folder / name).write_text(done.stdout)
        return folder / name

    with ThreadPoolExecutor(max_workers=len(FIGURES)) as pool:
        return dict(zip(FIGURES, pool.map(chain, FIGURES), strict=True))


# -- the API reference: every public module ------------------------------------------------

#: API page -> the packages whose every public module it renders (a module in two packages'
#: lists is rendered on the first page only). ``simlab.envs`` has its own hand-made page
#: (its classes are on the environments page).
API_PAGES: dict[str, tuple[str, ...]] = {
    "simlab": ("simlab", "simlab.commands", "simlab.cli"),
    "agents": ("simlab.agents",), "base": ("simlab.base",),
    "calibration": ("simlab.calibration",), "data": ("simlab.data",),
    "discretize": ("discretize",), "experiments": ("simlab.experiments",),
    "localization": ("simlab.localization",), "online": ("simlab.online",),
    "orchestration": ("simlab.orchestration",), "physics": ("simlab.physics",),
    "replay": ("simlab.replay",), "ros": ("simlab.ros",), "social": ("simlab.social",),
    "training": ("simlab.training",), "visitlab": ("simlab.visitlab",),
}
#: Packages documented by hand-made pages instead (see :data:`API_PAGES`).
CURATED = ("simlab.envs",)


def public_modules(package: str, *, recursive: bool = True) -> list[str]:
    """``package`` and its modules and subpackages whose names do not start with ``_``
    (``__main__`` excluded), in name order; a plain module is a list of itself."""
    import pkgutil

    mod = importlib.import_module(package)
    names = [package]
    if not hasattr(mod, "__path__"):
        return names
    for info in sorted(pkgutil.iter_modules(mod.__path__), key=lambda i: i.name):
        if info.name.startswith("_"):
            continue
        full = f"{package}.{info.name}"
        if info.ispkg and recursive:
            names += public_modules(full)
        elif info.ispkg or info.name != "__main__":
            names.append(full)
    return names


def api_markdown(page: str) -> str:
    """The ``::: module`` lines of API page ``page`` (:data:`API_PAGES`): every public module
    of its packages (of ``simlab`` itself only the top module)."""
    lines = []
    for package in API_PAGES[page]:
        top = package == "simlab"
        for name in public_modules(package, recursive=not top):
            if top and name != "simlab":
                continue
            if any(name == c or name.startswith(c + ".") for c in CURATED):
                continue
            shown = _ENV_CARDS.get(name)
            lines.append(f"::: {name}" if not shown else
                         f"::: {name}\n    options:\n      filters: [\"!^_\", "
                         + ", ".join(f'\"!^{c}$\"' for c in shown) + "]")
    return "\n\n".join(lines)


def _env_cards() -> dict[str, list[str]]:
    """module -> its env classes, whose cards the environments page renders (an object
    rendered on two pages would have two addresses)."""
    from simlab.envs import ENV_ENTRY_POINTS

    cards: dict[str, list[str]] = {}
    for entry in ENV_ENTRY_POINTS.values():
        module, cls = entry.split(":")
        cards.setdefault(module, []).append(cls)
    return cards


_ENV_CARDS = _env_cards()
