"""Replays every request of a real AKD's SOEM session into a fresh virtual AKD and holds each
reply to the real drive's (the replay itself: support/replay.py).

The capture `../shared/real-akd/soem-sdinfo-akd.pcapng` is SOEM scanning a real AKD: init,
SII reads, PreOp, SDO uploads of the PDO assignment and mapping, and a SafeOp request that the
drive refuses (odd process image, AL status code 0x001D). Reads of the DC receive and system
times differ by nature and are left out.

The drive of this capture had been powered up long before: its Init->PreOp took 4.2-6.2 ms and
its first mailbox reply came at once, as a real AKD's later ones do under TwinCAT, not its first
after power-up (docs/virtual_akd.md). The replay's virtual AKD is such a drive (`warm=True`).

One thing differs by timing, not by content: how soon the drive's firmware answers a mailbox
request. The real drive's replies appear 0.56 to 2.9 ms after the request, most by 1.3 ms, with no
pattern the capture reveals for certain; the virtual AKD answers after a fixed 1 ms. SOEM's polls of
the mailbox-in status (0x080D) that fall in between read "not yet" from the real drive and "full"
from the virtual one; they are counted apart and must be exactly that kind of difference.
"""

from __future__ import annotations

import pytest

from support.replay import Compared, replay, report

akd = pytest.importorskip("akd_ros._native")

CAPTURE = "soem-sdinfo-akd.pcapng"
# Mailbox status registers (SM0 0x0805, SM1 0x080D), whose "full" bit shows the firmware's timing.
MAILBOX_STATUS = (0x0805, 0x080D)
MAILBOX_FULL = 0x08


def mailbox_timing(c: Compared) -> bool:
    """A mailbox status poll where only the full bit differs: the virtual AKD's reply is there, the real drive's not
    yet."""
    if not (c.physical and c.request.ado in MAILBOX_STATUS) or c.identical:
        return False
    real, ours = c.real.data, c.ours.data
    only_full_differs = ours[0] & MAILBOX_FULL != 0 and real[0] & MAILBOX_FULL == 0 and real[1:] == ours[1:]
    return only_full_differs and c.real.wkc == c.ours.wkc


@pytest.fixture(scope="module")
def replayed(real_akd_dir):
    capture = real_akd_dir / CAPTURE
    if not capture.exists():
        pytest.skip(f"{capture} is absent")
    return replay(capture, akd.VirtualBus(1, warm=True))


def test_real_akd_replay_report(replayed):
    assert report(*replayed), "the capture holds no comparable replies"


def test_real_akd_replay_every_reply_matches(replayed):
    compared, _ = replayed
    comparable = [c for c in compared if not c.time_varying]
    timing = [c for c in comparable if mailbox_timing(c)]
    content = [c for c in comparable if not mailbox_timing(c)]
    differing = [c.describe() for c in content if not c.identical]
    print(f"\n{len(timing)} mailbox status polls differ by the firmware's reply time only")
    print(f"identical without them: {len(content) - len(differing)}/{len(content)}")
    assert not differing, "replies differ from the real drive's:\n" + "\n".join(differing)
    for area in ("SII", "AL", "SM", "mailbox", "ESC"):
        assert any(c.area == area for c in content), f"the replay compared no {area} reply"
    # The firmware timing differs on a minority of polls; most land on the same side.
    polls = [c for c in comparable if c.physical and c.request.ado in MAILBOX_STATUS]
    assert len(timing) < len(polls) / 4, f"{len(timing)} of {len(polls)} mailbox status polls differ"
