"""Waiting for a condition with a deadline, as every test against a running cycle does."""

from __future__ import annotations

import time


def wait_for(what: str, done, timeout: float = 10.0, poll: float = 0.002):
    """`done()`'s first true result, polled every `poll` seconds; fails the test naming `what` after `timeout`."""
    deadline = time.monotonic() + timeout
    while not (result := done()):
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(poll)
    return result
