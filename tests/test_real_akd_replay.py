"""Replays every request of a real AKD's SOEM session into a fresh virtual AKD and holds each
reply to the real drive's.

The capture `../shared/real-akd/soem-sdinfo-akd.pcapng` is SOEM scanning a real AKD: init,
SII reads, PreOp, SDO uploads of the PDO assignment and mapping, and a SafeOp request that the
drive refuses (odd process image, AL status code 0x001D). Each request frame is processed at its
capture time; requests the real drive did not answer are still replayed (they change state) but
not compared. Reads of the DC receive and system times differ by nature and are left out.

The drive of this capture went from Init to PreOp within 4.2-6.2 ms of the request, where a real AKD
under TwinCAT took about 19 ms (the virtual AKD's default, 17.5 ms; docs/virtual_akd.md): the replay
gives the virtual AKD this drive's pace there, 4.5 ms.

One thing differs by timing, not by content: how soon the drive's firmware answers a mailbox
request. The real drive's replies appear 0.56 to 2.9 ms after the request, most by 1.3 ms, with no
pattern the capture reveals for certain; the virtual AKD answers after a fixed 1 ms. SOEM's polls of
the mailbox-in status (0x080D) that fall in between read "not yet" from the real drive and "full"
from the virtual one; they are counted apart and must be exactly that kind of difference.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import pytest

from support.ethercat import COMMANDS, Datagram, parse, payload_of
from support.pcapng_reader import read_packets

akd = pytest.importorskip("akd_ros._native")

CAPTURE = "soem-sdinfo-akd.pcapng"
# This capture's drive: PreOp within 4.2-6.2 ms of the request.
INIT_TO_PREOP_MS = 4.5
RETURNED_MAC_BIT = 0x02
# Registers whose value is a time: the DC receive times (0x0900-0x090F), the system time
# (0x0910) and the processing unit's receive time (0x0918).
TIME_VARYING = range(0x0900, 0x0920)
# Mailbox status registers (SM0 0x0805, SM1 0x080D), whose "full" bit shows the firmware's timing.
MAILBOX_STATUS = (0x0805, 0x080D)
MAILBOX_FULL = 0x08
AREAS = [
    ("SII", range(0x0500, 0x0510)),
    ("AL", range(0x0120, 0x0136)),
    ("SM", range(0x0800, 0x0880)),
    ("mailbox", range(0x1000, 0x2000)),
    ("DC", range(0x0900, 0x09B0)),
]


@dataclass
class Compared:
    """One datagram of the replay: the request, the real reply and the virtual AKD's."""

    frame: int
    request: Datagram
    real: Datagram
    ours: Datagram

    @property
    def identical(self) -> bool:
        return self.real == self.ours

    @property
    def physical(self) -> bool:
        return self.request.command not in (10, 11, 12)

    @property
    def time_varying(self) -> bool:
        reads = COMMANDS[self.request.command].endswith(("RD", "RW", "RMW"))
        span = range(self.request.ado, self.request.ado + len(self.request.data))
        return self.physical and reads and any(a in TIME_VARYING for a in span)

    @property
    def mailbox_timing(self) -> bool:
        """A mailbox status poll where only the full bit differs: the virtual AKD's reply is
        there, the real drive's not yet."""
        if not (self.physical and self.request.ado in MAILBOX_STATUS) or self.identical:
            return False
        real, ours = self.real.data, self.ours.data
        return (
            ours[0] & MAILBOX_FULL != 0
            and real[0] & MAILBOX_FULL == 0
            and real[1:] == ours[1:]
            and self.real.wkc == self.ours.wkc
        )

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


def replay(capture) -> tuple[list[Compared], int]:
    """Replays the capture; returns the compared datagrams and the number of unanswered requests."""
    frames = [(p.number, p.time_ns, p.data[6], payload_of(p.data)) for p in read_packets(capture)]
    frames = [f for f in frames if f[3] is not None]
    bus = akd.VirtualBus(1, init_to_preop_ms=INIT_TO_PREOP_MS)
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


@pytest.fixture(scope="module")
def replayed(real_akd_dir):
    capture = real_akd_dir / CAPTURE
    if not capture.exists():
        pytest.skip(f"{capture} is absent")
    return replay(capture)


def test_real_akd_replay_report(replayed):
    compared, unanswered = replayed
    comparable = [c for c in compared if not c.time_varying]
    identical = sum(c.identical for c in comparable)
    left_out = sorted({f"0x{c.request.ado:04X}" for c in compared if c.time_varying})
    print(f"\nreplayed {len(compared)} answered datagrams ({unanswered} requests unanswered in the capture)")
    print(
        f"identical: {sum(c.identical for c in compared)}/{len(compared)} of all, "
        f"{identical}/{len(comparable)} = {100 * identical / len(comparable):.2f} % of the non-time-varying"
    )
    print(f"left out as time-varying (DC receive/system time reads): {', '.join(left_out)}")
    by_area = Counter(c.area for c in comparable if not c.identical)
    print(f"differences by area: {dict(by_area)}")
    for c in [c for c in comparable if not c.identical][:40]:
        print("  ", c.area, c.describe())
    assert comparable, "the capture holds no comparable replies"


def test_real_akd_replay_every_reply_matches(replayed):
    compared, _ = replayed
    comparable = [c for c in compared if not c.time_varying]
    timing = [c for c in comparable if c.mailbox_timing]
    content = [c for c in comparable if not c.mailbox_timing]
    differing = [c.describe() for c in content if not c.identical]
    print(f"\n{len(timing)} mailbox status polls differ by the firmware's reply time only")
    print(f"identical without them: {len(content) - len(differing)}/{len(content)}")
    assert not differing, "replies differ from the real drive's:\n" + "\n".join(differing)
    for area in ("SII", "AL", "SM", "mailbox", "ESC"):
        assert any(c.area == area for c in content), f"the replay compared no {area} reply"
    # The firmware timing differs on a minority of polls; most land on the same side.
    polls = [c for c in comparable if c.physical and c.request.ado in MAILBOX_STATUS]
    assert len(timing) < len(polls) / 4, f"{len(timing)} of {len(polls)} mailbox status polls differ"
