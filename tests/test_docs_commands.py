"""The commands the quick start and the tutorial show, run as written against the virtual AKD, so a wrong command
fails CI; and the README's, checked to be the quick start's, with `.ci/run` running the README's test command.

Each page's `sh` blocks run in order in a scratch folder that links the repository's config/, examples/ and .venv
(what the commands name), on a ROS domain of this module's own, each to exit status 0 within BLOCK_S. A block marked
`{.background ready="TEXT"}` is started, waited for until it prints TEXT and left running beside the blocks after it;
it is stopped with SIGINT, and must exit 0, at the next background block, at a block marked `{.stopped}` or at the
page's end. Blocks marked `{.real-drive}`, `{.ros2-cli}` or `{.ci}` are not run (a real drive; the `ros2` command of a
full ROS install; what .ci/run runs itself). The blocks are read with markdown-it and its attrs plugin, as MyST reads
them.
"""

from __future__ import annotations

import queue
import signal
import subprocess
import threading
import time
from pathlib import Path

import pytest
from markdown_it import MarkdownIt
from mdit_py_plugins.attrs import attrs_block_plugin

from support.ros import WAIT_S, lines_of, ros_environment

ROOT = Path(__file__).resolve().parents[1]
DOMAINS = range(45, 50)
PAGES = ("docs/quickstart.md", "docs/tutorial.md")
NOT_RUN = {"real-drive", "ros2-cli", "ci"}
"""The classes of blocks shown but not run."""
BLOCK_S = 120.0
"""A bound on one block, not a timing expectation."""
LINKED = ("config", "examples", ".venv")
"""What the commands name, linked into the scratch folder."""


def blocks(text: str) -> list[tuple[str, str, dict]]:
    """Every fenced block of a page: (language, content, attributes)."""
    parser = MarkdownIt("commonmark").use(attrs_block_plugin)
    return [(t.info.strip(), t.content, dict(t.attrs)) for t in parser.parse(text) if t.type == "fence"]


def classes(attrs: dict) -> set[str]:
    return set(str(attrs.get("class", "")).split())


class Background:
    """A command that runs until stopped, its output collected."""

    def __init__(self, command: str, ready: str, cwd: Path):
        self.command, self.log, self.lines = command, [], queue.Queue()
        # exec: the signal reaches the command, not a shell around it.
        self.process = subprocess.Popen(
            ["bash", "-c", f"exec {command}"],
            cwd=cwd,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            bufsize=1,
        )
        threading.Thread(target=lines_of, args=(self.process.stdout, self.lines, self.log), daemon=True).start()
        deadline = time.monotonic() + WAIT_S
        while not any(ready in line for line in self.log):
            assert self.process.poll() is None, f"{command!r} exited before {ready!r}:\n{self.output()}"
            assert time.monotonic() < deadline, f"{command!r} printed no {ready!r} within {WAIT_S} s:\n{self.output()}"
            time.sleep(0.05)

    def output(self) -> str:
        return "".join(self.log)

    def stop(self) -> None:
        """SIGINT, as Ctrl-C; it must exit 0."""
        self.process.send_signal(signal.SIGINT)
        try:
            status = self.process.wait(timeout=WAIT_S)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
            raise AssertionError(f"{self.command!r} did not stop on SIGINT:\n{self.output()}") from None
        assert status == 0, f"{self.command!r} exited {status} on SIGINT:\n{self.output()}"


@pytest.fixture
def scratch(tmp_path):
    for name in LINKED:
        (tmp_path / name).symlink_to(ROOT / name)
    with ros_environment(DOMAINS):
        yield tmp_path


@pytest.mark.parametrize("page", PAGES)
def test_the_page_s_commands_run_as_written(page, scratch):
    shown = [
        (code, attrs) for language, code, attrs in blocks((ROOT / page).read_text(encoding="utf-8")) if language == "sh"
    ]
    ran = 0
    background: Background | None = None
    try:
        for code, attrs in shown:
            kinds = classes(attrs)
            if kinds & NOT_RUN:
                continue
            if background is not None and kinds & {"background", "stopped"}:
                background.stop()
                background = None
            if "background" in kinds:
                background = Background(code.strip(), attrs["ready"], scratch)
            else:
                done = subprocess.run(
                    ["bash", "-euo", "pipefail", "-c", code],
                    cwd=scratch,
                    capture_output=True,
                    text=True,
                    timeout=BLOCK_S,
                    check=False,
                )
                context = f"\n{done.stdout}{done.stderr}" + (
                    f"\nbeside it:\n{background.output()}" if background else ""
                )
                assert done.returncode == 0, f"{code!r} exited {done.returncode}:{context}"
            ran += 1
        if background is not None:
            background.stop()
            background = None
    finally:
        if background is not None and background.process.poll() is None:
            background.process.kill()
            background.process.wait()
    assert ran >= 2, f"{page}: no command ran"


def test_the_readme_s_commands_are_the_quick_start_s_and_ci_runs_the_test_command():
    readme = [
        code.strip()
        for language, code, _ in blocks((ROOT / "README.md").read_text(encoding="utf-8"))
        if language == "sh"
    ]
    quick = {
        code.strip(): attrs
        for language, code, attrs in blocks((ROOT / PAGES[0]).read_text(encoding="utf-8"))
        if language == "sh"
    }
    run_node = next(code for code, attrs in quick.items() if "background" in classes(attrs))
    assert readme[0] == f"bash scripts/setup.sh && {run_node}"
    test_command = "bash scripts/setup.sh && bash scripts/test.sh"
    assert readme[1] == test_command and test_command in quick
    ci = [line.strip() for line in (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()]
    assert test_command in ci, ".ci/run does not run the README's test command"


def test_the_readme_s_python_runs(scratch):
    (code,) = [
        code for language, code, _ in blocks((ROOT / "README.md").read_text(encoding="utf-8")) if language == "python"
    ]
    done = subprocess.run(
        [str(ROOT / ".venv" / "bin" / "python"), "-c", code],
        cwd=scratch,
        capture_output=True,
        text=True,
        timeout=BLOCK_S,
        check=False,
    )
    assert done.returncode == 0, done.stdout + done.stderr
