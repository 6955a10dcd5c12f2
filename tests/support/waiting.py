"""Waiting for a condition with a deadline, as every test against a running cycle does, and for a process's lines."""

from __future__ import annotations

import queue
import threading
import time


def wait_for(what: str, done, timeout: float = 10.0, poll: float = 0.002):
    """`done()`'s first true result, polled every `poll` seconds; fails the test naming `what` after `timeout`."""
    deadline = time.monotonic() + timeout
    while not (result := done()):
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(poll)
    return result


class Lines:
    """A process's output lines, read on a thread so that a wait for the next one can time out."""

    def __init__(self, stream):
        self._lines: queue.Queue[str] = queue.Queue()
        threading.Thread(target=self._read, args=(stream,), daemon=True).start()

    def _read(self, stream) -> None:
        # The stream may be closed under the thread when the process is stopped.
        try:
            for line in stream:
                self._lines.put(line.rstrip("\n"))
        except (OSError, ValueError):
            return

    def next(self, timeout: float = 10.0) -> str:
        """The next line; raises queue.Empty after `timeout` seconds."""
        return self._lines.get(timeout=timeout)
