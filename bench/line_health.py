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
from collections.abc import Iterable

from cycle_jitter import cycle_thread_cpu_ns, jitter_histogram, merged, quantiles
from figures import Figures, json_argument, quantile

from akd_ros import _native

DRIVES = 6
INPUT_ENTRIES = [[0x60640020, 0x60410010]]


def cycle_in_op(link: str, drives: Iterable[int], period_ns: int, args, **options):
    """The cycle thread of a master on `link` in Op, the AKDs at `drives` mapped with INPUT_ENTRIES, under SCHED_FIFO
    args.priority with memory locked; the master to close afterwards, and the cycle."""
    master = _native.Master(link, timeout=0.5)
    master.scan()
    master.request_state("preop")
    for position in drives:
        master.configure_pdo(position, 0x1724, INPUT_ENTRIES)
    master.request_state("op")
    realtime = _native.RealTime(priority=args.priority, lock_memory=True, cpu_latency_us=0)
    return master, _native.Cycle(master, period_ns / 1e9, realtime=realtime, **options)


def measured(
    link: str, drives: Iterable[int], rate: int, args, tick=lambda cycle: None, last=lambda cycle: {}, **options
):
    """One run of args.seconds at `rate` Hz (`cycle_in_op`'s, with `options`), tick(cycle) called every 50 ms meanwhile:
    the period jitter and wake-up latency histograms, the exchange's p99, the cycle thread's CPU per cycle, overruns
    and lost frames, with `last(cycle)`'s figures, taken before the cycle stops."""
    period_ns = 1_000_000_000 // rate
    master, cycle = cycle_in_op(link, drives, period_ns, args, **options)
    with master:
        cpu0, cycles0 = cycle_thread_cpu_ns(), cycle.snapshot()["cycle"]
        while cycle.snapshot()["cycle"] < rate * args.seconds:
            tick(cycle)
            time.sleep(0.05)
        cpu1, cycles1 = cycle_thread_cpu_ns(), cycle.snapshot()["cycle"]
        extra = last(cycle)
        cycle.stop()
        stats, h = cycle.stats(), cycle.histograms()
    return {
        "rate": rate,
        "warnings": cycle.warnings,
        "jitter": jitter_histogram(h["period"], period_ns),
        "wake": [(edge / 1000, count) for edge, count in h["wake_latency"]],
        "exchange p99 µs": stats["exchange"]["p99_ns"] / 1000,
        "CPU/cycle µs": (cpu1 - cpu0) / max(1, cycles1 - cycles0) / 1000,
        "overruns": stats["overruns"],
        "lost": stats["lost_frames"],
        "acyclic lost": stats["acyclic_lost_frames"],
    } | extra


def run_cycle(rate: int, interval: float, args) -> dict:
    """One run at `rate` Hz reading the line every `interval` s (0: never)."""

    def line(cycle) -> dict:
        health = cycle.line_health()
        return {
            "line reads": health["reads"],
            "line frames lost": health["frames_lost"],
            "findings": health["findings"],
        }

    run = measured(f"sim:{DRIVES}", range(DRIVES), rate, args, last=line, line_health=interval)
    return run | {"reads": interval > 0}


def cycle_arguments(parser: argparse.ArgumentParser, variants: str) -> None:
    """The options every comparison of two cycles takes: rates, seconds, rounds (alternating `variants`), priority."""
    parser.add_argument("--rates", default="1000,4000", help="cycle rates in Hz, comma-separated")
    parser.add_argument("--seconds", type=int, default=4, help="s of each run")
    parser.add_argument("--rounds", type=int, default=3, help=f"rounds, alternating {variants}")
    parser.add_argument("--priority", type=int, default=80, help="SCHED_FIFO priority of the cycle thread (0: none)")


def compared(runs: list[dict], rates: list[int], key: str, labels: dict, extra=lambda these: {}) -> tuple:
    """The table rows and jitter series of `runs` at each of `rates`, those with `key` False and True apart (named
    `labels[False]`, `labels[True]` in column `key`): medians of the runs' own figures (a stall of the host falls on one
    run, not on the median), the worst of all, sums of overruns and lost frames, `extra(runs)`'s columns, and the
    ratios True / False."""
    rows, series = [], {}
    for rate in rates:
        figures_of = {}
        for variant in (False, True):
            these = [r for r in runs if r["rate"] == rate and r[key] == variant]

            def median(figure: str, of: str, these=these) -> float:
                return quantile([quantiles(r[of])[figure] for r in these], 0.5)

            figures_of[variant] = (
                {"rate Hz": rate, key: labels[variant]}
                | extra(these)
                | {
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
            )
            series[f"{key} {labels[variant]} {rate} Hz"] = merged([r["jitter"] for r in these])
        on, off = figures_of[True], figures_of[False]
        rows += [off, on]
        rows.append(
            {"rate Hz": rate, key: f"{labels[True]} / {labels[False]}"}
            | {
                k: (on[k] / off[k] if off[k] else float("nan"))
                for k in (
                    "jitter p99 µs",
                    "jitter p99.9 µs",
                    "wake p99 µs",
                    "wake p99.9 µs",
                    "exchange p99 µs",
                    "CPU/cycle µs",
                )
            }
        )
    return rows, series


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    cycle_arguments(parser, "reads on and off")
    parser.add_argument("--interval", type=float, default=0.25, help="s between reads of the line, when on")
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
    rows, series = compared(
        runs,
        rates,
        "reads",
        {False: "off", True: "on"},
        lambda these: {"line reads": sum(r["line reads"] for r in these)},
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
