"""The recovery table's measured times: each test of tests/test_recovery.py (and the node's) records its row here,
and conftest prints them all at the end of the run, as docs/howto/recovery.md's table quotes them."""

from __future__ import annotations

ROWS: list[tuple[str, str, str, str]] = []
"""(row, what the user sees, detection, recovery), in the order the tests ran."""


def ms(ns: int | None) -> str:
    """A duration in ns as milliseconds for the table, or "-" where there is none."""
    return "-" if ns is None else f"{ns / 1e6:.0f} ms"


def record(row: str, seen: str, detection_ns: int | None, recovery_ns: int | None) -> None:
    """Notes one row: what the user saw, and how long detection and recovery took (None: not applicable)."""
    ROWS.append((row, seen, ms(detection_ns), ms(recovery_ns)))


def lines() -> list[str]:
    """The table as Markdown lines."""
    out = ["| row | what the user sees | detected after | back in Op after |", "| --- | --- | --- | --- |"]
    out += [f"| {row} | {seen} | {detection} | {recovery} |" for row, seen, detection, recovery in ROWS]
    return out
