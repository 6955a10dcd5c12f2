"""Replaying a capture of a real line into a virtual one: every request frame is processed at its capture time,
each reply held to the real slaves'.

Requests the real line did not answer are still replayed (they change state) but not compared. Reads of the DC
receive and system times differ by nature and are told apart (`Compared.time_varying`) so that a test leaves them
out. Shared by the replays of the real AKD's SOEM capture and of the real EK1100 and EL1004's.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from support.ethercat import COMMANDS, Datagram, parse, payload_of
from support.pcapng_reader import read_packets

RETURNED_MAC_BIT = 0x02
LOGICAL_COMMANDS = (10, 11, 12)
# Registers whose value is a time: the DC receive times (0x0900-0x090F), the system time (0x0910) and the processing
# unit's receive time (0x0918).
TIME_VARYING = range(0x0900, 0x0920)
AREAS = [
    ("SII", range(0x0500, 0x0510)),
    ("AL", range(0x0120, 0x0136)),
    ("SM", range(0x0800, 0x0880)),
    ("mailbox", range(0x1000, 0x2000)),
    ("DC", range(0x0900, 0x09B0)),
]


@dataclass
class Compared:
    """One datagram of the replay: the request, the real reply and the virtual line's."""

    frame: int
    request: Datagram
    real: Datagram
    ours: Datagram

    @property
    def identical(self) -> bool:
        return self.real == self.ours

    @property
    def physical(self) -> bool:
        return self.request.command not in LOGICAL_COMMANDS

    @property
    def time_varying(self) -> bool:
        reads = COMMANDS[self.request.command].endswith(("RD", "RW", "RMW"))
        span = range(self.request.ado, self.request.ado + len(self.request.data))
        return self.physical and reads and any(a in TIME_VARYING for a in span)

    @property
    def area(self) -> str:
        for name, span in AREAS:
            if self.physical and self.request.ado in span:
                return name
        return "ESC"

    def describe(self) -> str:
        r = self.request
        return (
            f"frame {self.frame} {r.name} 0x{r.adp:04X}:0x{r.ado:04X} ({len(r.data)} bytes): "
            f"real wkc {self.real.wkc} {self.real.data[:16].hex()} / "
            f"ours wkc {self.ours.wkc} {self.ours.data[:16].hex()}"
        )


def replay(capture: Path, bus) -> tuple[list[Compared], int]:
    """Replays `capture` into `bus` (a `_native.VirtualBus`); returns the compared datagrams and the number of requests
    the real line left unanswered."""
    frames = [(p.number, p.time_ns, p.data[6], payload_of(p.data)) for p in read_packets(capture)]
    frames = [f for f in frames if f[3] is not None]
    compared, unanswered = [], 0
    for i, (number, time_ns, source, payload) in enumerate(frames):
        if source & RETURNED_MAC_BIT:
            continue
        ours = parse(bus.process(payload, time_ns))
        following = frames[i + 1] if i + 1 < len(frames) else None
        if following is None or not following[2] & RETURNED_MAC_BIT:
            unanswered += 1
            continue
        real = parse(following[3])
        assert len(real) == len(ours), f"frame {number}: datagram count differs"
        compared += [Compared(number, q, r, o) for q, r, o in zip(parse(payload), real, ours, strict=True)]
    return compared, unanswered


def report(compared: list[Compared], unanswered: int, shown: int = 40) -> list[Compared]:
    """Prints what the replay found (for -s) and returns the deterministic replies."""
    comparable = [c for c in compared if not c.time_varying]
    identical = sum(c.identical for c in comparable)
    left_out = sorted({f"0x{c.request.ado:04X}" for c in compared if c.time_varying})
    print(f"\nreplayed {len(compared)} answered datagrams ({unanswered} requests unanswered in the capture)")
    if comparable:
        share = 100 * identical / len(comparable)
        print(
            f"identical: {sum(c.identical for c in compared)}/{len(compared)} of all, "
            f"{identical}/{len(comparable)} = {share:.2f} % of the non-time-varying"
        )
    print(f"left out as time-varying (DC receive/system time reads): {', '.join(left_out)}")
    different = [c for c in comparable if not c.identical]
    by_area: dict[str, int] = {}
    for c in different:
        by_area[c.area] = by_area.get(c.area, 0) + 1
    print(f"differences by area: {by_area}")
    for c in different[:shown]:
        print("  ", c.area, c.describe())
    return comparable
