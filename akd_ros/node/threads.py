"""The node's Python threads: named in the operating system as the crate's are (the transports' callback groups,
`akd_ros.node.transports.worker`, and the publishing thread, `akd_ros.node.publishing`), and each giving the GIL up
within GIL_SWITCH_INTERVAL_S when another wants it (`hold_gil_briefly`, called by both runners)."""

from __future__ import annotations

import ctypes
import ctypes.util
import sys

_PR_SET_NAME = 15
_LIBC = ctypes.CDLL(ctypes.util.find_library("c"), use_errno=True)

GIL_SWITCH_INTERVAL_S = 0.0005
"""How long a Python thread of the node runs at most while another waits for the GIL (Python's default is 5 ms): the
thread that takes a command waits no longer than this behind the node's other Python work."""


def hold_gil_briefly() -> None:
    """Sets the interpreter's switch interval to GIL_SWITCH_INTERVAL_S, for the node's process (both runners)."""
    sys.setswitchinterval(GIL_SWITCH_INTERVAL_S)


def name_this_thread(name: str) -> None:
    """Gives the calling thread `name` (its first 15 bytes) in the operating system too, as the crate's threads
    have theirs (akd-cycle, akd-feed, akd-bag): what top -H, perf and /proc/PID/task show, and what a benchmark
    splits the node's CPU by."""
    _LIBC.prctl(_PR_SET_NAME, name.encode()[:15], 0, 0, 0)
