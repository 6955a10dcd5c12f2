"""Scheduling helpers the benchmarks share: real-time priority for a process they start (akd-sim, whose replies
over UDP the cycle waits for in every exchange, as a real drive answers in hardware)."""

from __future__ import annotations

import os
from pathlib import Path


def real_time(pid: int, priority: int, what: str = "akd-sim") -> None:
    """Gives every thread of process `pid` SCHED_FIFO `priority`, or says why it could not."""
    try:
        for task in Path(f"/proc/{pid}/task").iterdir():
            os.sched_setscheduler(int(task.name), os.SCHED_FIFO, os.sched_param(priority))
    except OSError as e:
        print(f"  warning: {what} not given SCHED_FIFO {priority}: {e}")
