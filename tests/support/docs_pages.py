"""The fenced blocks of the documentation a reader follows, README.md and every page under docs/: what each block is
and how the tests take it.

A block's marks follow its language in the fence's info string, which neither GitHub nor MyST shows:

    ```sh ready="active: publishing /joint_states"

Every block is one of these, and tests/test_docs_blocks.py holds each to it:

- a **command** (`sh` or `bash`): run as written by tests/test_docs_commands.py, in order with the page's other
  blocks, to exit status 0 (`exit=N`: N). `ready="TEXT"`: it runs until stopped (a node, a simulator), in the
  background once it printed TEXT; the page's background commands get Ctrl-C (SIGINT; each must exit 0) at its end,
  and the last one started before a block marked `after-ctrl-c`. `terminal="TEXT"`: a full-screen program, run in a
  terminal until its screen shows TEXT, then quit with `q` (it must exit 0).
- a **snippet** (`python`): run as a script with `.venv/bin/python`, in order, to exit status 0.
- **output** (`text`, or no language): what the command or snippet just above it prints, compared line by line
  with numbers normalised (`...` on a line of its own stands for any lines); a part of the output may be shown.
- a **parameters** fragment (`yaml params`, or `params=FILE` to read it after that file): what goes under
  `ros__parameters:`, checked by the node's own parameter check.
- **run by** another script (`run-by=FILE`): a set-up or test command that FILE runs itself; checked to be there.
- **not tested** (`not-tested="why"`): shown only, the reason in the page (a real drive, another machine's tool).
- a MyST **directive** (```` ```{toctree} ````, `{include}`, `{literalinclude}`, `{eval-rst}`): the site's markup.
"""

from __future__ import annotations

import shlex
from dataclasses import dataclass
from pathlib import Path

from markdown_it import MarkdownIt

ROOT = Path(__file__).resolve().parents[2]
COMMAND_LANGUAGES = {"sh", "bash"}
OUTPUT_LANGUAGES = {"text", ""}
MARKS = {
    "sh": {"ready", "after-ctrl-c", "exit", "terminal", "run-by", "not-tested"},
    "bash": {"ready", "after-ctrl-c", "exit", "terminal", "run-by", "not-tested"},
    "python": {"after-ctrl-c", "not-tested"},
    "text": {"not-tested"},
    "": {"not-tested"},
    "yaml": {"params", "not-tested"},
}
"""The marks each language takes; any other language must be marked not-tested."""


@dataclass(frozen=True)
class Block:
    """One fenced block of a page."""

    page: str
    """The page, relative to the repository's root."""
    line: int
    """The line of its opening fence, from 1."""
    language: str
    marks: dict[str, str]
    """Its marks; for a directive, {"argument": what follows its name}."""
    code: str

    @property
    def where(self) -> str:
        return f"{self.page}:{self.line}"

    @property
    def kind(self) -> str:
        """directive, not-tested, run-by, command, snippet, output, params, or unknown."""
        if self.language.startswith("{"):
            return "directive"
        if "not-tested" in self.marks:
            return "not-tested"
        if "run-by" in self.marks:
            return "run-by"
        if self.language in COMMAND_LANGUAGES:
            return "command"
        if self.language == "python":
            return "snippet"
        if self.language in OUTPUT_LANGUAGES:
            return "output"
        if self.language == "yaml" and "params" in self.marks:
            return "params"
        return "unknown"


def parse_marks(text: str) -> dict[str, str]:
    """`key="value" flag` as a dict (a flag's value is '')."""
    marks = {}
    for word in shlex.split(text):
        key, _, value = word.partition("=")
        marks[key] = value
    return marks


def blocks_of(page: str) -> list[Block]:
    """Every fenced block of `page` (relative to the root), nested ones (in lists) too, in order."""
    text = (ROOT / page).read_text(encoding="utf-8")
    found = []
    for token in MarkdownIt("commonmark").parse(text):
        if token.type != "fence":
            continue
        language, _, rest = token.info.strip().partition(" ")
        marks = {"argument": rest.strip()} if language.startswith("{") else parse_marks(rest)
        found.append(Block(page, token.map[0] + 1, language, marks, token.content))
    return found


def pages() -> list[str]:
    """README.md and every page under docs/ (not the build's output nor the pages it generates)."""
    docs = ROOT / "docs"
    under_docs = sorted(
        str(path.relative_to(ROOT))
        for path in docs.rglob("*.md")
        if not {"_build", "_generated"} & set(path.relative_to(docs).parts)
    )
    return ["README.md", *under_docs]
