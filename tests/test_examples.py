"""Every program in examples/ is shown on the documentation's examples page and run, as a reader runs it, by a page of
the documentation: tests/test_docs_commands.py runs that page's commands against the virtual AKD (the node's examples
against an `akd_node` on config/akd_sim_6axis.yaml or akd_sim.yaml that the page starts) and compares what each prints
with what the page shows. So each example runs once, where a reader meets it."""

from __future__ import annotations

import re

from support.docs_pages import ROOT, blocks_of, pages

EXAMPLES = ROOT / "examples"
HELPERS = ("ros_helpers.py",)
"""Imported by the examples, not run."""
RUN = re.compile(r"^\.venv(-noros)?/bin/python examples/(\w+\.py)\b", re.MULTILINE)


def run_by_pages() -> dict[str, list[str]]:
    """Each example a page's commands run, with the blocks that run it."""
    found: dict[str, list[str]] = {}
    for page in pages():
        for block in blocks_of(page):
            if block.kind == "command":
                for match in RUN.finditer(block.code):
                    found.setdefault(match.group(2), []).append(block.where)
    return found


def test_every_example_is_shown_on_the_examples_page():
    page = (ROOT / "docs" / "examples.md").read_text(encoding="utf-8")
    for path in sorted(EXAMPLES.glob("*.py")):
        assert f"```{{literalinclude}} ../examples/{path.name}" in page, path.name


def test_every_example_is_run_by_a_page_of_the_documentation():
    programs = {path.name for path in EXAMPLES.glob("*.py")} - set(HELPERS)
    run = run_by_pages()
    assert not programs - set(run), f"run by no page: {sorted(programs - set(run))}"
    assert not set(run) - programs, f"pages run examples that do not exist: {sorted(set(run) - programs)}"


def test_the_helpers_are_what_the_node_s_examples_import():
    importing = [p.name for p in EXAMPLES.glob("*.py") if "from ros_helpers import" in p.read_text(encoding="utf-8")]
    assert len(importing) >= 5, importing
