"""Building and reading EtherCAT frames in tests, independent of the Rust codec under test.

A frame here is the EtherCAT payload: the 2-byte frame header and the datagrams, without the
Ethernet header (what `VirtualBus.process` takes).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

COMMANDS = [
    "NOP",
    "APRD",
    "APWR",
    "APRW",
    "FPRD",
    "FPWR",
    "FPRW",
    "BRD",
    "BWR",
    "BRW",
    "LRD",
    "LWR",
    "LRW",
    "ARMW",
    "FRMW",
]
ETHERTYPE = 0x88A4


@dataclass(frozen=True)
class Datagram:
    """One datagram: command code, index, address words, IRQ, data and working counter."""

    command: int
    index: int
    adp: int
    ado: int
    data: bytes
    wkc: int = 0
    irq: int = 0

    @property
    def name(self) -> str:
        return COMMANDS[self.command] if self.command < len(COMMANDS) else f"command {self.command}"


def build(*datagrams: Datagram) -> bytes:
    """The payload carrying `datagrams` in order."""
    body = b""
    for i, d in enumerate(datagrams):
        more = 0x8000 if i + 1 < len(datagrams) else 0
        body += struct.pack("<BBHHHH", d.command, d.index, d.adp, d.ado, len(d.data) | more, d.irq)
        body += d.data + struct.pack("<H", d.wkc)
    return struct.pack("<H", len(body) | 0x1000) + body


def datagram(name: str, adp: int, ado: int, data: bytes | int, index: int = 0) -> Datagram:
    """A request datagram by mnemonic; `data` is the bytes to write or the length to read."""
    payload = bytes(data) if isinstance(data, int) else data
    return Datagram(COMMANDS.index(name), index, adp, ado, payload)


def parse(payload: bytes) -> list[Datagram]:
    """The datagrams of a payload (trailing Ethernet padding is ignored)."""
    (word,) = struct.unpack_from("<H", payload, 0)
    end = 2 + (word & 0x07FF)
    pos, out = 2, []
    while pos < end:
        command, index, adp, ado, length, irq = struct.unpack_from("<BBHHHH", payload, pos)
        n = length & 0x07FF
        data = payload[pos + 10 : pos + 10 + n]
        (wkc,) = struct.unpack_from("<H", payload, pos + 10 + n)
        out.append(Datagram(command, index, adp, ado, bytes(data), wkc, irq))
        pos += 12 + n
        if not length & 0x8000:
            break
    return out


def payload_of(ethernet_frame: bytes) -> bytes | None:
    """The EtherCAT payload of an Ethernet frame, without padding; None for other EtherTypes."""
    if len(ethernet_frame) < 16 or struct.unpack_from(">H", ethernet_frame, 12)[0] != ETHERTYPE:
        return None
    (word,) = struct.unpack_from("<H", ethernet_frame, 14)
    return ethernet_frame[14 : 16 + (word & 0x07FF)]


def exchange(bus, time_ns: int, *datagrams: Datagram) -> list[Datagram]:
    """Sends one frame of `datagrams` through `bus` at `time_ns`; returns the reply datagrams."""
    return parse(bus.process(build(*datagrams), time_ns))


STATION = 0x1001
MAILBOX_OUT, MAILBOX_IN, MAILBOX_SIZE = 0x1800, 0x1C00, 0x400
# SM1's status register and its "mailbox full" bit; how many frames a reply is polled for.
SM1_STATUS, MAILBOX_FULL, MAILBOX_POLLS = 0x080D, 0x08, 10


class VirtualAkdSession:
    """Drives one virtual AKD by hand-built frames: station address, mailbox sync managers,
    AL requests and SDO transfers through the mailbox, with a clock that advances by 10 ms per
    frame (longer than the firmware's reaction times but its first mailbox reply's, which is
    polled for)."""

    def __init__(self, bus):
        self.bus = bus
        self.time_ns = 0
        self.counter = 0
        self.request("APWR", 0, 0x0010, STATION.to_bytes(2, "little"))

    def request(self, name: str, adp: int, ado: int, data: bytes | int) -> Datagram:
        self.time_ns += 10_000_000
        return exchange(self.bus, self.time_ns, datagram(name, adp, ado, data))[0]

    def fp(self, name: str, ado: int, data: bytes | int) -> Datagram:
        return self.request(name, STATION, ado, data)

    def configure_mailbox(self) -> None:
        self.fp("FPWR", 0x0800, struct.pack("<HHBBBB", MAILBOX_OUT, MAILBOX_SIZE, 0x26, 0, 1, 0))
        self.fp("FPWR", 0x0808, struct.pack("<HHBBBB", MAILBOX_IN, MAILBOX_SIZE, 0x22, 0, 1, 0))

    def al_request(self, state: int) -> tuple[int, int]:
        """Writes AL control and returns (AL status, AL status code) once the drive handled it."""
        self.fp("FPWR", 0x0120, state.to_bytes(2, "little"))
        self.time_ns += 10_000_000
        reply = self.fp("FPRD", 0x0130, 6).data
        return int.from_bytes(reply[0:2], "little"), int.from_bytes(reply[4:6], "little")

    def mailbox(self, message: bytes) -> bytes:
        """Writes a mailbox message and returns the drive's reply (the whole mailbox-in buffer)."""
        written = self.fp("FPWR", MAILBOX_OUT, message.ljust(MAILBOX_SIZE, b"\0"))
        assert written.wkc == 1, "the mailbox-out buffer refused the message"
        # As a master polls SM1's status for the reply: the drive's first reply after power-up
        # takes 30 ms, three frames of this clock.
        for _ in range(MAILBOX_POLLS):
            if self.fp("FPRD", SM1_STATUS, 1).data[0] & MAILBOX_FULL:
                break
        reply = self.fp("FPRD", MAILBOX_IN, MAILBOX_SIZE)
        assert reply.wkc == 1, "no reply in the mailbox-in buffer"
        return reply.data

    def coe(self, service: int, body: bytes, mailbox_type: int = 3) -> bytes:
        self.counter = self.counter % 7 + 1
        header = struct.pack("<HHBB", 2 + len(body), 0, 0, mailbox_type | self.counter << 4)
        return self.mailbox(header + struct.pack("<H", service << 12) + body)

    def sdo_upload(self, index: int, subindex: int) -> tuple[int, bytes]:
        """Expedited upload request: returns the SDO command byte of the reply and its data."""
        reply = self.coe(2, struct.pack("<BHBI", 0x40, index, subindex, 0))
        return reply[8], reply[12:16]

    def sdo_download(self, index: int, subindex: int, value: bytes) -> tuple[int, int]:
        """Expedited download: returns the reply's command byte and its 4 data bytes as a number
        (the abort code when the command is 0x80)."""
        command = 0x23 | (4 - len(value)) << 2
        reply = self.coe(2, struct.pack("<BHB", command, index, subindex) + value.ljust(4, b"\0"))
        return reply[8], int.from_bytes(reply[12:16], "little")
