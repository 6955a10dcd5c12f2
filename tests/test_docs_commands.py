"""The commands and snippets of README.md and every page under docs/, run as written against the virtual AKD, one page
at a time, and the output each page shows compared with what they print (numbers normalised); what a block is and its
marks: `support.docs_pages`. A page added later is run as soon as it has a block to run.

Each page runs in a scratch folder that links what the commands name (config/, examples/, .venv, .venv-noros), in a
network namespace of its own where one can be made (as root), so that the ports the pages name (akd-sim's 34980, the
Zenoh router's 7447) and the ROS graph are the page's alone, on a ROS domain of this module's. The environment is a
reader's: no virtual environment on the PATH (a bare `akd-top` is "command not found", as for a newcomer), none of the
variables the ROS wheels set for the test's own interpreter. Each foreground command is bounded by BLOCK_S, a bound and
not a timing expectation.
"""

from __future__ import annotations

import contextlib
import fcntl
import itertools
import os
import pty
import queue
import re
import select
import signal
import struct
import subprocess
import termios
import threading
import time
from pathlib import Path

import pytest

from support.docs_pages import ROOT, Block, blocks_of, pages
from support.netns import netns_unavailable_reason
from support.ros import WAIT_S, lines_of, ros_environment

DOMAINS = range(45, 50)
BLOCK_S = 180.0
"""A bound on one foreground block, not a timing expectation."""
LINKED = ("config", "examples", ".venv", ".venv-noros")
"""What the commands name, linked into the scratch folder."""
RUNNABLE = ("command", "snippet")
SYSTEM_PATH = "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin"
TERMINAL_SIZE = (50, 200)
"""Rows and columns of the terminal a full-screen program is run in."""
ESCAPES = re.compile(r"\x1b(\[[0-9;?<>=]*[ -/]*[@-~]|\][^\x07\x1b]*(\x07|\x1b\\)|[PX^_][^\x1b]*\x1b\\|[@-Z\\-_])")
ROOT_WARNING = "warning: running as root is not needed"
"""What each tool prints first when run as root, as CI runs the pages; a reader's run, and the pages, have none."""
NUMBER = re.compile(r"0x[0-9A-Fa-f]+|[-+]?\d+(\.\d+)?(e[-+]?\d+)?")
_namespaces = itertools.count()


def runnable(page: str) -> bool:
    return any(block.kind in RUNNABLE for block in blocks_of(page))


def reader_environment() -> dict[str, str]:
    """This process's environment as a reader's shell has it: no virtual environment's bin/ on the PATH, none of the
    library paths the ROS wheels' bootstrapper set for this interpreter."""
    env = {
        key: value
        for key, value in os.environ.items()
        if key not in ("LD_LIBRARY_PATH", "PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")
        and not key.startswith("_ROS_WHEELS")
    }
    kept = [d for d in env.get("PATH", SYSTEM_PATH).split(":") if d and not (Path(d).parent / "pyvenv.cfg").exists()]
    env["PATH"] = ":".join(kept) or SYSTEM_PATH
    return env


@contextlib.contextmanager
def page_namespace():
    """The argv prefix that runs a command in a network namespace of the page's own (its loopback up), or none where
    namespaces cannot be made here; the namespace and what is left in it are gone afterwards."""
    if netns_unavailable_reason() is not None:
        yield []
        return
    name = f"akd-docs-{os.getpid() % 100000}x{next(_namespaces)}"
    subprocess.run(["ip", "netns", "add", name], check=True, capture_output=True, timeout=10)
    try:
        subprocess.run(["ip", "-n", name, "link", "set", "lo", "up"], check=True, capture_output=True, timeout=10)
        yield ["ip", "netns", "exec", name]
    finally:
        listed = subprocess.run(["ip", "netns", "pids", name], capture_output=True, text=True, timeout=10)
        for pid in listed.stdout.split():
            with contextlib.suppress(ProcessLookupError):
                os.kill(int(pid), signal.SIGKILL)
        subprocess.run(["ip", "netns", "del", name], capture_output=True, timeout=10)


def normalised(text: str) -> list[str]:
    """`text`'s lines without terminal escapes, trailing blanks, the digits of numbers (hex codes are kept) and the
    warning a tool gives root."""

    def digits(number: re.Match) -> str:
        return number.group() if number.group().startswith("0x") else "#"

    lines = ESCAPES.sub("", text).splitlines()
    return [NUMBER.sub(digits, line).rstrip() for line in lines if ROOT_WARNING not in line]


def shown_in(expected: list[str], output: list[str]) -> bool:
    """Whether the `expected` lines are a run of `output`'s; a line `...` (indented or not) stands for any lines."""

    def at(e: int, o: int) -> bool:
        if e == len(expected):
            return True
        if expected[e].strip() == "...":
            return any(at(e + 1, later) for later in range(o, len(output) + 1))
        return o < len(output) and expected[e] == output[o] and at(e + 1, o + 1)

    return any(at(0, start) for start in range(len(output) + 1))


class Page:
    """One page's run: where, with what, and what runs in the background."""

    def __init__(self, page: str, cwd: Path, prefix: list[str], env: dict[str, str]):
        self.page, self.cwd, self.prefix, self.env = page, cwd, prefix, env
        self.background: list[Background] = []

    def beside(self) -> str:
        return "".join(f"\n--- beside it, {b.command!r}:\n{b.output()}" for b in self.background)

    def run(self, block: Block) -> str:
        """Runs a foreground block to its end; its output, once it exited with the status the page says."""
        if block.kind == "command":
            argv = ["bash", "-euo", "pipefail", "-c", block.code]
        else:
            argv = [str(self.cwd / ".venv" / "bin" / "python"), "-c", block.code]
        try:
            done = subprocess.run(
                [*self.prefix, *argv],
                cwd=self.cwd,
                env=self.env,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT,
                text=True,
                timeout=BLOCK_S,
                check=False,
            )
        except subprocess.TimeoutExpired as timeout:
            pytest.fail(f"{block.where} did not end within {BLOCK_S} s:\n{timeout.output}{self.beside()}")
        status = int(block.marks.get("exit", 0))
        assert done.returncode == status, (
            f"{block.where} exited {done.returncode}, not {status}:\n{block.code}\n{done.stdout}{self.beside()}"
        )
        return done.stdout

    def stop_last(self) -> None:
        self.background.pop().stop()

    def stop_all(self) -> None:
        """Ctrl-C to each background command, the last started first; each must exit 0."""
        failures = []
        while self.background:
            try:
                self.stop_last()
            except AssertionError as failure:
                failures.append(str(failure))
        assert not failures, "\n".join(failures)


class Background:
    """A command that runs until stopped, its output collected."""

    def __init__(self, block: Block, page: Page):
        self.command, self.log, self.lines = block.code.strip(), [], queue.Queue()
        # exec: Ctrl-C reaches the command, not a shell around it.
        self.process = subprocess.Popen(
            [*page.prefix, "bash", "-c", f"exec {self.command}"],
            cwd=page.cwd,
            env=page.env,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            bufsize=1,
        )
        threading.Thread(target=lines_of, args=(self.process.stdout, self.lines, self.log), daemon=True).start()
        ready, deadline = block.marks["ready"], time.monotonic() + WAIT_S
        while not any(ready in line for line in self.log):
            if self.process.poll() is not None:
                pytest.fail(f"{block.where}: {self.command!r} exited before {ready!r}:\n{self.output()}")
            if time.monotonic() > deadline:
                self.process.kill()
                pytest.fail(f"{block.where}: {self.command!r} printed no {ready!r} in {WAIT_S} s:\n{self.output()}")
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
            raise AssertionError(f"{self.command!r} did not stop on Ctrl-C:\n{self.output()}") from None
        assert status == 0, f"{self.command!r} exited {status} on Ctrl-C:\n{self.output()}"


def run_in_terminal(block: Block, page: Page) -> None:
    """Runs a full-screen program in a terminal of its own until its screen shows the block's `terminal` text, then
    presses q; it must exit 0."""
    wanted, screen = block.marks["terminal"], b""
    controller, terminal = pty.openpty()
    fcntl.ioctl(terminal, termios.TIOCSWINSZ, struct.pack("HHHH", *TERMINAL_SIZE, 0, 0))
    process = subprocess.Popen(
        [*page.prefix, "bash", "-c", f"exec {block.code.strip()}"],
        cwd=page.cwd,
        env={**page.env, "TERM": "xterm-256color"},
        stdin=terminal,
        stdout=terminal,
        stderr=terminal,
        start_new_session=True,
    )
    os.close(terminal)

    def read(until: float) -> None:
        nonlocal screen
        while time.monotonic() < until and select.select([controller], [], [], 0.05)[0]:
            try:
                screen += os.read(controller, 65536)
            except OSError:  # the program closed its terminal
                return

    try:
        deadline = time.monotonic() + WAIT_S
        while wanted not in ESCAPES.sub("", screen.decode(errors="replace")):
            if process.poll() is not None or time.monotonic() > deadline:
                text = ESCAPES.sub("", screen.decode(errors="replace"))
                pytest.fail(f"{block.where}: the screen never showed {wanted!r}:\n{text[-3000:]}{page.beside()}")
            read(time.monotonic() + 0.2)
        os.write(controller, b"q")
        deadline = time.monotonic() + WAIT_S
        while process.poll() is None and time.monotonic() < deadline:
            read(time.monotonic() + 0.2)
        if process.poll() is None:
            process.kill()
        assert process.wait() == 0, f"{block.where}: {block.code.strip()!r} exited {process.returncode} on q"
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
        os.close(controller)


@pytest.fixture
def scratch(tmp_path):
    for name in LINKED:
        if (ROOT / name).exists():
            (tmp_path / name).symlink_to(ROOT / name)
    with ros_environment(DOMAINS):
        yield tmp_path


@pytest.mark.parametrize("page", [page for page in pages() if runnable(page)])
def test_the_page_runs_as_written(page, scratch):
    with page_namespace() as prefix:
        run = Page(page, scratch, prefix, reader_environment())
        last: tuple[Block, str] | None = None
        try:
            for block in blocks_of(page):
                if block.kind == "output":
                    assert last is not None, f"{block.where}: output of nothing run"
                    shown, printed = normalised(block.code), normalised(last[1])
                    assert shown_in(shown, printed), (
                        f"{block.where} shows what {last[0].where} does not print (numbers aside):\n{block.code}\n"
                        f"--- it printed:\n{last[1]}"
                    )
                    continue
                last = None
                if block.kind not in RUNNABLE:
                    continue
                if "after-ctrl-c" in block.marks:
                    assert run.background, f"{block.where}: after-ctrl-c, but nothing runs in the background"
                    run.stop_last()
                if "ready" in block.marks:
                    run.background.append(Background(block, run))
                elif "terminal" in block.marks:
                    run_in_terminal(block, run)
                else:
                    last = (block, run.run(block))
        finally:
            run.stop_all()
