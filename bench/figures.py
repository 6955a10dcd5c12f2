"""What every script of bench/ shares: the machine it ran on, the figures it measured as tables and distributions,
what it could not measure, and its --json file for bench/run.py; real-time priority for a process a script starts.

A script builds one `Figures`, adds tables (rows of dicts, printed as they are) and distributions (histograms of
(value µs, count), which bench/run.py draws as CDFs), names each figure it could not measure with `missing()`, and
ends with `sys.exit(figures.finish())`: the tables printed, the JSON written when --json was given, and exit status
1 when anything was missing, so no figure is ever made up.
"""

from __future__ import annotations

import argparse
import bisect
import collections
import json
import os
import platform
import time
from collections.abc import Iterable, Sequence
from pathlib import Path


def machine() -> dict:
    """uname, CPU model, cores and load averages (1/5/15 min) now."""
    model = next(
        (
            line.split(":", 1)[1].strip()
            for line in Path("/proc/cpuinfo").read_text().splitlines()
            if line.startswith("model name")
        ),
        platform.processor() or "unknown",
    )
    return {
        "uname": " ".join(platform.uname()),
        "cpu": model,
        "cores": os.cpu_count(),
        "load": [round(x, 2) for x in os.getloadavg()],
    }


def json_argument(parser: argparse.ArgumentParser) -> None:
    """The --json PATH option every script has."""
    parser.add_argument("--json", type=Path, help="also write the figures to this file as JSON (for bench/run.py)")


def quantile(values: Sequence[float], fraction: float) -> float:
    """The `fraction` quantile of `values` (nearest rank; 1.0 the largest)."""
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, max(0, round(fraction * len(ordered)) - 1))]


def histogram_quantile(histogram: Sequence[tuple[float, int]], fraction: float) -> float:
    """The `fraction` quantile of a histogram of (upper edge, count), as the upper edge of the bucket it falls in."""
    total = sum(c for _, c in histogram)
    cumulative = list(_cumulative(c for _, c in histogram))
    index = bisect.bisect_left(cumulative, max(1, round(fraction * total)))
    return histogram[min(index, len(histogram) - 1)][0]


def _cumulative(counts: Iterable[int]) -> Iterable[int]:
    seen = 0
    for count in counts:
        seen += count
        yield seen


def histogram_us(samples_ns: Iterable[int], resolution_ns: int = 100) -> list[tuple[float, int]]:
    """Samples in ns as a histogram of (upper edge µs, count) in buckets of `resolution_ns`, empty ones left out."""
    counts = collections.Counter(-(-s // resolution_ns) for s in samples_ns)
    return [(bucket * resolution_ns / 1000, counts[bucket]) for bucket in sorted(counts)]


def real_time(pid: int, priority: int, what: str = "akd-sim") -> None:
    """Gives every thread of process `pid` SCHED_FIFO `priority`, or says why it could not."""
    try:
        for task in Path(f"/proc/{pid}/task").iterdir():
            os.sched_setscheduler(int(task.name), os.SCHED_FIFO, os.sched_param(priority))
    except OSError as e:
        print(f"  warning: {what} not given SCHED_FIFO {priority}: {e}")


class Figures:
    """The figures of one run of a script: its settings (the parsed arguments), the machine, how long it ran."""

    def __init__(self, script: str, title: str, args: argparse.Namespace) -> None:
        self.started = time.monotonic()
        self.json_path: Path | None = getattr(args, "json", None)
        self.data: dict = {
            "script": script,
            "title": title,
            "settings": {k: v for k, v in vars(args).items() if k != "json"},
            "machine": machine(),
            "tables": [],
            "distributions": [],
            "notes": [],
            "not_measured": [],
        }
        print(f"{script}: {title}; settings {self.data['settings']}; load {self.data['machine']['load']}")

    def table(self, title: str, rows: list[dict]) -> None:
        """A table of `rows` (each a dict of column: value; every row the same columns)."""
        self.data["tables"].append({"title": title, "rows": rows})

    def distribution(self, title: str, series: dict[str, Sequence[tuple[float, int]]]) -> None:
        """Histograms of (upper edge µs, count) by label, drawn together as CDFs."""
        self.data["distributions"].append({"title": title, "series": {k: list(v) for k, v in series.items()}})

    def note(self, text: str) -> None:
        self.data["notes"].append(text)

    def missing(self, what: str) -> None:
        """A figure that could not be measured, and why: printed, and the script's exit status becomes 1."""
        print(f"  not measured: {what}")
        self.data["not_measured"].append(what)

    def finish(self) -> int:
        """Prints the tables, writes the JSON if asked, and gives the exit status: 1 if anything was not measured."""
        self.data["seconds"] = round(time.monotonic() - self.started, 1)
        self.data["machine_at_end"] = machine()
        for table in self.data["tables"]:
            print(f"\n{table['title']}")
            print(text_table(table["rows"]))
        for note in self.data["notes"]:
            print(f"  {note}")
        print(f"ran {self.data['seconds']} s")
        if self.json_path:
            self.json_path.write_text(json.dumps(self.data, indent=1))
        return 1 if self.data["not_measured"] else 0


def cell(value) -> str:
    """A value as a table shows it: floats with two decimals below 100, none above, small ones as they are."""
    if isinstance(value, float):
        if value and abs(value) < 0.01:
            return f"{value:.2g}"
        return f"{value:.2f}" if abs(value) < 100 else f"{value:.0f}"
    if isinstance(value, list | tuple):
        # A few values (load averages, a pair) side by side; a script's raw samples are no cell's business.
        return "/".join(cell(v) for v in value) if len(value) <= 4 else f"({len(value)} values)"
    if isinstance(value, dict):
        return ", ".join(f"{k} {cell(v)}" for k, v in value.items())
    return "" if value is None else str(value)


def columns_of(rows: Sequence[dict]) -> list[str]:
    """Every column of `rows`, in the order they first appear."""
    return list(dict.fromkeys(key for row in rows for key in row))


def text_table(rows: Sequence[dict]) -> str:
    """`rows` as aligned plain text."""
    columns = columns_of(rows)
    cells = [columns] + [[cell(row.get(c)) for c in columns] for row in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(columns))]
    return "\n".join("  ".join(v.rjust(w) for v, w in zip(r, widths, strict=True)) for r in cells)
