"""Locate the robot and arena files.

The repository keeps them at the top level (``robots/``, ``arenas/``); a wheel
ships them inside the package as ``simlab/_assets/{robots,arenas}``. Both layouts
are resolved from the package's own location, never from the working directory.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from simlab.base.errors import ConfigError

_KINDS = ("robots", "arenas")


def asset_dir(kind: str) -> Path:
    """Directory holding the built-in ``kind`` files (``"robots"`` or ``"arenas"``)."""
    if kind not in _KINDS:
        raise ValueError(f"unknown asset kind {kind!r}; expected one of {_KINDS}")
    packaged = Path(str(resources.files("simlab"))) / "_assets" / kind
    if packaged.is_dir():
        return packaged
    source_tree = Path(__file__).resolve().parents[2] / kind
    if source_tree.is_dir():
        return source_tree
    raise ConfigError(
        f"cannot find the built-in {kind} directory",
        path=source_tree,
        fix="reinstall simlab (pip install -e .) from a complete checkout",
    )


def available(kind: str, suffix: str) -> list[str]:
    """Names (file stems) of the built-in ``kind`` files with ``suffix``."""
    return sorted(p.stem for p in asset_dir(kind).glob(f"*{suffix}"))


def is_path(name_or_path: str | Path, suffix: str) -> bool:
    """Whether :func:`resolve` takes ``name_or_path`` as a file path (it ends in ``suffix``
    or holds a path separator) rather than a built-in name."""
    text = str(name_or_path)
    return text.endswith(suffix) or "/" in text or "\\" in text


def resolve(kind: str, name_or_path: str | Path, suffix: str) -> Path:
    """Turn a built-in name (``"table"``) or a file path into an existing path.

    A value containing a path separator or ending in ``suffix`` is taken as a path;
    anything else as the name of a built-in file. Unknown names raise a
    :class:`ConfigError` listing the known ones.
    """
    text = str(name_or_path)
    if is_path(text, suffix):
        path = Path(text)
        if path.is_dir():
            raise ConfigError("is a directory, not a file", path=path,
                              fix=f"give the {suffix} file itself")
        if not path.is_file():
            raise ConfigError("file not found", path=path)
        return path
    path = asset_dir(kind) / f"{text}{suffix}"
    if not path.is_file():
        known = ", ".join(available(kind, suffix)) or "none"
        raise ConfigError(
            f"unknown {kind[:-1]} name {text!r}",
            fix=f"known names: {known}; or give a path to a {suffix} file",
        )
    return path
