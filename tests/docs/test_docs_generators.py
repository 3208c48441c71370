"""The documentation site's generated pages follow the code: every subcommand and every
option of its parser is listed with its config field's default and help; the env cards
cover every registered id; examples naming a missing option or command are caught."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "docs"))

import simlab_docs  # noqa: E402  (docs/ is not a package)


@pytest.fixture(scope="module")
def commands() -> list[simlab_docs.ParsedCommand]:
    return simlab_docs.command_parsers()


def test_every_subcommand_and_option_is_on_the_commands_page(commands) -> None:
    from simlab.cli import SUBCOMMANDS

    page = simlab_docs.commands_markdown()
    names = {c.name.split()[0] for c in commands}
    assert names == set(SUBCOMMANDS)  # visitlab appears through its actions
    assert {"visitlab train", "visitlab show"} <= {c.name for c in commands}
    for cmd in commands:
        assert f"## `simlab {cmd.name}`" in page
        for action in cmd.parser._actions:
            for flag in action.option_strings:
                if flag not in ("-h", "--help"):
                    assert f"`{flag}`" in page, (cmd.name, flag)


def test_options_show_the_config_fields_default_and_help(commands) -> None:
    from simlab.data.collect import CollectConfig

    (collect,) = [c for c in commands if c.name == "collect"]
    assert CollectConfig in collect.configs
    page = simlab_docs.commands_markdown()
    section = page.split("## `simlab collect`")[1].split("\n## ")[0]
    fields = {f.name: f for f in dataclasses.fields(CollectConfig)}
    assert "simlab.data.collect.CollectConfig" in section
    assert "`simlab.commands.collect(...)`" in section
    part_size = fields["part_size"]
    row = next(line for line in section.splitlines() if line.startswith("| `--part-size`"))
    assert row == f"| `--part-size` | {part_size.default} | {part_size.metadata['help']} |"
    row = next(line for line in section.splitlines() if line.startswith("| `--out`"))
    assert row.startswith("| `--out` | required |")


def test_a_renamed_option_changes_the_page_and_fails_the_examples() -> None:
    # rename drive's --steps in the parser the site is generated from (a fresh copy)
    commands = simlab_docs.command_parsers()
    (drive,) = [c for c in commands if c.name == "drive"]
    (steps,) = [a for a in drive.parser._actions if "--steps" in a.option_strings]
    steps.option_strings = ["--primitive-count"]
    problems = simlab_docs.check_command_lines(
        "```bash\nsimlab drive --arena table --steps 100 --png d.png\n```\n", commands)
    assert problems == ["`simlab drive` has no option --steps "
                        "(in `simlab drive --arena table --steps 100 --png d.png`)"]


def test_examples_of_the_pages_name_real_commands_and_options(commands) -> None:
    pages = sorted((ROOT / "docs" / "pages").rglob("*.md"))
    assert len(pages) >= 8
    for page in [*pages, ROOT / "README.md"]:
        assert simlab_docs.check_command_lines(page.read_text(), commands) == [], page
    bad = ("```bash\nsimlab drivee --x\nsimlab visitlab train --task nav \\\n"
           "    --trialz 3\n# simlab drive --not-checked (a comment)\n```\n")
    assert simlab_docs.check_command_lines(bad, commands) == [
        "unknown command in `simlab drivee --x`",
        "`simlab visitlab train` has no option --trialz (in `simlab visitlab train "
        "--task nav --trialz 3`)",
    ]


def test_every_registered_env_has_its_card() -> None:
    from simlab.envs import ENV_ENTRY_POINTS

    page = simlab_docs.envs_markdown()
    for env_id in ENV_ENTRY_POINTS:
        assert f"## `{env_id}`" in page
        assert f'gym.make("simlab:{env_id}")' in page
    assert "::: simlab.envs.table_arena.TableArenaEnv" in page


def test_dataset_page_lists_every_column_with_its_unit() -> None:
    from simlab.data import schema

    page = simlab_docs.dataset_markdown()
    for name in schema.transition_schema("odometry").names:
        unit, _ = schema.COLUMN_DOCS[name]
        assert f"| `{name}` |" in page and f"| {unit} |" in page
    assert "| `parts` | array | yes |" in page


def test_rest_roles_become_code_spans() -> None:
    pytest.importorskip("griffe")
    from griffe_rest import markdown_of

    text = "See :func:`simlab.agents.greedy` and :class:`~simlab.base.actions.ActionSet`::\n\n    x\n"
    assert markdown_of(text) == "See `simlab.agents.greedy` and `ActionSet`:\n\n    x\n"


def test_figure_commands_keep_their_temporary_files_in_the_scratch_folder(
        tmp_path: Path, monkeypatch) -> None:
    """The merged robot URDF simlab caches in the temporary directory lands in the
    figures' scratch folder (removed after the build), not in the user's TMPDIR."""
    system_tmp = tmp_path / "system-tmp"
    system_tmp.mkdir()
    monkeypatch.setenv("TMPDIR", str(system_tmp))
    monkeypatch.setattr(simlab_docs, "FIGURES", {"d.png": [
        ["drive", "--steps", "1", "--png", "d.png", "--no-progress"]]})
    made = simlab_docs.make_figures(tmp_path / "scratch")
    assert made["d.png"].is_file()
    assert not list(system_tmp.iterdir())
    assert list((tmp_path / "scratch" / "tmp").glob("simlab-turtlebot3_burger-*.urdf"))


@pytest.mark.parametrize("how", ["failing command", "full disk"])
def test_a_figure_that_cannot_be_made_stops_the_build_in_one_line(
        how: str, tmp_path: Path, monkeypatch) -> None:
    pytest.importorskip("mkdocs")
    import errno
    import tempfile

    import hooks  # docs/hooks.py (docs/ is on sys.path)
    from mkdocs.exceptions import PluginError

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    if how == "failing command":
        monkeypatch.setattr(simlab_docs, "FIGURES", {"d.png": [
            ["drive", "--arena", "nosuch", "--steps", "1", "--no-progress"]]})
        needles = ["simlab drive --arena nosuch", "unknown arena name 'nosuch'"]
    else:
        def full(*args, **kwargs):
            raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "x"))

        monkeypatch.setattr(simlab_docs, "make_figures", full)
        needles = ["No space left on device", "TMPDIR"]
    with pytest.raises(PluginError) as exc:
        hooks.on_pre_build(None)
    text = str(exc.value)
    assert "\n" not in text and all(n in text for n in needles), text
    assert not list(tmp_path.glob("simlab-docs-*"))  # the scratch folder is gone


def test_the_api_reference_covers_every_public_module() -> None:
    """Every public module of simlab and discretize is rendered by an API page (the env
    modules by the hand-made one), and every API page is in the site's navigation."""
    import yaml

    pages = {p: simlab_docs.api_markdown(p) for p in simlab_docs.API_PAGES}
    rendered = {line[4:] for text in pages.values() for line in text.splitlines()
                if line.startswith("::: ")}
    # the hand-made pages (simlab.envs) render their modules by their own ::: lines
    for page in (ROOT / "docs" / "pages" / "api").glob("*.md"):
        rendered |= {line[4:].strip() for line in page.read_text().splitlines()
                     if line.startswith("::: ")}
    for package in ("simlab", "discretize"):
        for name in simlab_docs.public_modules(package):
            assert name in rendered, name
    assert "simlab.envs.minari_export" in rendered
    assert {"simlab.ros.bag", "simlab.online.meta", "simlab.calibration.transfer.score",
            "simlab.replay.loop", "simlab.localization.filter",
            "simlab.orchestration.pipeline", "simlab.experiments.spec"} <= rendered
    nav = yaml.safe_load("nav:" + (ROOT / "mkdocs.yml").read_text().split("\nnav:", 1)[1])
    listed = str(nav)
    for page in simlab_docs.API_PAGES:
        assert f"api/{page}.md" in listed, page
        assert f"<!-- simlab:api:{page} -->" in (ROOT / "docs" / "pages" / "api"
                                                 / f"{page}.md").read_text()


def test_rest_roles_become_links_where_the_target_is_rendered() -> None:
    pytest.importorskip("griffe")
    from griffe_rest import markdown_of

    known = {"simlab.agents.greedy": "simlab.agents.policy.greedy"}
    text = "Use :func:`simlab.agents.greedy`, :func:`~simlab.agents.greedy` or :func:`_x`."
    assert markdown_of(text, known.get) == (
        "Use [`simlab.agents.greedy`][simlab.agents.policy.greedy], "
        "[`greedy`][simlab.agents.policy.greedy] or `_x`.")


#: The modules whose docstrings hold reST tables (simple tables: ``=====  =====``).
TABLE_MODULES = ("simlab.physics.rate", "simlab.data.schema", "simlab.ros.bag",
                 "simlab.agents.registry", "simlab.orchestration.stages",
                 "simlab.experiments", "simlab.visitlab.actions", "simlab.visitlab.humans")
#: A line of a reST table's border or grid, as it would show in a page rendered raw.
REST_TABLE_ROW = r"(?m)^\s*(?:={3,}(?: +={3,})+|\+(?:-{3,}\+)+|\+(?:={3,}\+)+)\s*$"


def _rendered_docstrings(package: str) -> dict[str, str]:
    """Every docstring of ``package`` as the site renders it: loaded by griffe with the
    site's extension (mkdocs.yml), then Markdown with the site's extensions."""
    griffe = pytest.importorskip("griffe")
    import markdown
    import yaml

    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    extensions = [e if isinstance(e, str) else next(iter(e))
                  for e in config["markdown_extensions"]]
    loaded = griffe.load(package, search_paths=[str(ROOT)], extensions=griffe.load_extensions(
        str(ROOT / "docs" / "griffe_rest.py")))
    from griffe_rest import _walk

    return {obj.path: markdown.markdown(obj.docstring.value, extensions=extensions)
            for obj in _walk(loaded) if obj.docstring is not None}


def test_rest_tables_render_as_tables_and_no_border_row_is_left() -> None:
    import re

    html = {**_rendered_docstrings("simlab"), **_rendered_docstrings("discretize")}
    left = {path: re.search(REST_TABLE_ROW, text).group(0).strip()
            for path, text in html.items() if re.search(REST_TABLE_ROW, text)}
    assert left == {}
    for module in TABLE_MODULES:
        assert "<table>" in html[module], module
    rate = html["simlab.physics.rate"]
    assert "<th>rate (Hz)</th>" in rate and "<td>99.8 %</td>" in rate
    topics = html["simlab.ros.bag"]
    assert "<code>geometry_msgs/msg/PoseWithCovarianceStamped</code>" in topics
    assert topics.count("<tr>") == 18  # the header and the 17 topics


def test_simple_and_grid_tables_become_pipe_tables() -> None:
    pytest.importorskip("griffe")
    from griffe_rest import tables_to_markdown

    simple = ("Keys:\n\n====  =========\nkey   meaning\n====  =========\n``a``  first,\n"
              "      continued\n``long-key``  overflows its column\n====  =========\n\nEnd.")
    assert tables_to_markdown(simple) == (
        "Keys:\n\n| key | meaning |\n|---|---|\n| ``a`` | first, continued |\n"
        "| ``long-key`` | overflows its column |\n\nEnd.")
    headless = "=====  =====\n>=     a | b\n=====  =====\n"
    assert tables_to_markdown(headless) == "|  |  |\n|---|---|\n| >= | a \\| b |\n"
    grid = ("+-----+---------+\n| k   | meaning |\n+=====+=========+\n| a   | one     |\n"
            "|     | two     |\n+-----+---------+\n| b   | three   |\n+-----+---------+\n")
    assert tables_to_markdown(grid) == (
        "| k | meaning |\n|---|---|\n| a | one two |\n| b | three |\n")
    prose = "A heading\n=========\n\nand ``x == y``.\n"
    assert tables_to_markdown(prose) == prose


class _Page:
    def __init__(self, uri: str) -> None:
        self.file = type("F", (), {"src_uri": uri})()


def test_an_unknown_marker_stops_the_build_naming_page_and_marker() -> None:
    pytest.importorskip("mkdocs")
    import hooks
    from mkdocs.exceptions import PluginError

    page = "# Guide\n\n<!-- simlab:dataset -->\n\n<!-- simlab:comands -->\n"
    with pytest.raises(PluginError) as exc:
        hooks.on_page_markdown(page, _Page("guide.md"), None, None)
    text = str(exc.value)
    assert "guide.md" in text and "<!-- simlab:comands -->" in text and "\n" not in text
    assert "commands" in text  # the known names are listed
    with pytest.raises(PluginError, match="simlab:api:nosuch"):
        hooks.on_page_markdown("<!-- simlab:api:nosuch -->", _Page("api/x.md"), None, None)
    assert "| column |" in hooks.on_page_markdown("<!-- simlab:dataset -->", _Page("d.md"),
                                                  None, None)


def test_a_site_folder_that_cannot_be_written_is_one_line(tmp_path: Path, monkeypatch) -> None:
    pytest.importorskip("mkdocs")
    import errno
    import os
    import tempfile

    import hooks
    from mkdocs.exceptions import PluginError

    (tmp_path / "file").write_text("x")
    cases = [(tmp_path / "file" / "site", "Not a directory")]
    if os.geteuid() != 0:  # root writes into a read-only folder anyway
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o555)
        cases.append((ro / "site", "Permission denied"))
    for site, reason in cases:
        with pytest.raises(PluginError) as exc:
            hooks.on_pre_build({"site_dir": str(site)})
        text = str(exc.value)
        assert str(site) in text and reason in text and "\n" not in text, text

    def read_only(*args, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system", str(tmp_path / "site"))

    monkeypatch.setattr(tempfile, "TemporaryFile", read_only)
    with pytest.raises(PluginError, match=r"cannot write the site into .*Read-only file"):
        hooks.on_pre_build({"site_dir": str(tmp_path / "site")})
