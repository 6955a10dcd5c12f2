"""Measures six axes on one bus (akd_ros.Bus): the cycle thread's CPU time per cycle, its period jitter, and how
closely six virtual AKDs in interpolated position follow one trajectory the cycle thread plays.

Not a test: timing depends on the machine and its load; it prints, it never asserts. For each period, a Bus of six
drives (`joint_1`..`joint_6`, interpolated position) on the in-process virtual line "sim:6" and, with --udp, on
`akd-sim --count 6 --udp` (started here, stopped at the end) is enabled; a three-point trajectory of about 2 s, cubic
(a velocity at each point, zero at the last), is played through the cycle thread (`bus.cycle.play_trajectory`), and
every cycle's record (`bus.samples()`) is compared: |position - target_position| during the trajectory, on its last
point's time, and after settling. The CPU time is that of this process's `akd-cycle` thread (/proc schedstat) over
the cycles run (on "sim:6" the virtual AKDs serve each frame inside the cycle thread's exchange, so their work is
counted in; over UDP it is akd-sim's), the period p50/p99/max from the cycle's own period histogram since the start.

    .venv/bin/python bench/six_axes.py [--periods 0.001,0.00025] [--udp] [--priority 80] [--sim-priority 0]
        [--settle 0.5]

Over UDP the cycle waits for akd-sim's reply in every exchange, so akd-sim's scheduling is the cycle's: --sim-priority
gives its threads SCHED_FIFO too, as a real drive answers in hardware.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from cycle_jitter import cycle_thread_cpu_ns
from figures import histogram_quantile, real_time

from akd_ros import Bus, BusRequestError, DriveConfig, RealTime, _native
from support.netns import akd_sim_udp, free_udp_port

COUNT = 6
S = 1_000_000_000
# The trajectory, the same for each joint from where it stands: (time from start ns, offset rad, velocity rad/s).
POINTS = [(S // 2, 0.6, 0.8), (6 * S // 5, 0.9, -0.5), (2 * S, -0.3, 0.0)]


class Recorded:
    """Every cycle's records of the bus, taken often enough that neither the cycle's ring nor the Bus's drops any."""

    def __init__(self, bus: Bus) -> None:
        self.bus = bus
        self.columns: dict[str, list] = {}

    def take(self) -> None:
        for name, values in self.bus.samples().items():
            self.columns.setdefault(name, []).extend(values)

    def during(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.take()
            time.sleep(0.02)
        self.take()

    def errors(self, slave: int, start_ns: int, end_ns: int) -> list[int]:
        """|position - target_position| (counts) of drive `slave` in each cycle woken in [start_ns, end_ns)."""
        c = self.columns
        rows = zip(c["slave"], c["time_ns"], c["position"], c["target_position"], strict=True)
        return [abs(p - t) for s, at, p, t in rows if s == slave and start_ns <= at < end_ns]

    def last_target(self, slave: int) -> int:
        """Drive `slave`'s target in the latest cycle recorded."""
        c = self.columns
        return next(t for s, t in zip(reversed(c["slave"]), reversed(c["target_position"]), strict=True) if s == slave)


def run(link: str, period: float, args) -> dict:
    drives = [DriveConfig(slave=i, name=f"joint_{i + 1}", mode="interpolated_position") for i in range(COUNT)]
    with Bus(link, drives, period=period, realtime=RealTime(priority=args.priority)) as bus:
        for warning in bus.warnings:
            print(f"  warning: {warning}")
        bus.enable()
        records = Recorded(bus)
        records.during(0.1)
        per_count = [axis.units.si_per_count for axis in bus.axes]
        base = [records.last_target(axis.slave) for axis in bus.axes]
        times = [t for t, _, _ in POINTS]
        points = [
            [(b + offset / k, velocity / k, None) for b, k in zip(base, per_count, strict=True)]
            for _, offset, velocity in POINTS
        ]
        cpu0, cycles0 = cycle_thread_cpu_ns(), bus.cycle.snapshot()["cycle"]
        trajectory = bus.cycle.play_trajectory([a.slave for a in bus.axes], times, points)
        while (status := bus.cycle.trajectory_status(trajectory))["state"] in ("pending", "running"):
            records.during(0.05)
        records.during(args.settle)
        cpu1, cycles1 = cycle_thread_cpu_ns(), bus.cycle.snapshot()["cycle"]
        stats, histograms = bus.stats(), bus.cycle.histograms()
        # Each fault's text (or source) and the joints that reported it, once each.
        faults: dict[str, list[str]] = {}
        for axis in bus.axes:
            texts = {e["fault"].text or e["fault"].source for e in bus.events_of(axis.slave) if e["kind"] == "fault"}
            for text in sorted(texts):
                faults.setdefault(text, []).append(axis.name)
    start, end = status["started_ns"], status["started_ns"] + status["duration_ns"]
    during = [max(records.errors(a.slave, start, end), default=0) for a in bus.axes]
    at_end = [max(records.errors(a.slave, end, end + round(period * S)), default=0) for a in bus.axes]
    settled = [
        max(records.errors(a.slave, end + round(args.settle * S) - 50_000_000, end + S * 10), default=0)
        for a in bus.axes
    ]
    return {
        "link": link,
        "period": period,
        "cycles": cycles1 - cycles0,
        "state": status["state"],
        "faults": faults,
        "cpu_us": (cpu1 - cpu0) / max(1, cycles1 - cycles0) / 1000,
        "p50_us": histogram_quantile(histograms["period"], 0.5) / 1000,
        "p99_us": histogram_quantile(histograms["period"], 0.99) / 1000,
        "max_us": stats["period"]["max_ns"] / 1000,
        "overruns": stats["overruns"],
        "lost": stats["lost_frames"],
        "during": max(during),
        "at_end": max(at_end),
        "settled": max(settled),
        "rad_per_count": max(per_count),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--periods", default="0.001,0.00025", help="cycle periods in s, comma-separated")
    parser.add_argument("--udp", action="store_true", help="also on akd-sim --count 6 over UDP on loopback")
    parser.add_argument("--priority", type=int, default=80, help="the cycle thread's SCHED_FIFO priority (0: none)")
    parser.add_argument("--sim-priority", type=int, default=0, help="akd-sim's SCHED_FIFO priority (0: none)")
    parser.add_argument("--settle", type=float, default=0.5, help="s recorded after the trajectory's end")
    args = parser.parse_args()
    args.priority = args.priority or None
    periods = [float(p) for p in args.periods.split(",")]
    duration = POINTS[-1][0] / S
    print(
        f"six_axes: {COUNT} axes in interpolated_position, one cubic trajectory of {len(POINTS)} points over "
        f"{duration:.1f} s (offsets {', '.join(f'{o:+.2f}' for _, o, _ in POINTS)} rad), settle {args.settle} s, "
        f"priority {args.priority}, akd-sim priority {args.sim_priority or None}"
    )
    results = []

    def measured(link: str, period: float) -> None:
        # Drives that fault before or while the trajectory starts give no figures: say so, and go on.
        try:
            results.append(run(link, period, args))
        except (BusRequestError, _native.ConfigError, TimeoutError) as e:
            print(f"{link} at {1 / period:.0f} Hz: not measured: {e}")

    for period in periods:
        measured(f"sim:{COUNT}", period)
        if args.udp:
            port = free_udp_port()
            with akd_sim_udp(port, count=COUNT) as sim:
                if args.sim_priority:
                    real_time(sim.pid, args.sim_priority)
                measured(f"udp://127.0.0.1:{port}", period)
    print(
        f"{'link':24s} {'rate':>6s} {'axes':>4s} {'cycles':>6s} {'outcome':>7s} {'cpu/cycle':>9s} "
        f"{'period p50':>10s} {'p99':>9s} {'max':>9s} {'overruns':>8s} {'lost':>4s} "
        f"{'|pos-target| during':>22s} {'at end':>22s} {'settled':>22s}"
    )
    for r in results:

        def both(counts: int, r=r) -> str:
            # A trajectory that did not end as played has no tracking error to speak of.
            if r["state"] != "done":
                return "n/a"
            return f"{counts:6d} c {counts * r['rad_per_count'] * 1e3:8.3f} mrad"

        print(
            f"{r['link']:24s} {1 / r['period']:4.0f}Hz {COUNT:4d} {r['cycles']:6d} {r['state']:>7s} "
            f"{r['cpu_us']:7.1f}us {r['p50_us']:8.1f}us {r['p99_us']:7.1f}us {r['max_us']:7.1f}us "
            f"{r['overruns']:8d} {r['lost']:4d} {both(r['during']):>22s} {both(r['at_end']):>22s} "
            f"{both(r['settled']):>22s}"
        )
    for r in results:
        if r["faults"]:
            faults = "; ".join(f"{text} on {', '.join(joints)}" for text, joints in r["faults"].items())
            print(f"{r['link']} at {1 / r['period']:.0f} Hz, faults: {faults}")
    print(
        "cpu/cycle: the akd-cycle thread's CPU time over the cycles of the trajectory and the settling; period: the "
        "cycle's wake-to-wake time; |pos-target|: the largest over the six axes, in counts (c) and mrad of the load"
    )


if __name__ == "__main__":
    main()
