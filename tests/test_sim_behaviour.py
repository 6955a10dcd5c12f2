"""The virtual AKD answers wrong requests as the AKD does: AL status codes 0x0011, 0x0017 and
0x001D, SDO abort codes, mailbox errors, and malformed frames refused with FrameError; and the
drives of one virtual line tell themselves apart by their serial numbers, as real ones do."""

from __future__ import annotations

import contextlib
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from support.ethercat import COMMANDS, Datagram, VirtualAkdSession, build, datagram, exchange, parse
from support.netns import akd_sim_udp

akd = pytest.importorskip("akd_ros._native")

INIT, PREOP, SAFEOP, OP = 0x01, 0x02, 0x04, 0x08
ACK, ERROR = 0x10, 0x10
# The real AKD's serial number (AKD_FACTS.md, its SII dump).
REAL_SERIAL = 0x99830093


@pytest.fixture
def session():
    return VirtualAkdSession(akd.VirtualBus(1))


def test_sim_power_up_identity(session):
    assert session.fp("FPRD", 0x0000, 2).data == b"\x04\x02"
    assert session.al_request(INIT) == (INIT, 0)


def test_sim_invalid_state_change_gives_0x0011(session):
    assert session.al_request(SAFEOP) == (INIT | ERROR, 0x0011)
    assert session.al_request(OP | ACK) == (INIT | ERROR, 0x0011)


def test_sim_preop_without_mailbox_gives_0x0017(session):
    assert session.al_request(PREOP) == (INIT | ERROR, 0x0017)
    session.configure_mailbox()
    assert session.al_request(PREOP | ACK) == (PREOP, 0)


def test_sim_odd_power_up_mapping_gives_0x001d(session):
    session.configure_mailbox()
    session.al_request(PREOP)
    session.fp("FPWR", 0x0810, struct.pack("<HHBBBB", 0x1100, 17, 0x24, 0, 1, 0))
    session.fp("FPWR", 0x0818, struct.pack("<HHBBBB", 0x1140, 17, 0x20, 0, 1, 0))
    assert session.al_request(SAFEOP) == (PREOP | ERROR, 0x001D)


def test_sim_fixed_mapping_reaches_op_and_exchanges_process_data(session):
    session.configure_mailbox()
    session.al_request(PREOP)
    for assign, pdo in ((0x1C12, 0x1701), (0x1C13, 0x1B01)):
        assert session.sdo_download(assign, 0, b"\0")[0] == 0x60
        assert session.sdo_download(assign, 1, pdo.to_bytes(2, "little"))[0] == 0x60
        assert session.sdo_download(assign, 0, b"\1")[0] == 0x60
    # Wrong SM2 length: 0x0017; right: SafeOp.
    session.fp("FPWR", 0x0810, struct.pack("<HHBBBB", 0x1100, 8, 0x24, 0, 1, 0))
    session.fp("FPWR", 0x0818, struct.pack("<HHBBBB", 0x1140, 6, 0x20, 0, 1, 0))
    assert session.al_request(SAFEOP) == (PREOP | ERROR, 0x0017)
    session.fp("FPWR", 0x0810, struct.pack("<HHBBBB", 0x1100, 6, 0x24, 0, 1, 0))
    fmmu_out = struct.pack("<IHBBHBBBxxx", 0x10000, 6, 0, 7, 0x1100, 0, 2, 1)
    fmmu_in = struct.pack("<IHBBHBBBxxx", 0x10006, 6, 0, 7, 0x1140, 0, 1, 1)
    session.fp("FPWR", 0x0600, fmmu_out + fmmu_in)
    assert session.al_request(SAFEOP | ACK) == (SAFEOP, 0)
    assert session.al_request(OP) == (OP, 0)
    outputs = struct.pack("<iH", 123456, 0x000F)
    session.time_ns += 1_000_000
    lrw = exchange(session.bus, session.time_ns, Datagram(12, 0, 0x0000, 0x0001, outputs + bytes(6)))[0]
    assert lrw.wkc == 3
    assert lrw.data[6:] == struct.pack("<iH", 0, 0x0240), "position 0, statusword switch on disabled"
    # The controlword reached the object dictionary.
    assert session.sdo_upload(0x6040, 0) == (0x4B, b"\x0f\x00\x00\x00")
    assert session.sdo_upload(0x60C1, 1) == (0x43, struct.pack("<i", 123456))


@pytest.mark.parametrize(
    "index, subindex, value, code",
    [
        (0x1234, 0, b"\0", 0x06020000),  # object does not exist
        (0x6040, 7, b"\0\0", 0x06090011),  # subindex does not exist
        (0x6041, 0, b"\0\0", 0x06010002),  # read-only
        (0x6060, 0, b"\x02", 0x06090030),  # value range (mode 2 is not an AKD mode)
        (0x6040, 0, b"\0", 0x06070013),  # length too low
        (0x1600, 1, b"\x10\0\x40\x60", 0x06010003),  # entries only while sub 0 is 0
        (0x60C2, 2, b"\xfa", 0x06090032),  # 2 x 10^-6 s is below 250 µs
    ],
)
def test_sim_sdo_aborts(session, index, subindex, value, code):
    session.configure_mailbox()
    session.al_request(PREOP)
    assert session.sdo_download(index, subindex, value) == (0x80, code)


def test_sim_assignment_only_in_preop(session):
    session.configure_mailbox()
    session.al_request(PREOP)
    session.fp("FPWR", 0x0810, struct.pack("<HHBBBB", 0x1100, 17, 0x24, 0, 1, 0))
    assert session.sdo_upload(0x1C12, 0) == (0x4F, b"\x04\0\0\0")
    # Bootstrap is refused from PreOp; the mailbox keeps working in the error state.
    assert session.al_request(0x03) == (PREOP | ERROR, 0x0011)
    assert session.sdo_download(0x1C12, 0, b"\0") == (0x60, 0)


def test_sim_unsupported_mailbox_protocol_gets_a_mailbox_error(session):
    session.configure_mailbox()
    session.al_request(PREOP)
    reply = session.coe(0, b"\x01\x02", mailbox_type=0x05)
    assert reply[5] & 0x0F == 0 and struct.unpack_from("<HH", reply, 6) == (0x0001, 0x0002)


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=200))
def test_sim_garbage_never_panics(payload):
    bus = akd.VirtualBus(2)
    try:
        reply = bus.process(payload, 0)
    except akd.FrameError:
        return
    assert len(reply) == len(payload)


datagrams = st.builds(
    Datagram,
    command=st.integers(0, len(COMMANDS) - 1),
    index=st.integers(0, 255),
    adp=st.sampled_from([0, 1, 0xFFFF, 0x1001, 0x0000]) | st.integers(0, 0xFFFF),
    ado=st.sampled_from([0x0120, 0x0502, 0x0800, 0x0900, 0x0910, 0x1800, 0x1C00, 0xFFF0]) | st.integers(0, 0xFFFF),
    data=st.binary(max_size=64),
)


@settings(max_examples=300, deadline=None)
@given(st.lists(datagrams, min_size=1, max_size=6), st.integers(0, 2**63))
def test_sim_random_datagrams_are_served(frame, time_ns):
    bus = akd.VirtualBus(3, immediate=True)
    reply = parse(bus.process(build(*frame), time_ns))
    assert [(d.command, d.index, len(d.data)) for d in reply] == [(d.command, d.index, len(d.data)) for d in frame]
    # And again after a mailbox set-up, so mailbox and AL paths see random input too.
    session = VirtualAkdSession(bus)
    session.configure_mailbox()
    session.al_request(PREOP)
    exchange(bus, session.time_ns + 1, *frame)
    session.fp("FPRD", 0x0130, 6)
    assert exchange(bus, 0, datagram("BRD", 0, 0x0000, 2))[0].wkc == 3


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=80))
def test_sim_mailbox_garbage_gets_an_answer(message):
    session = VirtualAkdSession(akd.VirtualBus(1, immediate=True))
    session.configure_mailbox()
    session.al_request(PREOP)
    assert session.fp("FPWR", 0x1800, message.ljust(0x400, b"\0")).wkc == 1
    reply = session.fp("FPRD", 0x1C00, 0x400)
    padded = message.ljust(16, b"\0")
    announced = int.from_bytes(padded[0:2], "little")
    is_coe_sdo = 10 <= announced <= 0x3FA and padded[5] & 0x0F == 3 and padded[7] >> 4 == 2
    is_sdo_abort = is_coe_sdo and padded[8] >> 5 == 4
    # An EoE message that is long enough to be one carries a fragment of an Ethernet frame for the drive's IP stack
    # (or a response, or a frame type it ignores): answered only when it asks for an answer, as a set-IP request.
    is_eoe = 4 <= announced <= 0x3FA and padded[5] & 0x0F == 2
    if not is_eoe:
        assert reply.wkc == (0 if is_sdo_abort else 1), reply.data[:16].hex()
    # The drive keeps answering after whatever came before; the next request counts on from
    # the garbage's mailbox counter, as a master's would (the same counter is a repetition).
    session.counter = padded[5] >> 4 & 0x07
    assert session.sdo_upload(0x1018, 1) == (0x43, b"\x6a\0\0\0")


@contextlib.contextmanager
def three_drives(link: str, udp_port: int):
    """The link to a line of three virtual AKDs: in this process, or `akd-sim --count 3` over UDP."""
    if link == "sim:3":
        yield link
    else:
        with akd_sim_udp(udp_port, count=3):
            yield f"udp://127.0.0.1:{udp_port}"


@pytest.mark.parametrize("link", ["sim:3", "udp"])
def test_sim_drives_on_one_line_report_distinct_serials_in_sii_and_0x1018(link, udp_port):
    serials = []
    for _run in range(2):
        with three_drives(link, udp_port) as url, akd.Master(url, timeout=0.5) as master:
            # The scan's identity comes from each drive's SII.
            from_sii = [slave["serial_number"] for slave in master.scan()]
            master.request_state("preop")
            from_od = [int.from_bytes(master.sdo_read(p, 0x1018, 4), "little") for p in range(3)]
        assert from_od == from_sii, (from_od, from_sii)
        serials.append(from_sii)
    # The first drive is the real drive; the others differ from it and from each other, the same each run.
    assert serials[0][0] == REAL_SERIAL
    assert len(set(serials[0])) == 3, [hex(s) for s in serials[0]]
    assert serials[1] == serials[0]
