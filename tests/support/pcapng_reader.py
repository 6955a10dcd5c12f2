"""A small pcapng reader: enough to walk the Ethernet frames of a capture with their timestamps.

Only the blocks a capture of an EtherCAT session holds are decoded (section header, interface
description, enhanced and simple packet blocks); others are skipped by their length, so a file
with comments or statistics still reads.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

SECTION_HEADER = 0x0A0D0D0A
INTERFACE_DESCRIPTION = 0x00000001
SIMPLE_PACKET = 0x00000003
ENHANCED_PACKET = 0x00000006
BYTE_ORDER_MAGIC = 0x1A2B3C4D
OPTION_IF_TSRESOL = 9
# Fields of a packet block before its packet data: interface, timestamp (2), captured and
# original lengths for an enhanced one; the original length for a simple one.
ENHANCED_PACKET_FIXED_LEN = 20
SIMPLE_PACKET_FIXED_LEN = 4


@dataclass(frozen=True)
class Packet:
    """One captured frame: its number (1-based, as tshark counts), time in ns and bytes."""

    number: int
    time_ns: int
    data: bytes


class PcapngError(ValueError):
    """The file is not a pcapng capture this reader understands."""


def _resolution_ns(options: bytes, endian: str) -> float:
    """Nanoseconds per timestamp unit from the interface's if_tsresol option (default µs)."""
    pos = 0
    while pos + 4 <= len(options):
        code, length = struct.unpack_from(endian + "HH", options, pos)
        if code == 0:
            break
        value = options[pos + 4 : pos + 4 + length]
        if code == OPTION_IF_TSRESOL and value:
            exponent = value[0] & 0x7F
            units_per_second = 2**exponent if value[0] & 0x80 else 10**exponent
            return 1e9 / units_per_second
        pos += 4 + ((length + 3) & ~3)
    return 1000.0


def read_packets(path: str | Path) -> Iterator[Packet]:
    """Yields every packet of the capture at `path` in file order."""
    return parse_packets(Path(path).read_bytes())


def parse_packets(data: bytes) -> Iterator[Packet]:
    """Yields every packet of the capture `data` (a whole pcapng file) in file order."""
    pos = 0
    endian = "<"
    resolutions: list[float] = []
    number = 0
    while pos + 12 <= len(data):
        block_type = struct.unpack_from("<I", data, pos)[0]
        if block_type == SECTION_HEADER:
            magic = struct.unpack_from("<I", data, pos + 8)[0]
            if magic == BYTE_ORDER_MAGIC:
                endian = "<"
            elif magic == struct.unpack("<I", struct.pack(">I", BYTE_ORDER_MAGIC))[0]:
                endian = ">"
            else:
                raise PcapngError(f"bad byte-order magic 0x{magic:08X} at offset {pos}")
            resolutions = []
        block_type, length = struct.unpack_from(endian + "II", data, pos)
        if length < 12 or pos + length > len(data):
            raise PcapngError(f"block at offset {pos} has length {length}, past the end of the file")
        body = data[pos + 8 : pos + length - 4]
        if block_type == INTERFACE_DESCRIPTION:
            resolutions.append(_resolution_ns(body[8:], endian))
        elif block_type == ENHANCED_PACKET:
            if len(body) < ENHANCED_PACKET_FIXED_LEN:
                raise PcapngError(f"enhanced packet block at offset {pos} is {length} bytes, shorter than its fields")
            interface, high, low, captured = struct.unpack_from(endian + "IIII", body, 0)
            if captured > len(body) - ENHANCED_PACKET_FIXED_LEN:
                raise PcapngError(f"enhanced packet block at offset {pos} captured {captured} bytes, past its end")
            number += 1
            resolution = resolutions[interface] if interface < len(resolutions) else 1000.0
            start = ENHANCED_PACKET_FIXED_LEN
            yield Packet(number, int(((high << 32) | low) * resolution), body[start : start + captured])
        elif block_type == SIMPLE_PACKET:
            if len(body) < SIMPLE_PACKET_FIXED_LEN:
                raise PcapngError(f"simple packet block at offset {pos} is {length} bytes, shorter than its fields")
            number += 1
            yield Packet(number, 0, body[4:])
        pos += length
