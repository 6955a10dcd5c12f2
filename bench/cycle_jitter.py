"""Measures the cycle thread (akd_ros._native.Cycle): its period jitter and wake-up latency beside `cyclictest`
(Debian rt-tests) at the same interval and priority, and what Python costs it: busy Python threads and SDO traffic
beside the cycle, against an idle run.

Not a test: timing depends on the machine and its load. Each round runs, for each rate, the cycle thread on the
in-process virtual AKD ("sim") once under each load, then cyclictest (one thread, the same interval, priority and
number of loops, memory locked as the cycle is told to); rounds alternate, so a change of the machine's load over the
run falls on both. The loads:
- idle: this process does nothing but wait;
- busy: --busy Python threads doing pure-Python work, holding the GIL as much as the interpreter lets them;
- sdo: one Python thread reading an object by SDO through the cycle (`Cycle.sdo_read`) back to back.

Wake-up latency is what cyclictest measures: how late after its deadline the thread woke. Period jitter is
|wake-to-wake time - period|. Both come from the cycle's own 1 µs histograms; cyclictest's from its -h histogram.

cyclictest holds the CPUs' wake-up latency at 0 µs through PM QoS (/dev/cpu_dma_latency) while it runs, which keeps
an idle CPU polling rather than halted: on a virtual machine a halted vCPU wakes tens of µs late. So that both run
alike, every run of the cycle holds it the same way (`Cycle(..., realtime=RealTime(cpu_latency_us=0))`; where it may
not, the cycle's warning says so).

    .venv/bin/python bench/cycle_jitter.py [--rates 1000,4000] [--seconds 4] [--rounds 2] [--loads idle,busy,sdo]
        [--priority 80] [--busy 2] [--no-cyclictest] [--json PATH]
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

from figures import Figures, histogram_quantile, json_argument

from akd_ros import _native

LOADS = ("idle", "busy", "sdo")
STATUSWORD = (0x6041, 0)


def busy_work(stop: threading.Event, done: list[int]) -> None:
    """Pure-Python work holding the GIL as much as the interpreter lets it."""
    while not stop.is_set():
        sum(i * i for i in range(2000))
        done[0] += 1


def sdo_work(cycle: _native.Cycle, stop: threading.Event, done: list[int]) -> None:
    """SDO reads through the cycle, back to back."""
    while not stop.is_set():
        cycle.sdo_read(0, *STATUSWORD)
        done[0] += 1


class Load:
    """The load of one run, running for the duration of the block; `done` counts its iterations."""

    def __init__(self, name: str, args, cycle: _native.Cycle | None = None) -> None:
        self.stop, self.done = threading.Event(), [0]
        work = {"idle": [], "busy": [(busy_work, ())] * args.busy, "sdo": [(sdo_work, (cycle,))]}[name]
        self.threads = [threading.Thread(target=f, args=(*a, self.stop, self.done)) for f, a in work]

    def __enter__(self) -> Load:
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


def jitter_histogram(period: list[tuple[int, int]], period_ns: int) -> list[tuple[float, int]]:
    """The period histogram (upper edge ns, count) as one of |period - nominal| (µs, count)."""
    counts: dict[float, int] = {}
    for edge, count in period:
        key = abs(edge - period_ns) / 1000
        counts[key] = counts.get(key, 0) + count
    return sorted(counts.items())


def run_cycle(rate: int, load: str, args) -> dict:
    period_ns = 1_000_000_000 // rate
    cycles = rate * args.seconds
    with _native.Master("sim", timeout=0.5) as master:
        master.scan()
        master.request_state("op")
        cycle = _native.Cycle(
            master,
            period_ns / 1e9,
            realtime=_native.RealTime(priority=args.priority, lock_memory=True, cpu_latency_us=0),
        )
        with Load(load, args, cycle) as running:
            cpu0, cycles0 = cycle_thread_cpu_ns(), cycle.snapshot()["cycle"]
            while cycle.snapshot()["cycle"] < cycles:
                time.sleep(0.05)
            cpu1, cycles1 = cycle_thread_cpu_ns(), cycle.snapshot()["cycle"]
            done = running.done[0]
        cycle.stop()
        stats, h = cycle.stats(), cycle.histograms()
        state = master.al_status(0)[0]
    jitter = jitter_histogram(h["period"], period_ns)
    wake = [(edge / 1000, count) for edge, count in h["wake_latency"]]
    return {
        "rate": rate,
        "load": load,
        "cycles": stats["cycles"],
        "warnings": cycle.warnings,
        "state": state,
        "jitter": jitter,
        "wake": wake,
        "exchange p99 µs": stats["exchange"]["p99_ns"] / 1000,
        "CPU/cycle µs": (cpu1 - cpu0) / max(1, cycles1 - cycles0) / 1000,
        "overruns": stats["overruns"],
        "lost": stats["lost_frames"],
        "work/s": done / args.seconds,
    }


def run_cyclictest(rate: int, args) -> dict:
    loops = rate * args.seconds
    argv = ["cyclictest", "-q", "-m", "-t1", f"-i{1_000_000 // rate}", f"-l{loops}", "-h10000"]
    if args.priority:
        argv.append(f"-p{args.priority}")
    result = subprocess.run(argv, capture_output=True, text=True, timeout=args.seconds * 3 + 30, check=False)
    buckets = [(int(us) + 1.0, int(n)) for us, n in re.findall(r"^(\d+) (\d+)$", result.stdout, re.MULTILINE) if int(n)]
    overflows = re.search(r"# Histogram Overflows: (\d+)", result.stdout)
    worst = re.search(r"# Max Latencies: (\d+)", result.stdout)
    if result.returncode != 0 or not buckets or overflows is None or worst is None:
        raise RuntimeError(f"cyclictest failed ({result.returncode}): {result.stderr.strip()[:200]}")
    if int(overflows.group(1)):
        buckets.append((float(worst.group(1)), int(overflows.group(1))))
    return {"rate": rate, "argv": " ".join(argv), "wake": buckets}


def quantiles(histogram: list[tuple[float, int]]) -> dict:
    return {
        "p50": histogram_quantile(histogram, 0.5),
        "p99": histogram_quantile(histogram, 0.99),
        "p99.9": histogram_quantile(histogram, 0.999),
        "max": histogram[-1][0],
    }


def merged(histograms: list[list[tuple[float, int]]]) -> list[tuple[float, int]]:
    counts: dict[float, int] = {}
    for histogram in histograms:
        for edge, count in histogram:
            counts[edge] = counts.get(edge, 0) + count
    return sorted(counts.items())


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rates", default="1000,4000", help="cycle rates in Hz, comma-separated")
    parser.add_argument("--seconds", type=int, default=4, help="s of each run")
    parser.add_argument("--rounds", type=int, default=2, help="rounds, alternating the contenders")
    parser.add_argument("--loads", default="idle,busy,sdo", help=f"loads of the cycle's runs, of {', '.join(LOADS)}")
    parser.add_argument("--priority", type=int, default=80, help="SCHED_FIFO priority of both (0: none)")
    parser.add_argument("--busy", type=int, default=2, help="Python threads of the busy load")
    parser.add_argument("--no-cyclictest", action="store_true", help="the cycle's runs only")
    json_argument(parser)
    args = parser.parse_args()
    rates = [int(r) for r in args.rates.split(",")]
    loads = args.loads.split(",")
    if unknown := set(loads) - set(LOADS):
        parser.error(f"--loads: {', '.join(sorted(unknown))} unknown; allowed: {', '.join(LOADS)}")
    args.priority = args.priority or None
    figures = Figures("cycle_jitter.py", "the cycle thread's jitter beside cyclictest, and Python's cost on it", args)
    with_cyclictest = not args.no_cyclictest
    if with_cyclictest and shutil.which("cyclictest") is None:
        figures.missing("cyclictest: not installed (Debian package rt-tests; scripts/setup.sh installs it)")
        with_cyclictest = False
    cycles, peers = [], []
    for _ in range(args.rounds):
        for rate in rates:
            for load in loads:
                cycles.append(run_cycle(rate, load, args))
            if with_cyclictest:
                try:
                    peers.append(run_cyclictest(rate, args))
                except (RuntimeError, subprocess.TimeoutExpired) as e:
                    figures.missing(f"cyclictest at {rate} Hz: {e}")
    for run in cycles:
        if run["state"] != "Op" or run["lost"]:
            figures.missing(f"cycle at {run['rate']} Hz, {run['load']}: {run['lost']} lost frames, in {run['state']}")
    for warning in sorted({w for run in cycles for w in run["warnings"]}):
        figures.note(f"cycle warning: {warning}")

    def runs(rate: int, load: str) -> list[dict]:
        return [r for r in cycles if r["rate"] == rate and r["load"] == load]

    if with_cyclictest and "idle" in loads:
        rows, series = [], {}
        for rate in rates:
            ours = quantiles(merged([r["wake"] for r in runs(rate, "idle")]))
            mine = [p for p in peers if p["rate"] == rate]
            if not mine:
                continue
            theirs = quantiles(merged([p["wake"] for p in mine]))
            jitter = quantiles(merged([r["jitter"] for r in runs(rate, "idle")]))
            rows.append(
                {"rate Hz": rate}
                | {f"cycle wake {k} µs": v for k, v in ours.items()}
                | {f"cyclictest wake {k} µs": v for k, v in theirs.items()}
                | {"ratio p99": ours["p99"] / theirs["p99"], "ratio p99.9": ours["p99.9"] / theirs["p99.9"]}
                | {"cycle period jitter p99 µs": jitter["p99"], "period jitter p99.9 µs": jitter["p99.9"]}
            )
            series[f"cycle {rate} Hz"] = merged([r["wake"] for r in runs(rate, "idle")])
            series[f"cyclictest {rate} Hz"] = merged([p["wake"] for p in mine])
            figures.note(f"cyclictest at {rate} Hz: {mine[0]['argv']}")
        figures.table(
            "Cycle thread against cyclictest (same interval and priority, alternating; ratio = cycle / cyclictest)",
            rows,
        )
        figures.distribution("wake-up latency: cycle thread and cyclictest", series)
    if len(loads) > 1 and "idle" in loads:
        rows, series = [], {}
        for rate in rates:
            idle = quantiles(merged([r["jitter"] for r in runs(rate, "idle")]))
            for load in loads:
                these = runs(rate, load)
                jitter = quantiles(merged([r["jitter"] for r in these]))
                wake = quantiles(merged([r["wake"] for r in these]))
                rows.append(
                    {
                        "rate Hz": rate,
                        "load": load,
                        "work/s": sum(r["work/s"] for r in these) / len(these),
                        "jitter p99 µs": jitter["p99"],
                        "jitter p99.9 µs": jitter["p99.9"],
                        "jitter max µs": jitter["max"],
                        "wake p99 µs": wake["p99"],
                        "wake p99.9 µs": wake["p99.9"],
                        "exchange p99 µs": max(r["exchange p99 µs"] for r in these),
                        "CPU/cycle µs": sum(r["CPU/cycle µs"] for r in these) / len(these),
                        "overruns": sum(r["overruns"] for r in these),
                        "p99 / idle": jitter["p99"] / idle["p99"],
                        "p99.9 / idle": jitter["p99.9"] / idle["p99.9"],
                    }
                )
                series[f"{load} {rate} Hz"] = merged([r["jitter"] for r in these])
        figures.table("Python's cost on the cycle: period jitter |period - nominal| by load (ratios to idle)", rows)
        figures.distribution("cycle period jitter by Python load", series)
        figures.note(
            f"loads: idle (nothing), busy ({args.busy} pure-Python threads), sdo (Cycle.sdo_read of 0x6041 back to"
            " back); work/s: the load's iterations per second"
        )
    figures.note(
        f"cycle on the in-process virtual AKD (sim), SCHED_FIFO {args.priority}, memory locked; {args.rounds} rounds of"
        f" {args.seconds} s per run, alternating; latencies from 1 µs histograms (upper edges)"
    )
    figures.note(
        "CPU wake-up latency held at 0 µs (PM QoS, /dev/cpu_dma_latency) during the cycle's runs (Cycle"
        " cpu_latency_us=0) as cyclictest holds it during its own, unless a cycle warning above says it was not"
    )
    return figures.finish()


if __name__ == "__main__":
    sys.exit(main())
