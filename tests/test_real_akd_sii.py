"""The SII codec against the real AKD's EEPROM image, and the virtual AKD's image against it.

`../shared/real-akd/akd.hex` is a raw 2048-byte dump of a real AKD-P00606-NBCC-E000's SII
EEPROM (firmware 01-20-00-003). The expected values below come from the drive's documentation
(AKD EtherCAT manual §5.1, §5.15) and from AKD_FACTS.md, not from running the codec.
"""

from __future__ import annotations

import pytest

from akd_ros import _native


@pytest.fixture(scope="module")
def real_image(real_akd_dir) -> bytes:
    return (real_akd_dir / "akd.hex").read_bytes()


def test_real_akd_sii_identity_and_names(real_image):
    sii = _native.parse_sii(real_image)
    assert (sii["vendor_id"], sii["product_code"], sii["revision"]) == (0x6A, 0x00414B44, 2)
    assert sii["serial_number"] == 0x99830093
    assert sii["name"] == "AKD EtherCAT Drive (CoE)"
    assert sii["model"] == "AKD-P00606-NBCC-E000"
    assert sii["firmware"] == "01-20-00-003"
    assert sii["eeprom_bytes"] == len(real_image) == 2048


def test_real_akd_sii_mailbox_and_sync_managers(real_image):
    sii = _native.parse_sii(real_image)
    # EoE, CoE, FoE.
    assert sii["mailbox_protocols"] == 0x0002 | 0x0004 | 0x0008
    assert sii["standard_mailbox"] == {
        "receive_offset": 0x1800,
        "receive_size": 0x400,
        "send_offset": 0x1C00,
        "send_size": 0x400,
    }
    layout = [(sm["start_address"], sm["control"], sm["type"]) for sm in sii["sync_managers"]]
    # FMMU 0 outputs, 1 inputs, 2 mailbox status, then an unused one.
    assert sii["fmmu_usage"] == [1, 2, 3, 0xFF]
    # Mailbox out, mailbox in, process data out, process data in.
    assert layout == [(0x1800, 0x26, 1), (0x1C00, 0x22, 2), (0x1100, 0x24, 3), (0x1140, 0x20, 4)]


def test_real_akd_sii_pdos_carry_named_entries(real_image):
    sii = _native.parse_sii(real_image)
    rx = {p["index"]: p for p in sii["rx_pdos"]}
    tx = {p["index"]: p for p in sii["tx_pdos"]}
    # The manual's default fixed mappings: 0x1701 (set-point, controlword) on SM2 and
    # 0x1B01 on SM3.
    assert [(e["index"], e["subindex"], e["bit_len"], e["name"]) for e in rx[0x1701]["entries"]] == [
        (0x60C1, 1, 32, "1st set-point"),
        (0x6040, 0, 16, "Controlword"),
    ]
    assert rx[0x1701]["sync_manager"] == 2
    assert tx[0x1B01]["sync_manager"] == 3
    assert [e["name"] for e in tx[0x1B01]["entries"]] == ["Position actual internal value", "Statusword"]
    assert {p["name"] for p in sii["rx_pdos"]} == {"Outputs"}
    assert {p["name"] for p in sii["tx_pdos"]} == {"Inputs"}
    assert sorted(rx) == [0x1600, 0x1601, 0x1602, 0x1603, *range(0x1701, 0x1703), *range(0x1720, 0x1726)]
    assert [m["name"] for m in sii["dc_modes"]] == ["DcSync", "DcOff"]
    assert sii["dc_modes"][0]["assign_activate"] == 0x0300


def test_real_akd_sii_virtual_image_equals_the_real_one(real_image):
    ours = _native.akd_sii_image()
    first_difference = next((i for i, (a, b) in enumerate(zip(ours, real_image, strict=False)) if a != b), None)
    assert first_difference is None, f"first differing byte at 0x{first_difference:04X}"
    assert len(ours) == len(real_image)


def test_real_akd_sii_bad_images_raise_named_errors():
    image = bytearray(_native.akd_sii_image())
    with pytest.raises(_native.SiiError, match="shorter than the 128-byte header"):
        _native.parse_sii(bytes(image[:100]))
    corrupt = bytearray(image)
    corrupt[8] ^= 0x01
    with pytest.raises(_native.SiiError, match="checksum"):
        _native.parse_sii(bytes(corrupt))
    # Cut inside the TxPDO category: its length word now runs past the data.
    with pytest.raises(_native.SiiError, match=r"category 0x0032 .* announces"):
        _native.parse_sii(bytes(image[:0x300]))
    # A PDO entry naming string 200 of a table of 33.
    bad_name = bytearray(image)
    statusword_name = image.index(bytes([0x41, 0x60, 0x00, 0x09]))
    bad_name[statusword_name + 3] = 200
    with pytest.raises(_native.SiiError, match="names string 200 but the strings category has 33"):
        _native.parse_sii(bytes(bad_name))


def test_real_akd_sii_scan_of_the_virtual_akd_reports_the_real_identity(real_image):
    if not hasattr(_native, "Master"):
        pytest.skip("akd_ros._native.Master is not built yet (MASTER engineer's binding)")
    real = _native.parse_sii(real_image)
    master = _native.Master("sim")
    try:
        (slave,) = master.scan()
    finally:
        master.close()
    for key in ("vendor_id", "product_code", "revision", "serial_number", "name", "model", "firmware"):
        assert slave[key] == real[key], key
    assert slave["mailbox_protocols"] == real["mailbox_protocols"]
