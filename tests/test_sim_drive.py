"""The virtual AKD's drive from Python: CiA 402 by SDO, the motor moving, injected faults with
their emergency message and 0x603F, the hardware enable, and a latch firing where a simulated
input toggles. The master-side tests are native/tests/drive_motion.rs."""

from __future__ import annotations

import struct

import pytest
from akd_ros._native import Ds402State

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
    assert session.bus.drive_state(0)["state"] == Ds402State.OPERATION_ENABLED


def test_sim_drive_moves_in_profile_velocity(session):
    assert session.bus.drive_state(0)["state"] == Ds402State.SWITCH_ON_DISABLED
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
    assert (state["state"], state["fault"], state["fault_number"]) == (Ds402State.FAULT, "over_temperature", 235)
    emergency = session.fp("FPRD", MAILBOX_IN, MAILBOX_SIZE).data
    code, register = struct.unpack_from("<HB", emergency, 8)
    assert (emergency[7] >> 4, code, register, emergency[11:15]) == (1, 0x4310, 0x09, b"F235")
    assert sdo_read(session, 0x603F, 2) == 0x4310
    sdo_write(session, 0x6040, 0, struct.pack("<H", FAULT_RESET))
    assert session.bus.drive_state(0)["state"] == Ds402State.SWITCH_ON_DISABLED
    with pytest.raises(akd.ConfigError, match=r'no fault named "F1".*sync_lost \(F125\)'):
        session.bus.inject_fault(0, "F1")


def test_sim_drive_hardware_enable_low_keeps_it_from_operation(session):
    session.bus.set_hardware_enable(0, False)
    for controlword in (SHUTDOWN, SWITCH_ON, ENABLE_OPERATION):
        sdo_write(session, 0x6040, 0, struct.pack("<H", controlword))
    assert session.bus.drive_state(0)["state"] == Ds402State.SWITCH_ON_DISABLED
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


def profile_move(session: VirtualAkdSession, target: int) -> None:
    """Profile position (mode 1): target 0x607A, started by the rising edge of controlword bit 4, then 2 s."""
    sdo_write(session, 0x6060, 0, b"\x01")
    for controlword in (SHUTDOWN, SWITCH_ON, ENABLE_OPERATION):
        sdo_write(session, 0x6040, 0, struct.pack("<H", controlword))
    sdo_write(session, 0x607A, 0, struct.pack("<i", target))
    sdo_write(session, 0x6040, 0, struct.pack("<H", ENABLE_OPERATION | 0x0010))
    session.time_ns += 2_000_000_000
    session.bus.advance(session.time_ns)


def test_sim_drive_ds402_scaling_objects_hold_the_firmwares_defaults(session):
    # AKD EtherCAT manual 2017 §5.3.70-72: 2^20 increments per motor revolution, gear and feed 1/1.
    defaults = {(0x608F, 1): REV, (0x608F, 2): 1, (0x6091, 1): 1, (0x6091, 2): 1, (0x6092, 1): 1, (0x6092, 2): 1}
    for (index, sub), value in defaults.items():
        command, data = session.sdo_upload(index, sub)
        assert (command, int.from_bytes(data[:4], "little")) == (0x43, value), f"0x{index:04X}:{sub:02X}"
    for index in (0x608F, 0x6091, 0x6092):
        assert session.sdo_upload(index, 0)[1][0] == 2
    # Only powers of two for the increments (FB1.PSCALE), and no ratio with a zero in it.
    for index, sub, value in ((0x608F, 1, 1000), (0x6091, 2, 0), (0x6092, 1, 0)):
        assert session.sdo_download(index, sub, struct.pack("<I", value)) == (0x80, 0x06090030)
    # Cyclic synchronous velocity and torque (9, 10) are not the AKD's: 0x6502 has no bit for them.
    assert sdo_read(session, 0x6502) == 0xE5
    for mode in (9, 10):
        assert session.sdo_download(0x6060, 0, bytes([mode])) == (0x80, 0x06090030)


def test_sim_drive_positions_follow_ds402_scaling_only_where_fbus_param05_bit_4_selects_it(session):
    # 3600 position units (0.1°) per driving-shaft revolution, 2 motor revolutions per shaft revolution:
    # 1800 units per motor revolution. FBUS.PARAM05 bit 4 clear: the UNIT parameters' 2^20 counts still.
    sdo_write(session, 0x6092, 1, struct.pack("<I", 3600))
    sdo_write(session, 0x6091, 1, struct.pack("<I", 2))
    profile_move(session, REV // 2)
    assert abs(session.bus.drive_state(0)["position"] - REV // 2) < 200
    assert abs(sdo_read(session, 0x6064) - REV // 2) < 200 and abs(sdo_read(session, 0x6063) - REV // 2) < 200
    sdo_write(session, 0x3E05, 0, struct.pack("<I", 0x10))
    assert abs(sdo_read(session, 0x6064) - 900) <= 1, "half a motor revolution in 0.1° of the shaft"
    # A target in those units: a quarter of a shaft revolution is half a motor revolution on.
    sdo_write(session, 0x6040, 0, struct.pack("<H", ENABLE_OPERATION))
    profile_move(session, 900 + 900)
    assert abs(sdo_read(session, 0x6064) - 1800) <= 1
    # The increments (0x6063, 0x60C1:01) follow 0x608F alone: 2^16 per revolution now.
    sdo_write(session, 0x608F, 1, struct.pack("<I", 1 << 16))
    assert abs(sdo_read(session, 0x6063) - (1 << 16)) <= 2
