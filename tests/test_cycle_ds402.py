"""The DS402 sequencer in the cycle thread (Cycle.enable/disable/quick_stop/reset_fault)
against the in-process virtual AKD, through the real Master and Cycle.

The waits have deadlines only so that a broken sequencer fails instead of hanging; nothing
here asserts how fast anything happens. Hardware enable low cannot be set on a Master("sim")'s
own bus from Python: native/tests/cycle_ds402.rs covers it.

The virtual AKDs judge missed frames by the frames the line lost (`?missed=lost`): nothing here is about this shared
host's scheduling, so a cycle it runs late must not fault them (F125) as it would a real drive.
"""

from __future__ import annotations

import struct
import time

import pytest
from akd_ros._native import DriveRequest, Ds402State, RequestProgress

from akd_ros import _native

# 0x1724 outputs: target position 0x607A (i32), controlword (u16), torque offset 0x60B2 (i16).
CSP_OUTPUTS = struct.Struct("<iHh")
# 0x1B24 inputs: actual position 0x6064 (i32), statusword (u16).
CSP_INPUTS = struct.Struct("<iH")


def master_with(rx: int, tx: int, mode: int):
    m = _native.Master("sim?missed=lost")
    m.scan()
    m.request_state("preop")
    m.configure_pdo(0, rx, tx)
    m.sdo_write(0, 0x6060, 0, bytes([mode]))
    m.request_state("op")
    return m


@pytest.fixture
def csp():
    """A drive in cyclic synchronous position (8) with 0x1724/0x1B24, cycling at 1 kHz."""
    with master_with(0x1724, 0x1B24, 8) as m, _native.Cycle(m, 0.001) as cycle:
        yield cycle


def actual(cycle) -> int:
    return CSP_INPUTS.unpack(cycle.snapshot()["inputs"][0])[0]


def after_cycles(cycle, count: int) -> dict:
    """The snapshot `count` cycles from now."""
    start = cycle.snapshot()["cycle"]
    deadline = time.monotonic() + 30
    while (snapshot := cycle.snapshot())["cycle"] < start + count:
        assert time.monotonic() < deadline, "the cycle stopped"
        time.sleep(0.002)
    return snapshot


def settled(cycle) -> int:
    """The actual position once it stays the same for 20 cycles."""
    deadline = time.monotonic() + 10
    position = actual(cycle)
    while True:
        later = CSP_INPUTS.unpack(after_cycles(cycle, 20)["inputs"][0])[0]
        if later == position:
            return position
        assert time.monotonic() < deadline, f"the axis keeps moving ({position} -> {later})"
        position = later


def move_to(cycle, target: int) -> None:
    cycle.set_outputs(0, CSP_OUTPUTS.pack(target, 0, 0))
    deadline = time.monotonic() + 10
    while abs(actual(cycle) - target) > 100:
        assert time.monotonic() < deadline, f"the axis stays at {actual(cycle)}, target {target}"
        time.sleep(0.005)


def test_sequencer_leaves_the_drive_alone_until_asked(csp):
    after_cycles(csp, 5)
    status = csp.drive_status(0)
    assert status.state == Ds402State.SWITCH_ON_DISABLED
    assert (status.request, status.progress, status.reason) == (None, RequestProgress.IDLE, None)
    with pytest.raises(_native.EtherCatError, match="no slave at position 3"):
        csp.enable(3)


def test_enable_is_bumpless_and_set_points_after_it_move_the_axis(csp):
    before = settled(csp)
    csp.enable(0)
    csp.wait_state(0, Ds402State.OPERATION_ENABLED)
    status = csp.drive_status(0)
    assert (status.request, status.progress) == (DriveRequest.ENABLE, RequestProgress.DONE)
    assert abs(actual(csp) - before) <= 1
    move_to(csp, 300_000)
    csp.disable(0)
    csp.wait_state(0, Ds402State.SWITCH_ON_DISABLED)
    # A stale set-point written while disabled is not taken at the next enable: with the axis
    # away from 0, taking it would move the axis back to 0.
    csp.set_outputs(0, CSP_OUTPUTS.pack(0, 0, 0))
    here = settled(csp)
    assert abs(here) > 200_000
    csp.enable(0)
    csp.wait_state(0, Ds402State.OPERATION_ENABLED)
    snapshot = after_cycles(csp, 50)
    assert abs(actual(csp) - here) <= 1
    # What went out: the target the cycle thread holds is where the axis is, with Enable
    # operation, although the set-point written is 0.
    assert CSP_OUTPUTS.unpack(csp.outputs(0))[:2] == (0, 0)
    target, controlword, _ = CSP_OUTPUTS.unpack(snapshot["outputs"][0])
    assert (abs(target - here) <= 1, controlword) == (True, 0x000F)
    # A set-point written after enable passes through.
    move_to(csp, here + 100_000)


def test_disable_and_quick_stop(csp):
    csp.enable(0)
    csp.wait_state(0, Ds402State.OPERATION_ENABLED)
    csp.quick_stop(0)
    csp.wait_state(0, Ds402State.QUICK_STOP_ACTIVE)
    assert csp.drive_status(0).progress == RequestProgress.DONE
    csp.disable(0)
    csp.wait_state(0, Ds402State.SWITCH_ON_DISABLED)
    status = csp.drive_status(0)
    assert (status.request, status.progress) == (DriveRequest.DISABLE, RequestProgress.DONE)
    # The controlword that goes out is Disable voltage.
    assert CSP_OUTPUTS.unpack(after_cycles(csp, 1)["outputs"][0])[1] == 0


def test_fault_is_not_retried_and_reset_fault_clears_it_by_the_rising_edge():
    # Mode 8 with the interpolation mapping 0x1701: the drive gets no 0x607A set-points and
    # raises F706 (cyclic set-points missing) once enabled.
    with master_with(0x1701, 0x1B01, 8) as m, _native.Cycle(m, 0.001) as cycle:
        cycle.request_timeout = 0.2
        cycle.enable(0)
        cycle.wait_state(0, Ds402State.FAULT)
        status = cycle.drive_status(0)
        assert (status.request, status.progress) == (DriveRequest.ENABLE, RequestProgress.LOST)
        assert "fault (bit 3)" in status.reason
        # The sequencer does not reset it by itself: the drive stays in Fault.
        after_cycles(cycle, 50)
        assert cycle.drive_status(0).state == Ds402State.FAULT
        # Enable does not reset a fault either: it is stuck, and says why.
        cycle.enable(0)
        with pytest.raises(_native.TimeoutError, match=r"enable stuck in Fault .*fault \(bit 3\)"):
            cycle.wait_state(0, Ds402State.OPERATION_ENABLED)
        cycle.reset_fault(0)
        cycle.wait_state(0, Ds402State.SWITCH_ON_DISABLED)
        status = cycle.drive_status(0)
        assert (status.request, status.progress, status.reason) == (
            DriveRequest.FAULT_RESET,
            RequestProgress.DONE,
            None,
        )
        # Out of Fault, bit 7 is low again (ready for the next edge), the power stage stays off.
        assert struct.unpack("<iH", after_cycles(cycle, 1)["outputs"][0])[1] == 0


def test_a_drive_without_controlword_is_refused_naming_what_is_missing():
    with _native.Master("sim?missed=lost") as m:
        m.scan()
        m.request_state("preop")
        m.configure_pdo(0, [[0x607A0020]], [[0x60410010, 0x60640020]])
        m.request_state("op")
        with _native.Cycle(m, 0.001) as cycle:
            with pytest.raises(_native.EtherCatError, match="lacks controlword 0x6040"):
                cycle.enable(0)
            with pytest.raises(_native.EtherCatError, match="lacks controlword 0x6040"):
                cycle.drive_status(0)


def test_wait_state_takes_the_crates_states_not_names(csp):
    with pytest.raises(TypeError, match="Ds402State"):
        csp.wait_state(0, "Operation enabled")


def test_set_point_handshake_and_command_timeout_refuse_what_cannot_work(csp):
    with pytest.raises(_native.ConfigError, match="no set-point handshake was asked for"):
        csp.wait_setpoint(0)
    with pytest.raises(_native.ConfigError, match=r"bits 0x0100: allowed are bit 4 \(0x0010"):
        csp.start_setpoint(0, 0x0100)
    # Cyclic synchronous position shows statusword bit 12 all along: a handshake never starts.
    csp.enable(0)
    csp.wait_state(0, Ds402State.OPERATION_ENABLED)
    csp.request_timeout = 0.1
    assert csp.start_setpoint(0, 0x0030) == 1
    with pytest.raises(_native.TimeoutError, match=r"stuck in Operation enabled .*bit 12 stayed set"):
        csp.wait_setpoint(0)
    status = csp.setpoint_status(0)
    assert (status["request"], status["bits"], status["progress"]) == (1, 0x30, "stuck")
    assert "bit 12 stayed set" in status["reason"]
    with pytest.raises(_native.ConfigError, match="lacks target velocity 0x60FF or target torque 0x6071"):
        csp.set_command_timeout(0, 1.0, "hold")
    with pytest.raises(_native.ConfigError, match='policy "halt": allowed "hold" or "quick_stop"'):
        csp.set_command_timeout(0, 1.0, "halt")
