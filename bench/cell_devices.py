"""Measures what running devices beside the drives costs the cycle thread: the same two virtual AKDs alone and behind
an EK1100 with an EL1004 and an EL2004 (a cell's line), alternating.

Not a test: timing depends on the machine and its load. Each round runs, for each rate, the cycle thread on the
in-process line `sim:2` and on `sim:ek1100,el1004,el2004,akd,akd` (the virtual slaves served in the cycle thread
itself, so that the terminals' frames cost the thread their serving too: the worst case; over a real line the ESCs
answer in hardware), in alternating order; rounds alternate too, so a change of the machine's load over the run falls
on both. On the cell the devices are run as akd_node runs them: the EL2004's outputs set by name every 50 ms, the
EL1004's inputs watched for edges every cycle, their presence judged. Each run gives the period jitter |wake-to-wake
time - period| and wake-up latency from the cycle's own 1 µs histograms, the exchange's p99, the cycle thread's CPU
per cycle (/proc schedstat), overruns and lost frames; each figure is the median of the runs' own, beside the worst of
all. The ratios (cell / drives alone) are the figures to quote: the terminals must not cost the drives a lost frame.

    .venv/bin/python bench/cell_devices.py [--rates 1000,4000] [--seconds 4] [--rounds 3] [--priority 80]
        [--json PATH]
"""

from __future__ import annotations

import argparse
import itertools
import sys

from figures import Figures, json_argument
from line_health import compared, cycle_arguments, measured

DRIVES = 2
TERMINALS = "ek1100,el1004,el2004"
OUTPUTS = 2
"""The EL2004's position on the cell."""


def run_cycle(rate: int, cell: bool, args) -> dict:
    """One run at `rate` Hz on the drives alone or on the cell."""
    first_drive = len(TERMINALS.split(",")) if cell else 0
    line = f"sim:{TERMINALS},{','.join(['akd'] * DRIVES)}" if cell else f"sim:{DRIVES}"
    outputs = itertools.cycle([{"channel_1_output": True, "channel_3_output": False}, {"channel_1_output": False}])

    def tick(cycle) -> None:
        if cell:
            cycle.set_channels(OUTPUTS, next(outputs))

    run = measured(line, range(first_drive, first_drive + DRIVES), rate, args, tick=tick)
    return run | {"cell": cell}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    cycle_arguments(parser, "the cell and the drives alone")
    json_argument(parser)
    args = parser.parse_args()
    rates = [int(r) for r in args.rates.split(",")]
    args.priority = args.priority or None
    figures = Figures("cell_devices.py", "what devices beside the drives cost the cycle", args)
    runs = []
    for round_number in range(args.rounds):
        for rate in rates:
            order = (True, False) if round_number % 2 == 0 else (False, True)
            runs += [run_cycle(rate, cell, args) for cell in order]
    for run in runs:
        if run["lost"] or run["acyclic lost"]:
            figures.missing(
                f"{run['rate']} Hz, {'cell' if run['cell'] else 'drives alone'}: {run['lost']} cyclic frames lost,"
                f" {run['acyclic lost']} beside the cycle"
            )
    for warning in sorted({w for run in runs for w in run["warnings"]}):
        figures.note(f"cycle warning: {warning}")
    rows, series = compared(runs, rates, "cell", {False: "AKDs alone", True: "cell"})
    figures.table(
        "The cycle on two AKDs behind an EK1100, an EL1004 and an EL2004, against the two alone: medians of the runs'"
        " own figures (ratios: cell / alone)",
        rows,
    )
    figures.distribution("cycle period jitter, the cell and the drives alone", series)
    figures.note(
        f"cycle on in-process virtual lines (served in the cycle thread), SCHED_FIFO {args.priority}, memory locked,"
        f" CPU wake-up latency held at 0 µs; on the cell the EL2004's outputs set by name every 50 ms;"
        f" {args.rounds} rounds of {args.seconds} s per run, alternating"
    )
    return figures.finish()


if __name__ == "__main__":
    sys.exit(main())
