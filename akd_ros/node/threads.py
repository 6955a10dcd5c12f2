"""The node's Python threads, named in the operating system as the crate's are: the transports' callback groups
(`akd_ros.node.transports.worker`) and the publishing thread (`akd_ros.node.publishing`)."""

from __future__ import annotations

import ctypes
import ctypes.util

_PR_SET_NAME = 15
_LIBC = ctypes.CDLL(ctypes.util.find_library("c"), use_errno=True)


def name_this_thread(name: str) -> None:
    """Gives the calling thread `name` (its first 15 bytes) in the operating system too, as the crate's threads
    have theirs (akd-cycle, akd-feed, akd-bag): what top -H, perf and /proc/PID/task show, and what a benchmark
    splits the node's CPU by."""
    _LIBC.prctl(_PR_SET_NAME, name.encode()[:15], 0, 0, 0)
