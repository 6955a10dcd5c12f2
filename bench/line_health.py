"""Measures what reading the line's links and error counters beside the cycle costs the cycle thread: the same cycle
on six virtual AKDs with the reads on (every `--interval` s, the default a Cycle has) and off, alternating.

Not a test: timing depends on the machine and its load. Each round runs, for each rate, the cycle thread on the
in-process line of six virtual AKDs ("sim:6", the virtual ESCs served in the cycle thread itself, so that a read's
frame costs the thread its serving too: the worst case; over a real line the ESCs answer in hardware) once with the
reads and once without, in alternating order; rounds alternate too, so a change of the machine's load over the run
falls on both. Each run gives the period jitter |wake-to-wake time - period| and wake-up latency from the cycle's own
1 µs histograms, the exchange's p99, the cycle thread's CPU per cycle (/proc schedstat), overruns and lost frames (of
the process data and of the frames beside it), and the reads done. A shared machine stalls one run and not the next,
so each figure is the median of the runs' own (a stall of the host falls on one run, not on the median), beside the
worst of all. The ratios (reads on / off) are the figures to quote: no lost frame and no measurable jitter is what
the reads must cost.

    .venv/bin/python bench/line_health.py [--rates 1000,4000] [--seconds 4] [--rounds 3] [--interval 0.25]
        [--priority 80] [--json PATH]
"""

from __future__ import annotations

import argparse
import sys
import time

from cycle_jitter import cycle_thread_cpu_ns, jitter_histogram, merged, quantiles
from figures import Figures, json_argument, quantile

from akd_ros import _native

DRIVES = 6
INPUT_ENTRIES = [[0x60640020, 0x60410010]]


def run_cycle(rate: int, interval: float, args) -> dict:
    """One run at `rate` Hz reading the line every `interval` s (0: never)."""
    period_ns = 1_000_000_000 // rate
    cycles = rate * args.seconds
    with _native.Master(f"sim:{DRIVES}", timeout=0.5) as master:
        master.scan()
        master.request_state("preop")
        for position in range(DRIVES):
            master.configure_pdo(position, 0x1724, INPUT_ENTRIES)
        master.request_state("op")
        cycle = _native.Cycle(
            master,
            period_ns / 1e9,
            realtime=_native.RealTime(priority=args.priority, lock_memory=True, cpu_latency_us=0),
            line_health=interval,
        )
        cpu0, cycles0 = cycle_thread_cpu_ns(), cycle.snapshot()["cycle"]
        while cycle.snapshot()["cycle"] < cycles:
            time.sleep(0.05)
        cpu1, cycles1 = cycle_thread_cpu_ns(), cycle.snapshot()["cycle"]
        line = cycle.line_health()
        cycle.stop()
        stats, h = cycle.stats(), cycle.histograms()
    return {
        "rate": rate,
        "reads": interval > 0,
        "warnings": cycle.warnings,
        "jitter": jitter_histogram(h["period"], period_ns),
        "wake": [(edge / 1000, count) for edge, count in h["wake_latency"]],
        "exchange p99 µs": stats["exchange"]["p99_ns"] / 1000,
        "CPU/cycle µs": (cpu1 - cpu0) / max(1, cycles1 - cycles0) / 1000,
        "overruns": stats["overruns"],
        "lost": stats["lost_frames"],
        "acyclic lost": stats["acyclic_lost_frames"],
        "line reads": line["reads"],
        "line frames lost": line["frames_lost"],
        "findings": line["findings"],
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rates", default="1000,4000", help="cycle rates in Hz, comma-separated")
    parser.add_argument("--seconds", type=int, default=4, help="s of each run")
    parser.add_argument("--rounds", type=int, default=3, help="rounds, alternating reads on and off")
    parser.add_argument("--interval", type=float, default=0.25, help="s between reads of the line, when on")
    parser.add_argument("--priority", type=int, default=80, help="SCHED_FIFO priority of the cycle thread (0: none)")
    json_argument(parser)
    args = parser.parse_args()
    rates = [int(r) for r in args.rates.split(",")]
    args.priority = args.priority or None
    figures = Figures("line_health.py", "what reading the line's counters beside the cycle costs it", args)
    runs = []
    for round_number in range(args.rounds):
        for rate in rates:
            order = (args.interval, 0.0) if round_number % 2 == 0 else (0.0, args.interval)
            runs += [run_cycle(rate, interval, args) for interval in order]
    for run in runs:
        if run["lost"] or run["acyclic lost"] or run["line frames lost"]:
            figures.missing(
                f"{run['rate']} Hz, reads {'on' if run['reads'] else 'off'}: {run['lost']} cyclic frames lost,"
                f" {run['acyclic lost']} beside the cycle, {run['line frames lost']} of the reads"
            )
        if run["findings"]:
            figures.missing(f"{run['rate']} Hz: the clean virtual line showed {run['findings']}")
    for warning in sorted({w for run in runs for w in run["warnings"]}):
        figures.note(f"cycle warning: {warning}")
    rows, series = [], {}
    for rate in rates:
        figures_of = {}
        for reads in (False, True):
            these = [r for r in runs if r["rate"] == rate and r["reads"] == reads]

            def median(figure: str, of: str, these=these) -> float:
                return quantile([quantiles(r[of])[figure] for r in these], 0.5)

            figures_of[reads] = {
                "rate Hz": rate,
                "reads": "on" if reads else "off",
                "line reads": sum(r["line reads"] for r in these),
                "jitter p99 µs": median("p99", "jitter"),
                "jitter p99.9 µs": median("p99.9", "jitter"),
                "wake p99 µs": median("p99", "wake"),
                "wake p99.9 µs": median("p99.9", "wake"),
                "jitter max µs (all runs)": quantiles(merged([r["jitter"] for r in these]))["max"],
                "exchange p99 µs": quantile([r["exchange p99 µs"] for r in these], 0.5),
                "CPU/cycle µs": quantile([r["CPU/cycle µs"] for r in these], 0.5),
                "overruns": sum(r["overruns"] for r in these),
                "lost frames": sum(r["lost"] + r["acyclic lost"] for r in these),
            }
            series[f"reads {'on' if reads else 'off'} {rate} Hz"] = merged([r["jitter"] for r in these])
        on, off = figures_of[True], figures_of[False]
        rows += [off, on]
        rows.append(
            {"rate Hz": rate, "reads": "on / off"}
            | {
                k: (on[k] / off[k] if off[k] else float("nan"))
                for k in ("jitter p99 µs", "jitter p99.9 µs", "wake p99 µs", "wake p99.9 µs", "CPU/cycle µs")
            }
        )
    figures.table(
        "The cycle with the line's counters read beside it and without: medians of the runs' own figures (ratios: on"
        " / off)",
        rows,
    )
    figures.distribution("cycle period jitter, the line's counters read and not", series)
    figures.note(
        f"cycle on the in-process line of {DRIVES} virtual AKDs (sim:{DRIVES}, served in the cycle thread),"
        f" SCHED_FIFO {args.priority}, memory locked, CPU wake-up latency held at 0 µs; reads every {args.interval} s"
        f" when on; {args.rounds} rounds of {args.seconds} s per run, alternating"
    )
    return figures.finish()


if __name__ == "__main__":
    sys.exit(main())
