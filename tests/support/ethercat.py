"""Building and reading EtherCAT frames in tests, independent of the Rust codec under test.

A frame here is the EtherCAT payload: the 2-byte frame header and the datagrams, without the
Ethernet header (what `VirtualBus.process` takes).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

COMMANDS = "NOP APRD APWR APRW FPRD FPWR FPRW BRD BWR BRW LRD LWR LRW ARMW FRMW".split()
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
