"""Measures the cycle thread (akd_ros._native.Cycle): period jitter, wake-up latency, exchange
time and CPU time per cycle at 1 kHz and 4 kHz, each beside `cyclictest` (Debian rt-tests) run
right after it in the same conditions (same interval, loop count, priority, CPU, and the same
Python busy threads running).

Not a test: timing depends on the machine and its load. The cycle's wake-up latency is what
cyclictest measures (how late after the deadline the thread woke); period jitter is the
deviation of the wake-to-wake time from the nominal period.

    .venv/bin/python bench/cycle_jitter.py [--cycles 100000] [--rates 1000,4000]
        [--priority 80] [--cpu 1] [--lock-memory] [--busy 2] [--udp]
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from akd_ros import _native
from support.netns import akd_sim_udp, free_udp_port


def busy_work(stop: threading.Event) -> None:
    """Pure-Python work holding the GIL as much as the interpreter lets it."""
    while not stop.is_set():
        sum(i * i for i in range(2000))


class Busy:
    """`count` Python threads busy for the duration of the block."""

    def __init__(self, count: int) -> None:
        self.stop = threading.Event()
        self.threads = [threading.Thread(target=busy_work, args=(self.stop,)) for _ in range(count)]

    def __enter__(self) -> Busy:
        for t in self.threads:
            t.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop.set()
        for t in self.threads:
            t.join()


def cycle_thread_cpu_ns() -> int:
    """CPU time of this process's `akd-cycle` thread so far (ns, from /proc schedstat)."""
    for task in Path("/proc/self/task").iterdir():
        if (task / "comm").read_text().strip() == "akd-cycle":
            return int((task / "schedstat").read_text().split()[0])
    raise RuntimeError("no akd-cycle thread")


def percentile(histogram: list[tuple[int, int]], fraction: float) -> int:
    """Upper bucket edge (ns) under which `fraction` of the samples lie."""
    total = sum(c for _, c in histogram)
    rank, seen = max(1, round(fraction * total)), 0
    for edge, count in histogram:
        seen += count
        if seen >= rank:
            return edge
    return histogram[-1][0]


def us(ns: float) -> str:
    return f"{ns / 1000:8.1f}"


def run_cycle(link: str, rate: int, args) -> None:
    period_ns = 1_000_000_000 // rate
    with _native.Master(link, timeout=0.5) as master:
        master.scan()
        master.request_state("op")
        with Busy(args.busy):
            cycle = _native.Cycle(
                master, period_ns / 1e9, priority=args.priority, cpu=args.cpu, lock_memory=args.lock_memory
            )
            for w in cycle.warnings:
                print(f"  warning: {w}")
            while cycle.snapshot()["cycle"] < 10:
                time.sleep(0.01)
            cpu0, cycles0 = cycle_thread_cpu_ns(), cycle.snapshot()["cycle"]
            while cycle.snapshot()["cycle"] < args.cycles:
                time.sleep(0.05)
            cpu1, cycles1 = cycle_thread_cpu_ns(), cycle.snapshot()["cycle"]
            cycle.stop()
        s, h = cycle.stats(), cycle.histograms()
        assert master.al_status(0)[0] == "Op", master.al_status(0)
        master.request_state("init")
    period, latency, exchange = s["period"], s["wake_latency"], s["exchange"]
    jitter = max(period["max_ns"] - period_ns, period_ns - period["min_ns"])
    print(f"  cycle   {rate} Hz, {s['cycles']} cycles on {link}, {args.busy} Python threads busy")
    print(
        f"    period       min {us(period['min_ns'])}  mean {us(period['mean_ns'])}  "
        f"p99 {us(period['p99_ns'])}  max {us(period['max_ns'])} us;  jitter (max |period - "
        f"{period_ns / 1000:.0f}|) {us(jitter)} us"
    )
    print(
        f"    wake latency min {us(latency['min_ns'])}  mean {us(latency['mean_ns'])}  "
        f"p99 {us(latency['p99_ns'])}  p99.9 {us(percentile(h['wake_latency'], 0.999))}  "
        f"max {us(latency['max_ns'])} us"
    )
    print(
        f"    exchange     min {us(exchange['min_ns'])}  mean {us(exchange['mean_ns'])}  "
        f"p99 {us(exchange['p99_ns'])}  max {us(exchange['max_ns'])} us"
    )
    print(
        f"    CPU time per cycle {(cpu1 - cpu0) / max(1, cycles1 - cycles0) / 1000:.1f} us; "
        f"overruns {s['overruns']}, lost frames {s['lost_frames']}, wkc errors {s['wkc_errors']}, "
        f"other errors {s['other_errors']}, set-points busy {s['setpoints_busy']}"
    )


def run_cyclictest(rate: int, args) -> None:
    if shutil.which("cyclictest") is None:
        print("  cyclictest: not installed (Debian package rt-tests; scripts/setup.sh installs it)")
        return
    argv = ["cyclictest", "-q", "-t1", f"-i{1_000_000 // rate}", f"-l{args.cycles}"]
    if args.priority is not None:
        argv.append(f"-p{args.priority}")
    if args.cpu is not None:
        argv.append(f"-a{args.cpu}")
    if args.lock_memory:
        argv.append("-m")
    with Busy(args.busy):
        result = subprocess.run(argv, capture_output=True, text=True, timeout=args.cycles / rate * 3 + 30)
    m = re.search(r"C:\s*(\d+)\s+Min:\s*(\d+)\s+Act:\s*\d+\s+Avg:\s*(\d+)\s+Max:\s*(\d+)", result.stdout)
    if result.returncode != 0 or m is None:
        print(f"  cyclictest failed ({result.returncode}): {result.stderr.strip()} {result.stdout.strip()}")
        return
    count, low, avg, high = m.groups()
    print(f"  cyclictest {rate} Hz, {count} loops ({' '.join(argv[1:])})")
    print(f"    wake latency min {float(low):8.1f}  mean {float(avg):8.1f}  max {float(high):8.1f} us")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=100_000)
    parser.add_argument("--rates", default="1000,4000", help="cycle rates in Hz, comma-separated")
    parser.add_argument("--priority", type=int, default=80, help="SCHED_FIFO priority (0: none)")
    parser.add_argument("--cpu", type=int, default=None, help="bind the cycle thread to this CPU")
    parser.add_argument("--lock-memory", action="store_true")
    parser.add_argument("--busy", type=int, default=2, help="Python threads doing busy work meanwhile")
    parser.add_argument("--udp", action="store_true", help="akd-sim over UDP on loopback instead of in-process")
    args = parser.parse_args()
    args.priority = args.priority or None
    rates = [int(r) for r in args.rates.split(",")]
    print(
        f"cycle_jitter: {args.cycles} cycles per rate, priority {args.priority}, cpu {args.cpu}, "
        f"lock memory {args.lock_memory}"
    )
    for rate in rates:
        if args.udp:
            port = free_udp_port()
            with akd_sim_udp(port):
                run_cycle(f"udp://127.0.0.1:{port}", rate, args)
        else:
            run_cycle("sim", rate, args)
        run_cyclictest(rate, args)


if __name__ == "__main__":
    main()
