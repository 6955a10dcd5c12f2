"""The virtual terminals against the real Beckhoff terminals of `../shared/real-ethercat/`: their SII images, what
SOEM read of a real EL1004, and a replay of SOEM's session with a real EK1100 and EL1004 (the replay itself:
support/replay.py).

`ek1100.hex` and `el2004-eeprom-dump.bin` are raw dumps of real terminals' EEPROMs;
`soem-sdinfo-ek1100-el1004.pcapng` is SOEM (slaveinfo) scanning a real EK1100 followed by a real EL1004: ESC
registers, SII reads word by word, PreOp, SM and FMMU set-up, DC measurement and SafeOp. Tests skip where the
directory is absent.
"""

from __future__ import annotations

import struct

import pytest

from akd_ros import _native
from support.ethercat import parse, payload_of
from support.pcapng_reader import read_packets
from support.replay import replay, report

CAPTURE = "soem-sdinfo-ek1100-el1004.pcapng"
# The replay gets at least this share of the real line's deterministic replies right (issue 35).
REQUIRED_SHARE = 0.99
SII_CONTROL, SII_ADDRESS, SII_DATA = 0x0502, 0x0504, 0x0508


@pytest.mark.parametrize(("product", "dump"), [("ek1100", "ek1100.hex"), ("el2004", "el2004-eeprom-dump.bin")])
def test_real_ethercat_virtual_images_are_the_real_dumps(real_ethercat_dir, product, dump):
    real = (real_ethercat_dir / dump).read_bytes()
    assert _native.sim_sii_image(product) == real


@pytest.mark.parametrize(
    ("dump", "order", "product_code"),
    [
        ("ek1100.hex", "EK1100", 0x044C2C52),
        ("el2004-eeprom-dump.bin", "EL2004", 0x07D43052),
        ("el2262.bin", "EL2262", 0x08D63052),
        ("el2828.hex", "EL2828", 0x0B0C3052),
        ("el2889.hex", "EL2889", 0x0B493052),
    ],
)
def test_real_ethercat_images_read_with_the_codec(real_ethercat_dir, dump, order, product_code):
    sii = _native.parse_sii((real_ethercat_dir / dump).read_bytes())
    assert (sii["vendor_id"], sii["product_code"], sii["order"]) == (2, product_code, order)


def sii_reads(capture) -> dict[int, dict[int, bytes]]:
    """Per station address, the EEPROM words SOEM read in `capture` and the 8 bytes each read gave."""
    address: dict[int, int] = {}
    reads: dict[int, dict[int, bytes]] = {}
    for packet in read_packets(capture):
        payload = payload_of(packet.data)
        if payload is None or not packet.data[6] & 0x02:
            continue
        for d in parse(payload):
            if d.wkc and d.name == "FPWR" and d.ado == SII_CONTROL and len(d.data) == 6:
                address[d.adp] = struct.unpack_from("<I", d.data, 2)[0]
            elif d.wkc and d.name == "FPRD" and d.ado == SII_DATA and d.adp in address:
                reads.setdefault(d.adp, {})[address[d.adp]] = d.data
    return reads


def test_real_ethercat_the_virtual_el1004_holds_what_soem_read_of_the_real_one(real_ethercat_dir):
    reads = sii_reads(real_ethercat_dir / CAPTURE)
    for station, product in ((0x1001, "ek1100"), (0x1002, "el1004")):
        image = _native.sim_sii_image(product)
        assert len(reads[station]) >= 10, f"too few SII reads of {product} in the capture"
        for word, data in reads[station].items():
            assert image[2 * word : 2 * word + len(data)] == data, f"{product} word 0x{word:04X}"
    el1004 = _native.parse_sii(_native.sim_sii_image("el1004"))
    assert (el1004["product_code"], el1004["revision"]) == (0x03EC3052, 0x00130000)
    assert [(p["index"], p["entries"][0]["bit_len"]) for p in el1004["tx_pdos"]] == [(0x1A00 + n, 1) for n in range(4)]


@pytest.fixture(scope="module")
def replayed(real_ethercat_dir):
    return replay(real_ethercat_dir / CAPTURE, _native.VirtualBus(line="ek1100,el1004"))


def test_real_ethercat_replay_of_soem_with_an_ek1100_and_an_el1004(replayed):
    comparable = report(*replayed)
    identical = sum(c.identical for c in comparable)
    assert len(comparable) > 200, "the capture holds too few comparable replies"
    assert identical >= REQUIRED_SHARE * len(comparable), f"{identical} of {len(comparable)} replies identical"
    for area in ("SII", "AL", "SM", "ESC", "DC"):
        assert any(c.area == area and c.identical for c in comparable), f"the replay compared no {area} reply"
