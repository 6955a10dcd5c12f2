"""Measures a third-party master's cycle against akd-sim over a veth pair: SOEM through pysoem.

Not a test: timing depends on the machine. akd-sim serves the virtual AKDs on one veth end in its
own network namespace; pysoem in the other brings them to Op with the fixed mappings 0x1701/0x1B01
and times `send_processdata` + `receive_processdata` (one LRW frame, Python loop included).
Prints percentiles and worst of the round trip and the working counters seen. Needs root.

    .venv/bin/python bench/soem_cycle.py [--cycles 5000] [--count 2]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from support.netns import master_script_report, netns_unavailable_reason, veth_pair
from support.soem_script import SOEM_HELPERS

SCRIPT = (
    SOEM_HELPERS
    + r"""
iface, cycles = sys.argv[1], int(sys.argv[2])
master, _, _ = open_master(iface)
try:
    use_mappings(master, select_fixed_mappings)
    master.config_map()
    reach_safeop(master)
    reach_op(master)
    times, wkcs = [], {}
    for _ in range(cycles):
        start = time.perf_counter_ns()
        master.send_processdata()
        wkc = master.receive_processdata(20000)
        times.append(time.perf_counter_ns() - start)
        wkcs[wkc] = wkcs.get(wkc, 0) + 1
    master.state = pysoem.INIT_STATE
    master.write_state()
finally:
    master.close()
print(json.dumps({"times_ns": times, "wkcs": wkcs, "expected_wkc": master.expected_wkc}))
"""
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cycles", type=int, default=5000)
    parser.add_argument("--count", type=int, default=1, help="virtual AKDs on the line")
    args = parser.parse_args()
    reason = netns_unavailable_reason()
    if reason:
        sys.exit(f"soem_cycle: {reason}")
    with veth_pair() as net:
        report = master_script_report(net, SCRIPT, [str(args.cycles)], count=args.count)
    times = sorted(report["times_ns"])

    def pick(q: float) -> float:
        return times[min(len(times) - 1, int(q * len(times)))] / 1000

    print(
        f"SOEM over veth, {args.count} virtual AKD(s), {len(times)} cycles: "
        f"p50 {pick(0.5):.1f} us, p99 {pick(0.99):.1f} us, p99.9 {pick(0.999):.1f} us, "
        f"worst {times[-1] / 1000:.1f} us; WKC seen {report['wkcs']} "
        f"(expected {report['expected_wkc']})"
    )


if __name__ == "__main__":
    main()
