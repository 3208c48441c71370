"""MkDocs hooks of the documentation site (``mkdocs.yml``: ``hooks``).

* A page line ``<!-- simlab:NAME -->`` is replaced by the page generated from the code
  (``commands``, ``envs``, ``dataset``; :mod:`simlab_docs`), ``<!-- simlab:api:PAGE -->``
  by the ``:::`` lines of every public module of the API page's packages,
  ``<!-- simlab:figure:NAME -->`` by a figure's text. A ``simlab:`` marker left over (a
  misspelt or removed name) stops the build naming the page and the marker: it would be
  an invisible hole in the page.
* The site folder must be writable: checked before the figures are made, a one-line
  error naming it otherwise (mkdocs' own is a traceback from deep in its build).
* Every ``simlab ...`` line of a code block must name a real subcommand and real options:
  otherwise a warning, which ``mkdocs build --strict`` turns into a failed build.
* The guide's figures are made by the commands it shows (:data:`simlab_docs.FIGURES`),
  in a scratch folder, at every build, and served under ``figures/``.
"""

from __future__ import annotations

import logging
import re
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

import simlab_docs  # beside this file (sys.path above)

log = logging.getLogger("mkdocs.plugins.simlab")

_GENERATED = {
    "commands": simlab_docs.commands_markdown,
    "envs": simlab_docs.envs_markdown,
    "dataset": simlab_docs.dataset_markdown,
}
_state: dict[str, Any] = {}


def on_pre_build(config: Any) -> None:
    """The parsers of the commands, and the guide's figures made in a scratch folder. A
    figure that cannot be made (a full disk, a failing command) stops the build with one
    line (mkdocs' ``PluginError``, no traceback) and leaves no scratch folder behind."""
    from mkdocs.exceptions import PluginError

    if config is not None:
        _check_site_dir(Path(config["site_dir"]))
    _state["commands"] = simlab_docs.command_parsers()
    start = time.perf_counter()
    scratch = None
    try:
        scratch = tempfile.TemporaryDirectory(prefix="simlab-docs-")
        _state["figures"] = simlab_docs.make_figures(Path(scratch.name))
    except (OSError, simlab_docs.FigureError) as exc:
        if scratch is not None:
            scratch.cleanup()
        what = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        where = f" ({exc.filename})" if isinstance(exc, OSError) and exc.filename else ""
        raise PluginError(f"simlab: the guide's figures could not be made: {what}{where} "
                          "(free space in the temporary directory, or set TMPDIR)") from None
    _state["scratch"] = scratch
    log.info("simlab: figures made by their commands in %.1f s", time.perf_counter() - start)


def _check_site_dir(site: Path) -> None:
    """``PluginError`` (one line) unless ``site`` can be made and written into."""
    from mkdocs.exceptions import PluginError

    try:
        site.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=site):
            pass
    except OSError as exc:
        what = exc.strerror or str(exc)
        raise PluginError(f"simlab: cannot write the site into {site}: {what} (make it "
                          "writable, or choose another site_dir: mkdocs build -d DIR)"
                          ) from None


#: ``<!-- simlab:... -->``: the markers this hook replaces (module docstring).
_MARKER = re.compile(r"<!--\s*simlab:([^>]*?)\s*-->")


def on_files(files: Any, config: Any) -> Any:
    from mkdocs.structure.files import File

    for name, path in _state.get("figures", {}).items():
        if name.endswith(".txt"):
            continue
        files.append(File.generated(config, f"figures/{name}", abs_src_path=str(path)))
    return files


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    for name, make in _GENERATED.items():
        marker = f"<!-- simlab:{name} -->"
        if marker in markdown:
            markdown = markdown.replace(marker, make())
    for name in simlab_docs.API_PAGES:
        marker = f"<!-- simlab:api:{name} -->"
        if marker in markdown:
            markdown = markdown.replace(marker, simlab_docs.api_markdown(name))
    for name, path in _state.get("figures", {}).items():
        marker = f"<!-- simlab:figure:{name} -->"
        if marker in markdown:
            markdown = markdown.replace(marker, "```text\n" + path.read_text().rstrip()
                                        + "\n```")
    left = _MARKER.search(markdown)
    if left is not None:
        from mkdocs.exceptions import PluginError

        known = [*_GENERATED, *(f"api:{n}" for n in simlab_docs.API_PAGES),
                 *(f"figure:{n}" for n in _state.get("figures", {}))]
        raise PluginError(f"simlab: {page.file.src_uri}: unknown marker {left.group(0)} "
                          f"(known: {', '.join(known)})")
    for problem in simlab_docs.check_command_lines(markdown, _state.get("commands")):
        log.warning("%s: %s", page.file.src_uri, problem)
    return markdown


def on_post_build(config: Any) -> None:
    scratch = _state.pop("scratch", None)
    if scratch is not None:
        scratch.cleanup()
