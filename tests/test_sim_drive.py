"""The virtual AKD's drive from Python: CiA 402 by SDO, the motor moving, injected faults with
their emergency message and 0x603F, the hardware enable, and a latch firing where a simulated
input toggles. The master-side tests are native/tests/drive_motion.rs."""

from __future__ import annotations

import struct

import pytest

from support.ethercat import MAILBOX_IN, MAILBOX_SIZE, VirtualAkdSession

akd = pytest.importorskip("akd_ros._native")

PREOP = 0x02
REV = 1 << 20
SHUTDOWN, SWITCH_ON, ENABLE_OPERATION, FAULT_RESET = 0x0006, 0x0007, 0x000F, 0x0080


def sdo_write(session: VirtualAkdSession, index: int, subindex: int, value: bytes) -> None:
    command, code = session.sdo_download(index, subindex, value)
    assert command == 0x60, f"0x{index:04X}:{subindex} refused with abort 0x{code:08X}"


def sdo_read(session: VirtualAkdSession, index: int, size: int = 4) -> int:
    command, data = session.sdo_upload(index, 0)
    assert command & 0xF3 == 0x43, f"0x{index:04X} not uploaded (command 0x{command:02X})"
    return int.from_bytes(data[:size], "little", signed=index not in (0x6041, 0x603F, 0x20A5))


@pytest.fixture
def session():
    s = VirtualAkdSession(akd.VirtualBus(1, immediate=True))
    s.configure_mailbox()
    assert s.al_request(PREOP) == (PREOP, 0)
    return s


def enable_profile_velocity(session: VirtualAkdSession) -> None:
    sdo_write(session, 0x6060, 0, b"\x03")
    for controlword in (SHUTDOWN, SWITCH_ON, ENABLE_OPERATION):
        sdo_write(session, 0x6040, 0, struct.pack("<H", controlword))
    assert session.bus.drive_state(0)["state"] == "Operation enabled"


def test_sim_drive_moves_in_profile_velocity(session):
    assert session.bus.drive_state(0)["state"] == "Switch on disabled"
    enable_profile_velocity(session)
    sdo_write(session, 0x60FF, 0, struct.pack("<i", 2 * REV))
    session.time_ns += 500_000_000
    session.bus.advance(session.time_ns)
    state = session.bus.drive_state(0)
    assert abs(state["velocity"] - 2 * REV) < 0.01 * REV, state
    assert abs(sdo_read(session, 0x606C) - 2 * REV) < 0.01 * REV
    assert sdo_read(session, 0x6041, 2) & 0x0400, "target reached"


def test_sim_drive_injected_fault_sends_an_emergency_and_resets_on_the_edge(session):
    enable_profile_velocity(session)
    session.bus.inject_fault(0, "F235")
    session.time_ns += 1_000_000
    session.bus.advance(session.time_ns)
    state = session.bus.drive_state(0)
    assert (state["state"], state["fault"], state["fault_number"]) == ("Fault", "over_temperature", 235)
    emergency = session.fp("FPRD", MAILBOX_IN, MAILBOX_SIZE).data
    code, register = struct.unpack_from("<HB", emergency, 8)
    assert (emergency[7] >> 4, code, register, emergency[11:15]) == (1, 0x4310, 0x09, b"F235")
    assert sdo_read(session, 0x603F, 2) == 0x4310
    sdo_write(session, 0x6040, 0, struct.pack("<H", FAULT_RESET))
    assert session.bus.drive_state(0)["state"] == "Switch on disabled"
    with pytest.raises(akd.ConfigError, match=r'no fault named "F1".*sync_lost \(F125\)'):
        session.bus.inject_fault(0, "F1")


def test_sim_drive_hardware_enable_low_keeps_it_from_operation(session):
    session.bus.set_hardware_enable(0, False)
    for controlword in (SHUTDOWN, SWITCH_ON, ENABLE_OPERATION):
        sdo_write(session, 0x6040, 0, struct.pack("<H", controlword))
    assert session.bus.drive_state(0)["state"] == "Switch on disabled"
    assert sdo_read(session, 0x6041, 2) & 0x0080, "warning while hardware enable is low"
    session.bus.set_hardware_enable(0, True)
    enable_profile_velocity(session)


def test_sim_drive_latch_fires_where_the_input_toggles(session):
    toggle = 0.75 * REV + 0.5
    session.bus.set_input_toggles(0, 1, [toggle])
    with pytest.raises(akd.ConfigError, match="inputs 1 to 7"):
        session.bus.set_input_toggles(0, 9, [0.0])
    enable_profile_velocity(session)
    sdo_write(session, 0x20A4, 0, struct.pack("<H", 0x0001))
    sdo_write(session, 0x60FF, 0, struct.pack("<i", REV))
    session.time_ns += 1_500_000_000
    session.bus.advance(session.time_ns)
    status = sdo_read(session, 0x20A5, 2)
    assert status & 0x0001 and status & 0x8000, f"latch 1 rising valid, input 1 high: 0x{status:04X}"
    assert abs(sdo_read(session, 0x20A0) - toggle) <= 1
