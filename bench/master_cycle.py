"""Measures the master's cyclic exchange: round-trip time of one cycle (LRW + DC FRMW) per link.

Not a test: timing depends on the machine. Prints count, mean, percentiles and worst of the
exchange() round trip, for the in-process virtual AKD and, with --udp, for `akd-sim` over UDP
on loopback (started here, stopped at the end).

    .venv/bin/python bench/master_cycle.py [--cycles 5000] [--count 2] [--udp] [--dc]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from akd_ros import _native
from support.netns import akd_sim_udp, free_udp_port


def measure(link: str, count: int, cycles: int, dc: bool) -> None:
    with _native.Master(link, timeout=0.5) as master:
        master.scan()
        master.request_state("preop")
        if dc:
            master.configure_dc(1_000_000)
        master.request_state("op")
        times = []
        for _ in range(cycles):
            start = time.perf_counter_ns()
            master.exchange()
            times.append(time.perf_counter_ns() - start)
        stats = master.stats()
    times.sort()

    def pct(p: float) -> float:
        return times[min(len(times) - 1, int(p * len(times)))] / 1000

    print(
        f"{link:28s} slaves={count} dc={dc} cycles={cycles}: mean {statistics.mean(times) / 1000:.1f} us, "
        f"p50 {pct(0.5):.1f} us, p99 {pct(0.99):.1f} us, p99.9 {pct(0.999):.1f} us, max {times[-1] / 1000:.1f} us; "
        f"lost {stats['lost_frames']}, wkc errors {stats['wkc_errors']}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=5000)
    parser.add_argument("--count", type=int, default=1)
    parser.add_argument("--udp", action="store_true", help="also measure over UDP to akd-sim")
    parser.add_argument("--dc", action="store_true", help="distributed clocks on (FRMW in every cycle)")
    args = parser.parse_args()
    measure(f"sim:{args.count}", args.count, args.cycles, args.dc)
    if args.udp:
        port = free_udp_port()
        with akd_sim_udp(port, count=args.count):
            measure(f"udp://127.0.0.1:{port}", args.count, args.cycles, args.dc)


if __name__ == "__main__":
    main()
