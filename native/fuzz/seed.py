"""Writes the fuzz targets' seed corpora from the real AKD's files in ../shared/real-akd/.

Frames come from SOEM's session with a real AKD (soem-sdinfo-akd.pcapng), read with the
pcapng reader the tests use (tests/support/pcapng_reader.py):
- frame: every distinct EtherCAT payload sent or returned;
- mailbox, coe: the mailbox messages written to the drive's SM0 (0x1800) and read from its
  SM1 (0x1C00), cut to the length their header announces;
- virtual_akd: the master's requests in order as `[time step][length LE][payload]` records
  (see fuzz_targets/virtual_akd.rs), repeated polls left out (their time kept), in seeds of at
  most MAX_SEQUENCE bytes: the session's start, and later windows each led by the frames that
  brought the drive there (writes only);
- sii: the drive's SII EEPROM image (akd.hex);
- pcapng_reader: the capture's first 4 KiB (its header blocks and first packets).

Usage: python3 seed.py REAL_AKD_DIR CORPUS_DIR
"""

from __future__ import annotations

import hashlib
import struct
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
from support.pcapng_reader import read_packets

ETH_HEADER_LEN = 14
RETURNED_MAC_BIT = 0x02
MAILBOX_OUT, MAILBOX_IN = 0x1800, 0x1C00
# Commands that write (APWR, APRW, FPWR, FPRW, BWR, BRW, LWR, LRW, ARMW, FRMW).
WRITES = {2, 3, 5, 6, 8, 9, 11, 12, 13, 14}
FPWR, FPRD = 5, 4
STEP_NS = 100_000
MAX_SEQUENCE = 4096


def payload(ethernet: bytes) -> bytes:
    """The EtherCAT payload of an Ethernet frame, without the padding after its datagrams."""
    body = ethernet[ETH_HEADER_LEN:]
    length = struct.unpack_from("<H", body)[0] & 0x07FF
    return body[: 2 + length]


def datagrams(frame: bytes):
    """(command, ado, data) of each datagram of a well-formed payload."""
    pos, end = 2, len(frame)
    while pos + 10 <= end:
        command = frame[pos]
        ado, word = struct.unpack_from("<HH", frame, pos + 4)
        length = word & 0x07FF
        yield command, ado, frame[pos + 10 : pos + 10 + length]
        pos += 12 + length
        if not word & 0x8000:
            break


def mailbox_message(data: bytes) -> bytes | None:
    if len(data) < 6:
        return None
    length = struct.unpack_from("<H", data)[0]
    return data[: 6 + length] if length and 6 + length <= len(data) else None


def write(directory: Path, content: bytes) -> None:
    directory.mkdir(parents=True, exist_ok=True)
    (directory / hashlib.sha1(content).hexdigest()).write_bytes(content)


def record(step_ns: int, frame: bytes) -> bytes:
    return bytes([min(255, round(step_ns / STEP_NS))]) + struct.pack("<H", len(frame)) + frame


def main(real: Path, out: Path) -> None:
    packets = list(read_packets(real / "soem-sdinfo-akd.pcapng"))
    requests = []
    for packet in packets:
        if packet.data[12:14] != b"\x88\xa4":
            continue
        frame = payload(packet.data)
        write(out / "frame", frame)
        returned = packet.data[6] & RETURNED_MAC_BIT
        if not returned:
            requests.append((packet.time_ns, frame))
        for command, ado, data in datagrams(frame):
            written = command == FPWR and ado == MAILBOX_OUT and not returned
            read = command == FPRD and ado == MAILBOX_IN and returned
            if written or read:
                message = mailbox_message(data)
                if message:
                    write(out / "mailbox", message)
                    write(out / "coe", message)

    # Repeated polls carry nothing new for the drive: keep one, and the time they took.
    session, last, last_time = [], None, requests[0][0]
    for time_ns, frame in requests:
        if frame != last:
            session.append((time_ns - last_time, frame))
            last_time = time_ns
        last = frame
    writes = {i for i, (_, frame) in enumerate(session) if any(c in WRITES for c, _, _ in datagrams(frame))}
    start = 0
    while start < len(session):
        lead = b"".join(record(10 * STEP_NS, session[i][1]) for i in sorted(writes) if i < start)
        if start and len(lead) > MAX_SEQUENCE // 2:
            lead = b""
        seed = bytearray(lead)
        end = start
        while end < len(session) and len(seed) + len(record(*session[end])) <= MAX_SEQUENCE:
            seed += record(*session[end])
            end += 1
        write(out / "virtual_akd", bytes(seed))
        start = max(end, start + 1)

    write(out / "sii", (real / "akd.hex").read_bytes())
    capture = (real / "soem-sdinfo-akd.pcapng").read_bytes()
    write(out / "pcapng_reader", capture[:4096])
    for name, directory in sorted((d.name, d) for d in out.iterdir()):
        print(f"{name}: {len(list(directory.iterdir()))} seeds")


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]))
