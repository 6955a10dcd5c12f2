"""The tests' pcapng reader refuses a truncated or overlong packet block with a PcapngError that
says where, as fuzzing it (native/fuzz, target pcapng_reader) asks, and reads the real capture."""

from __future__ import annotations

import struct

import pytest

from support.pcapng_reader import PcapngError, parse_packets, read_packets

ENHANCED_PACKET = 6
SIMPLE_PACKET = 3


def block(kind: int, body: bytes) -> bytes:
    length = 12 + len(body)
    return struct.pack("<II", kind, length) + body + struct.pack("<I", length)


def test_an_enhanced_packet_block_shorter_than_its_fields_is_named():
    # The input the fuzzer found: an enhanced packet block of 12 bytes, no fields at all.
    with pytest.raises(PcapngError, match="enhanced packet block at offset 0 is 12 bytes, shorter than its fields"):
        list(parse_packets(bytes.fromhex("060000000c00000001000000")))


def test_an_enhanced_packet_capturing_more_than_its_block_holds_is_named():
    body = struct.pack("<IIIII", 0, 0, 0, 100, 100) + bytes(8)
    with pytest.raises(PcapngError, match="at offset 0 captured 100 bytes, past its end"):
        list(parse_packets(block(ENHANCED_PACKET, body)))


def test_a_simple_packet_block_shorter_than_its_fields_is_named():
    with pytest.raises(PcapngError, match="simple packet block at offset 0 is 12 bytes"):
        list(parse_packets(block(SIMPLE_PACKET, b"")))


def test_well_formed_packets_read_as_before():
    frame = bytes(range(60))
    packets = list(
        parse_packets(
            block(ENHANCED_PACKET, struct.pack("<IIIII", 0, 0, 5, 60, 60) + frame)
            + block(SIMPLE_PACKET, struct.pack("<I", 60) + frame)
        )
    )
    assert [(p.number, p.time_ns, p.data) for p in packets] == [(1, 5000, frame), (2, 0, frame)]


def test_the_real_capture_reads_whole(real_akd_dir):
    packets = list(read_packets(real_akd_dir / "soem-sdinfo-akd.pcapng"))
    assert len(packets) == 6762
    assert sum(p.data[12:14] == b"\x88\xa4" for p in packets) == 6759
