"""Every fenced block of README.md and docs/ is of a kind the tests take, and what can be
checked without running it is: its marks, the output blocks' place, the parameters fragments (the node's own check),
the blocks run by another script (they are there), the command convention (`.venv/bin/...`, so that nothing typed as
shown fails with "command not found"), and Markdown that reads as Markdown on GitHub. tests/test_docs_commands.py runs
the rest; `support.docs_pages` says what each kind is.
"""

from __future__ import annotations

import re
import shlex
import textwrap
import xml.etree.ElementTree as ElementTree
from importlib.metadata import distribution

import pytest
import yaml
from markdown_it import MarkdownIt
from myst_parser.mdit_to_docutils.base import default_slugify

from akd_ros import params
from support.docs_pages import COMMAND_LANGUAGES, MARKS, ROOT, blocks_of, pages

PAGES = pages()
TOOLS = {e.name for e in distribution("akd_ros").entry_points if e.group == "console_scripts"}
"""akd_ros's commands, which exist only in its environments' bin/."""
ENVIRONMENT_COMMANDS = TOOLS | {"python", "pytest", "pip", "ruff", "sphinx-build"}
"""Commands found only in .venv/bin (or .venv-noros/bin): typed bare, they are "command not found"."""
PLACEHOLDER = re.compile(r"\b[A-Z][A-Z0-9_.]*[A-Z]\b|\[|\.\.\.")
"""A synopsis (`akd-sdo LINK read INDEX:SUB`) names its arguments in capitals; it is not typed as shown."""
ATTRIBUTE_LINE = re.compile(r"^\s*\{[.#%][^}]*\}\s*$")
"""MyST's block attributes (`{.class key=value}`), which GitHub shows as text."""


def every_block():
    return [block for page in PAGES for block in blocks_of(page)]


def test_the_pages_are_found():
    assert {"README.md", "docs/quickstart.md", "docs/tutorial.md", "docs/howto/zenoh.md"} <= set(PAGES)


def test_every_block_is_of_a_kind_the_tests_take():
    problems = []
    for block in every_block():
        if block.kind == "directive":
            continue
        allowed = MARKS.get(block.language, {"not-tested"})
        if unknown := set(block.marks) - allowed:
            problems.append(f"{block.where}: ```{block.language} takes {sorted(allowed)}, not {sorted(unknown)}")
        if block.kind == "unknown":
            problems.append(f'{block.where}: ```{block.language} is run by no test: mark it not-tested="why"')
        if "not-tested" in block.marks and not block.marks["not-tested"].strip():
            problems.append(f"{block.where}: not-tested needs the reason, in the page")
        if "ready" in block.marks and (not block.marks["ready"] or len(block.code.strip().splitlines()) != 1):
            problems.append(f'{block.where}: ready="TEXT" needs TEXT, and one command (it gets Ctrl-C)')
        if "exit" in block.marks and not block.marks["exit"].isdigit():
            problems.append(f"{block.where}: exit= takes an exit status")
    assert not problems, "\n".join(problems)


def test_output_follows_the_command_or_snippet_it_shows():
    problems = []
    for page in PAGES:
        before = None
        for block in blocks_of(page):
            foreground = before is not None and before.kind in ("command", "snippet")
            if block.kind == "output" and not (foreground and not {"ready", "terminal"} & set(before.marks)):
                problems.append(f"{block.where}: output of no command or snippet run in the foreground just above it")
            before = block
    assert not problems, "\n".join(problems)


def test_no_attribute_line_shows_as_text_on_github():
    lines = [
        f"{page}:{number}: {line.strip()}"
        for page in PAGES
        for number, line in enumerate((ROOT / page).read_text(encoding="utf-8").splitlines(), start=1)
        if ATTRIBUTE_LINE.match(line)
    ]
    assert not lines, 'marks go after the fence\'s language (```sh not-tested="why"):\n' + "\n".join(lines)


def bare_commands(text: str, *, whole: bool) -> list[str]:
    """The environment's commands `text` types bare. `whole`: text is a block of command lines, where each command
    (after `sudo`, `exec`, a pipe ...) counts; else it is an inline span, which counts when it starts with one and
    has arguments that are not a synopsis's placeholders."""
    try:
        words = shlex.split(text, comments=True)
    except ValueError:
        words = text.split()
    if not whole:
        if len(words) < 2 or PLACEHOLDER.search(text):
            return []
        return [words[0]] if words[0] in ENVIRONMENT_COMMANDS else []
    # `ros2 run akd_ros akd-scan` names the tool to ros2, which finds it itself.
    named_to_ros2 = {
        i + 3 for i, word in enumerate(words) if word == "ros2" and words[i + 1 : i + 3] == ["run", "akd_ros"]
    }
    return [word for i, word in enumerate(words) if word in ENVIRONMENT_COMMANDS and i not in named_to_ros2]


def test_commands_are_typed_with_the_environment_they_run_from():
    """akd_ros's tools, python and pytest are in .venv/bin (or .venv-noros/bin), which nothing puts on the PATH: a
    command typed as the page shows it must name that folder."""
    found = []
    for page in PAGES:
        for block in blocks_of(page):
            if block.language in COMMAND_LANGUAGES:
                found += [f"{block.where}: {word}" for word in bare_commands(block.code, whole=True)]
        for token in MarkdownIt("commonmark").parse((ROOT / page).read_text(encoding="utf-8")):
            spans = [child.content for child in token.children or [] if child.type == "code_inline"]
            found += [f"{page}:{token.map[0] + 1}: `{span}`" for span in spans if bare_commands(span, whole=False)]
    assert not found, "write these .venv/bin/NAME (an option alone without the tool's name):\n" + "\n".join(found)


def test_blocks_run_by_another_script_are_there():
    problems = []
    for block in every_block():
        if block.kind != "run-by":
            continue
        script = (ROOT / block.marks["run-by"]).read_text(encoding="utf-8")
        for line in block.code.splitlines():
            for command in filter(None, (part.split("#")[0].strip() for part in line.split("&&"))):
                if command not in script:
                    problems.append(f"{block.where}: {block.marks['run-by']} does not run {command!r}")
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("block", [b for b in every_block() if b.kind == "params"], ids=lambda b: b.where)
def test_a_parameters_fragment_passes_the_nodes_check(block, tmp_path):
    fragment = tmp_path / "fragment.yaml"
    body = textwrap.indent(textwrap.dedent(block.code), "    ")
    fragment.write_text(f"akd_node:\n  ros__parameters:\n{body}", encoding="utf-8")
    files = [str(ROOT / block.marks["params"])] if block.marks["params"] else []
    arguments = [word for path in [*files, str(fragment)] for word in ("--params-file", path)]
    params.settings(params.read_arguments(["--ros-args", *arguments]))


def test_every_yaml_and_xml_block_is_well_formed():
    problems = []
    for block in every_block():
        try:
            if block.language == "yaml":
                yaml.safe_load(block.code)
            elif block.language == "xml":
                ElementTree.fromstring(block.code)
        except (yaml.YAMLError, ElementTree.ParseError) as error:
            problems.append(f"{block.where}: {error}")
    assert not problems, "\n".join(problems)


def test_literal_includes_name_files_that_exist():
    missing = [
        f"{block.where}: {block.marks['argument']}"
        for block in every_block()
        if block.language == "{literalinclude}" and not ((ROOT / block.page).parent / block.marks["argument"]).is_file()
    ]
    assert not missing, "\n".join(missing)


def heading_anchors(page) -> set[str]:
    """The anchors GitHub gives `page`'s headings (and MyST too, with myst_heading_anchors)."""
    tokens = MarkdownIt("commonmark").parse(page.read_text(encoding="utf-8"))
    return {default_slugify(tokens[i + 1].content) for i, t in enumerate(tokens) if t.type == "heading_open"}


def test_links_to_a_heading_name_it_as_github_does():
    wrong = []
    for page in PAGES:
        for token in MarkdownIt("commonmark").parse((ROOT / page).read_text(encoding="utf-8")):
            for link in [c for c in token.children or [] if c.type == "link_open"]:
                target, _, anchor = str(link.attrs["href"]).partition("#")
                if not anchor or "://" in target:
                    continue
                path = ((ROOT / page).parent / target) if target else ROOT / page
                if path.suffix == ".md" and anchor not in heading_anchors(path):
                    wrong.append(f"{page}:{token.map[0] + 1}: {target}#{anchor}")
    assert not wrong, "no heading of the page has that anchor on GitHub:\n" + "\n".join(wrong)
