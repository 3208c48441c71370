"""Command options as one frozen, validated, documented dataclass (CleanRL's ``Args``).

A command's options are spelled once, as the fields of a dataclass::

    @dataclass(frozen=True, kw_only=True)
    class EstimateConfig(CommandConfig):
        dataset: Path | None = option(None, "dataset directory written by `simlab collect`",
                                      positional=True)
        out: Path = option(help="model file mdp.npz")
        plot: bool = option(True, "write the entropy bar plot")

and everything else is generated from them:

* ``EstimateConfig.add_arguments(parser)`` — the argparse options (``--out``, ``--no-plot``
  for a bool that defaults to true, ``--n-states`` for ``n_states``), each with its help
  text and default, plus ``--config FILE`` (a TOML file of the same fields; options given
  on the command line win over the file, the file over the defaults);
  a ``bool | None`` field that defaults to None (unset: decided elsewhere) gets both
  ``--name`` and ``--no-name``;
* ``EstimateConfig.from_args(namespace)`` and ``EstimateConfig.from_toml(path)``;
* :func:`command` — the Python function takes the config (``estimate(cfg)``) or the same
  fields as arguments (``estimate(dataset, out=..., plot=False)``), so the function's
  signature is the dataclass's.

Fields are checked at construction by their annotation (``int`` a whole number, ``float``
a finite number, ``bool`` true/false, ``str``, ``Path`` — strings become paths —, with
``| None`` allowing None, ``tuple[...]`` from lists) and then by the class's own
``validate()`` (ranges, choices, combinations), so a config that exists is a valid config.

Why argparse under our own layer and not tyro or simple-parsing (which also make a CLI
from a dataclass): measured by ``benchmarks/cli_parsers.py`` (median of 5 fresh
interpreters, 2-core VM), importing tyro 1.0 costs 46 ms and simple-parsing 0.1.9 60 ms,
on top of what every ``simlab`` command and ``--help`` already imports (argparse 2 ms; this
module with simlab's base 36 ms); building a parser for a 6-field config and parsing a
command line takes 0.5 ms here, 1.8 ms in tyro, 2.4 ms in simple-parsing. Neither is
slower to write against, but swapping would change the command lines the thesis scripts
and tests use (positional arguments, ``--no-x`` flags, ``--config`` TOML files with the
command line winning over the file, ``bool | None`` given both ways) across every command,
for no gain in speed.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import inspect
import numbers
import operator
import os
import types
import typing
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, ClassVar, TypeVar

from simlab.base.errors import ConfigError

__all__ = ["CommandConfig", "command", "option"]

C = TypeVar("C", bound="CommandConfig")

_MISSING = dataclasses.MISSING


class _Unset:
    """argparse default of every generated option: "not given on the command line"."""

    def __repr__(self) -> str:
        return "<not given>"


_UNSET = _Unset()


def option(default: Any = _MISSING, help: str = "", *, positional: bool = False,
           choices: tuple[Any, ...] | None = None, metavar: str | None = None,
           flag: str | None = None, cli: bool = True, parse: Callable[[str], Any] | None = None
           ) -> Any:
    """A documented field of a :class:`CommandConfig`.

    ``default`` — omitted: the option is required. ``help`` — one line for ``--help``
    (units in it). ``positional`` — an argument without ``--`` (optional when it has a
    default). ``choices`` — the allowed values (argparse and construction both refuse
    others). ``flag`` — the option's name on the command line when it is not the field's
    name with dashes. ``cli=False`` — settable from Python and TOML only. ``parse`` — how the
    command line's string becomes the field's value (default: by the annotation).
    """
    meta = {"help": help, "positional": positional, "choices": choices, "metavar": metavar,
            "flag": flag, "cli": cli, "parse": parse}
    if isinstance(default, list | dict | set):
        raise TypeError("mutable defaults: use a tuple")
    return dataclasses.field(default=default, metadata=meta)


class CommandConfig:
    """Base of every command's options (subclasses are ``@dataclass(frozen=True,
    kw_only=True)``: keyword-only, so a required field may follow one with a default).

    Subclasses set ``COMMAND`` (the subcommand's name, for messages) and may define
    ``validate(self)`` for checks beyond the field types (it may also normalise values
    with ``object.__setattr__``).
    """

    COMMAND: ClassVar[str] = ""
    #: The fields a call may give positionally, in order (default: every field, in field
    #: order). Set it when field groups from base classes come first in the field order.
    ARGUMENTS: ClassVar[tuple[str, ...]] = ()
    #: Fields of which at most one may be given on the command line (one argparse mutually
    #: exclusive group); ``validate()`` checks the same for files and Python calls.
    EXCLUSIVE: ClassVar[tuple[str, ...]] = ()

    # -- construction -----------------------------------------------------------------

    def __post_init__(self) -> None:
        hints = _hints(type(self))
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            value = getattr(self, f.name)
            new = _coerce(value, hints[f.name], f.name)
            if new is not None and _is_seed(f.name, hints[f.name]):
                _check_seed(new, f.name)
            choices = f.metadata.get("choices")
            if choices is not None and new is not None and new not in choices:
                raise ConfigError(f"expected one of {', '.join(map(str, choices))}; "
                                  f"got {value!r}", key=f.name)
            if new is not value:
                object.__setattr__(self, f.name, new)
        self.validate()

    def validate(self) -> None:
        """Checks beyond the field types (override)."""

    @classmethod
    def from_mapping(cls: type[C], values: Mapping[str, Any], *,
                     path: str | os.PathLike[str] | None = None) -> C:
        """Build from a mapping of field names or long option names (``--id`` of a field
        ``dataset_id``: key ``id``; dashes or underscores); unknown keys, a field given
        twice and missing required fields name the file and the key."""
        known = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
        kwargs = cls._by_field(values, path)
        missing = [f for f in known.values() if f.name not in kwargs
                   and f.default is _MISSING and f.default_factory is _MISSING]
        if missing:
            flags = ", ".join(f"{f.name} ({_flag_name(f)})" for f in missing)
            raise ConfigError(f"missing required option(s): {flags}", path=path,
                              key=missing[0].name)
        try:
            return cls(**kwargs)
        except ConfigError as exc:
            if path is None or exc.path is not None:
                raise
            raise ConfigError(exc.problem, path=path, key=exc.key, fix=exc.fix) from None

    @classmethod
    def _by_field(cls, values: Mapping[str, Any], path: str | os.PathLike[str] | None
                  ) -> dict[str, Any]:
        """``values`` keyed by field name: a key is a field name or a long option name
        (dashes or underscores); an unknown key or a field given twice is a ConfigError
        naming the file and the key."""
        known = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
        alias = {f.metadata["flag"].replace("-", "_"): f.name for f in known.values()
                 if f.metadata.get("flag")}
        out: dict[str, Any] = {}
        for key, value in values.items():
            name = key.replace("-", "_")
            name = name if name in known else alias.get(name, name)
            if name not in known:
                raise ConfigError(f"unknown option {key!r}", path=path, key=key,
                                  fix="known options: " + ", ".join(sorted({*known, *alias})))
            if name in out:
                raise ConfigError(f"option {name!r} given twice (as its field name and as "
                                  "its option name)", path=path, key=key,
                                  fix="keep one of the two keys")
            out[name] = value
        return out

    @classmethod
    def from_toml(cls: type[C], path: str | os.PathLike[str], table: str | None = None) -> C:
        """Read the options from a TOML file (the whole file, or one ``[table]``)."""
        from simlab.base.io import read_toml

        data = read_toml(path)
        if table is not None:
            if not isinstance(data.get(table), dict):
                raise ConfigError(f"no [{table}] table", path=path, key=table)
            data = data[table]
        return cls.from_mapping(data, path=path)

    def replace(self: C, **changes: Any) -> C:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)  # type: ignore[type-var]

    def to_dict(self) -> dict[str, Any]:
        """Field values as JSON/TOML-friendly Python (paths as strings, tuples as lists)."""
        return {f.name: _plain(getattr(self, f.name))
                for f in dataclasses.fields(self)}  # type: ignore[arg-type]

    # -- command line -----------------------------------------------------------------

    @classmethod
    def add_arguments(cls, parser: argparse.ArgumentParser, *, config_file: bool = True) -> None:
        """Add one argparse option per field (an option not given stays a marker in the
        namespace so that :meth:`from_args` can tell it from one given)."""
        hints = _hints(cls)
        group = parser.add_mutually_exclusive_group() if cls.EXCLUSIVE else parser
        for f in dataclasses.fields(cls):  # type: ignore[arg-type]
            if f.metadata.get("cli", True):
                _add_field(group if f.name in cls.EXCLUSIVE else parser, f, hints[f.name])
        if config_file:
            parser.add_argument("--config", default=None, metavar="FILE",
                                help="TOML file of these options (keys as the long option "
                                     "names); options on the command line win")

    @classmethod
    def from_args(cls: type[C], args: argparse.Namespace) -> C:
        """Defaults, then ``--config FILE``, then the options given on the command line."""
        values: dict[str, Any] = {}
        config_path = getattr(args, "config", None)
        if config_path is not None:
            from simlab.base.io import read_toml

            values.update(cls._by_field(read_toml(config_path), config_path))
        names = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
        values.update({k: v for k, v in vars(args).items()
                       if k in names and v is not _UNSET})
        return cls.from_mapping(values, path=config_path)


def command(config_cls: type[C], *, extras: tuple[str, ...] = ()
            ) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """Decorate ``fn(cfg)`` so it also takes the config's fields as arguments.

    ``fn(cfg)`` with a ``config_cls`` instance runs as is; ``fn(*args, **kwargs)`` builds
    the config first, positional arguments taken in the order of ``ARGUMENTS`` (default:
    the dataclass's fields) (``estimate(dataset, out, plot=False)``). ``extras`` name
    keyword arguments that are not options but run-time objects (a log callback) and go to
    ``fn`` beside the config. An unknown keyword is a :class:`ConfigError` naming it and
    the known options. ``help(fn)`` shows every option.
    """
    fields = [f.name for f in dataclasses.fields(config_cls)]  # type: ignore[arg-type]
    names = list(config_cls.ARGUMENTS) or fields

    def wrap(fn: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(fn)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            runtime = {k: kwargs.pop(k) for k in extras if k in kwargs}
            if len(args) == 1 and not kwargs and isinstance(args[0], config_cls):
                return fn(args[0], **runtime)
            if len(args) > len(names):
                raise TypeError(f"{fn.__name__}() takes at most {len(names)} positional "
                                f"arguments ({len(args)} given)")
            for name, value in zip(names, args, strict=False):
                if name in kwargs:
                    raise TypeError(f"{fn.__name__}() got multiple values for {name!r}")
                kwargs[name] = value
            unknown = sorted(set(kwargs) - set(fields))
            if unknown:
                raise ConfigError(f"unknown option(s) {', '.join(map(repr, unknown))} of "
                                  f"{config_cls.COMMAND or fn.__name__}", key=unknown[0],
                                  fix="known: " + ", ".join(fields))
            return fn(config_cls(**kwargs), **runtime)

        params = list(inspect.signature(config_cls).parameters.values())
        own = inspect.signature(fn).parameters
        params += [inspect.Parameter(k, inspect.Parameter.KEYWORD_ONLY,
                                     default=own[k].default if k in own else None)
                   for k in extras]
        ret = inspect.signature(fn).return_annotation
        wrapper.__signature__ = inspect.Signature(params, return_annotation=ret)  # type: ignore[attr-defined]
        wrapper.config_class = config_cls  # type: ignore[attr-defined]
        return wrapper

    return wrap


# -- helpers ------------------------------------------------------------------------------

@functools.cache
def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _split_optional(tp: Any) -> tuple[Any, bool]:
    """``X | None`` -> (X, True); ``X`` -> (X, False)."""
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        optional = len(args) < len(typing.get_args(tp))
        return (args[0] if len(args) == 1 else functools.reduce(operator.or_, args)), optional
    return tp, False


def _coerce(value: Any, tp: Any, name: str) -> Any:
    base, optional = _split_optional(tp)
    if value is None:
        if optional:
            return None
        raise ConfigError("a value is required", key=name)
    origin = typing.get_origin(base)
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise ConfigError(f"expected a list, got {value!r}", key=name)
        args = typing.get_args(base)
        item = args[0] if args else Any
        return tuple(_coerce(v, item, name) for v in value)
    if base is bool:
        if isinstance(value, bool):
            return value
        raise ConfigError(f"expected true or false, got {value!r}", key=name)
    if base is int:
        if isinstance(value, numbers.Integral) and not isinstance(value, bool):
            return int(value)
        raise ConfigError(f"expected a whole number, got {value!r}", key=name)
    if base is float:
        if isinstance(value, numbers.Real) and not isinstance(value, bool):
            return float(value)
        raise ConfigError(f"expected a number, got {value!r}", key=name)
    if base is str:
        if isinstance(value, str):
            return value
        raise ConfigError(f"expected a text, got {value!r}", key=name)
    if base is Path:
        if isinstance(value, Path):
            return value
        if isinstance(value, str | os.PathLike) and str(value):
            return Path(value)
        raise ConfigError(f"expected a path, got {value!r}", key=name)
    return value  # Any, unions of several types, records: the class's validate() checks


#: Largest seed: seeds are stored in int64 arrays and metadata (npz, Parquet) and handed to
#: compiled code, and ``numpy.random.SeedSequence`` takes only non-negative integers.
MAX_SEED = 2**63 - 1


def _is_seed(name: str, tp: Any) -> bool:
    """A root seed: an ``int`` field named ``seed`` or ``*_seed`` (``layout_seed``)."""
    return (name == "seed" or name.endswith("_seed")) and _split_optional(tp)[0] is int


def _check_seed(value: int, name: str) -> None:
    """Every command's seed goes to ``numpy.random.SeedSequence``, which refuses negative
    numbers with a bare ``ValueError``: checked here once for every command and every way of
    giving it (option, options file, Python call)."""
    if not 0 <= value <= MAX_SEED:
        fix = (f"seeds are non-negative: e.g. {-value} instead of {value}" if value < 0
               and -value <= MAX_SEED else "choose a seed in [0, 2**63 - 1]")
        raise ConfigError(f"expected a whole number in [0, 2**63 - 1], got {value!r}",
                          key=name, fix=fix)


def _plain(value: Any) -> Any:
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    return value


def _flag_name(f: dataclasses.Field) -> str:
    return "--" + (f.metadata.get("flag") or f.name.replace("_", "-"))


def _add_field(parser: argparse.ArgumentParser, f: dataclasses.Field, tp: Any) -> None:
    base, _optional = _split_optional(tp)
    meta = f.metadata
    required = f.default is _MISSING and f.default_factory is _MISSING
    default = None if required else f.default
    help_text = meta.get("help", "")
    if not required and default not in (None, "", ()) and base is not bool:
        shown = ",".join(map(str, default)) if isinstance(default, tuple) else default
        help_text += f" (default {shown})"
    kw: dict[str, Any] = {"help": help_text, "default": _UNSET}
    if meta.get("metavar"):
        kw["metavar"] = meta["metavar"]
    if meta.get("choices") is not None:
        kw["choices"] = meta["choices"]
    if base is bool:
        kw.pop("metavar", None)
        if default is None and _optional:  # unset unless given: both spellings
            name = meta.get("flag") or f.name.replace("_", "-")
            parser.add_argument(_flag_name(f), dest=f.name, action="store_true", **kw)
            parser.add_argument(f"--no-{name}", dest=f.name, action="store_false",
                                default=_UNSET, help=f"the opposite of --{name}")
            return
        if default is True:
            flag = "--no-" + (meta.get("flag") or f.name.replace("_", "-"))
            if flag not in kw["help"]:  # the field's help says what "on" does
                kw["help"] = f"turn off (on by default): {kw['help']}"
            parser.add_argument(flag, dest=f.name, action="store_false", **kw)
        else:
            parser.add_argument(_flag_name(f), dest=f.name, action="store_true", **kw)
        return
    kw["type"] = meta.get("parse") or _parser_for(base)
    if typing.get_origin(base) is tuple:
        kw["nargs"] = "+"
    if meta.get("positional"):
        if not required:
            kw["nargs"] = "?"
        parser.add_argument(f.name, **kw)
        return
    if required:  # not argparse-required: --config FILE may give it
        kw["help"] += " (required)"
    parser.add_argument(_flag_name(f), dest=f.name, **kw)


def _parser_for(base: Any) -> Callable[[str], Any]:
    if typing.get_origin(base) is tuple:
        args = typing.get_args(base)
        return _parser_for(args[0] if args else str)
    if base in (int, float, Path):
        return base
    return str
