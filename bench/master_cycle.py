"""Measures the cost of one cyclic exchange in-process: the master and 1, 4, 16 or 64 virtual AKDs on one bus.

Not a test: timing depends on the machine and its load. For each count, `Master("sim:N")` is scanned and taken to Op
with its default mapping, and `exchange()` (the cyclic frame: process data LRW plus the supervision the cycle keeps)
is called back to back, from a thread at SCHED_FIFO 80 as the cycle thread runs: the wall time of each call and
this thread's CPU time over all of them. In-process the virtual AKDs serve the frame inside the call, so both are
the master's and the drives' work together, with no wire; the frame's size is that of the cyclic frame recorded by
the master's own pcapng recorder in a short run apart.

    .venv/bin/python bench/master_cycle.py [--counts 1,4,16,64] [--cycles 5000] [--priority 80] [--json PATH]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from figures import Figures, histogram_us, json_argument, quantile

from akd_ros import _native
from support.pcapng_reader import read_packets


def op_master(link: str, pcap: str | None = None) -> _native.Master:
    master = _native.Master(link, pcap=pcap, timeout=0.5)
    master.scan()
    master.request_state("op")
    return master


def frame_bytes(count: int) -> int:
    """The Ethernet frame length of the cyclic exchange with `count` drives, from a capture of a few of them."""
    with tempfile.TemporaryDirectory(prefix="master_cycle-") as temp:
        path = Path(temp) / "cycle.pcapng"
        with op_master(f"sim:{count}", str(path)) as master:
            for _ in range(3):
                master.exchange()
        # The capture ends with the last exchange's request and reply, which are of the same length.
        return len(list(read_packets(path))[-1].data)


def measure(count: int, cycles: int) -> tuple[dict, list[int]]:
    """One count's figures, and every exchange's time in ns."""
    with op_master(f"sim:{count}") as master:
        for _ in range(100):
            master.exchange()
        before = master.stats()
        times = []
        cpu0 = time.thread_time_ns()
        for _ in range(cycles):
            start = time.perf_counter_ns()
            master.exchange()
            times.append(time.perf_counter_ns() - start)
        cpu = time.thread_time_ns() - cpu0
        after = master.stats()
    return {
        "AKDs": count,
        "frame bytes": frame_bytes(count),
        "cycles": cycles,
        "p50 µs": quantile(times, 0.5) / 1000,
        "p99 µs": quantile(times, 0.99) / 1000,
        "p99.9 µs": quantile(times, 0.999) / 1000,
        "max µs": max(times) / 1000,
        "CPU/cycle µs": cpu / cycles / 1000,
        "lost": after["lost_frames"] - before["lost_frames"],
        "wkc errors": after["wkc_errors"] - before["wkc_errors"],
    }, times


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--counts", default="1,4,16,64", help="virtual AKDs on the bus, comma-separated")
    parser.add_argument("--cycles", type=int, default=5000)
    parser.add_argument("--priority", type=int, default=80, help="this thread's SCHED_FIFO priority (0: none)")
    json_argument(parser)
    args = parser.parse_args()
    figures = Figures("master_cycle.py", "cost of one cyclic exchange in-process (master + virtual AKDs)", args)
    if args.priority:
        # As the cycle thread runs it: the machine's other work then delays the loop less than it would.
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(args.priority))
        except OSError as e:
            figures.note(f"not SCHED_FIFO {args.priority}: {e}")
    rows, series = [], {}
    for count in (int(c) for c in args.counts.split(",")):
        try:
            row, times = measure(count, args.cycles)
        except _native.EtherCatError as e:
            figures.missing(f"{count} AKDs: {e}")
            continue
        if row["lost"] or row["wkc errors"]:
            figures.missing(f"{count} AKDs: {row['lost']} frames lost, {row['wkc errors']} wrong working counters")
        rows.append(row)
        series[f"{count} AKD{'s' if count > 1 else ''}"] = histogram_us(times)
    figures.table("In-process exchange() per cycle, by drives on the bus", rows)
    figures.distribution("in-process exchange() (master + virtual AKDs)", series)
    figures.note(
        "in-process: the virtual AKDs serve the frame inside exchange(), so the time and CPU are the master's and the"
        " drives' together, with no wire; frame bytes: the cyclic Ethernet frame as the master's recorder writes it"
    )
    return figures.finish()


if __name__ == "__main__":
    sys.exit(main())
