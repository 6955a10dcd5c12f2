"""Controlling virtual AKDs while a master drives them: `Master("sim").simulator` while a Cycle
holds the master, and the commands `akd-sim` takes on stdin while a master talks to it over UDP.

Everything runs through the real Master, Cycle and akd-sim process. The waits have deadlines
only so that a failure does not hang; nothing here asserts how fast anything happens.

The virtual AKDs judge missed frames by the frames the line lost (`?missed=lost`): nothing here is about this shared
host's scheduling, so a cycle it runs late must not fault them (F125) as it would a real drive.
"""

from __future__ import annotations

import json
import math
import re
import signal
import struct
import subprocess
import time

import pytest
from akd_ros._native import Ds402State

from akd_ros import _native
from support.netns import console_script, udp_port_bound
from support.waiting import Lines

# 0x1724 outputs: target position 0x607A (i32), controlword (u16), torque offset 0x60B2 (i16).
CSP_OUTPUTS = struct.Struct("<iHh")
# The inputs mapped here: actual position 0x6064 (i32), statusword 0x6041, latch status 0x20A5.
INPUTS = struct.Struct("<iHH")
INPUT_ENTRIES = [[0x60640020, 0x60410010, 0x20A50010]]

STATUSWORD_FAULT = 0x0008
STATUSWORD_WARNING = 0x0080


def inputs(cycle) -> tuple[int, int, int]:
    """(actual position, statusword, latch status) of the last cycle."""
    return INPUTS.unpack(cycle.snapshot()["inputs"][0])


def wait_for(what: str, done, timeout: float = 10.0):
    """Polls `done()` until it gives something true, and returns that."""
    deadline = time.monotonic() + timeout
    while not (result := done()):
        assert time.monotonic() < deadline, what
        time.sleep(0.002)
    return result


@pytest.fixture
def rig():
    """A Master("sim") in Op in cyclic synchronous position (8) with 0x1724 and the inputs
    above, its Simulator, and a Cycle at 1 kHz holding the master."""
    with _native.Master("sim?missed=lost") as master:
        master.scan()
        master.request_state("preop")
        master.configure_pdo(0, 0x1724, INPUT_ENTRIES)
        master.sdo_write(0, 0x6060, 0, bytes([8]))
        master.request_state("op")
        with _native.Cycle(master, 0.001) as cycle:
            yield master, master.simulator, cycle


def enabled(cycle) -> None:
    cycle.enable(0)
    cycle.wait_state(0, Ds402State.OPERATION_ENABLED)


def test_a_fault_injected_while_a_cycle_holds_the_master_shows_in_the_statusword(rig):
    master, _, cycle = rig
    # The Simulator is reachable while the Cycle holds the master, which itself is not.
    simulator = master.simulator
    with pytest.raises(_native.ConfigError, match="handed to a Cycle"):
        master.sdo_read(0, 0x603F, 0)
    enabled(cycle)
    assert simulator.drive_state(0)["fault"] is None
    simulator.inject_fault(0, "F439")
    wait_for("statusword fault bit", lambda: inputs(cycle)[1] & STATUSWORD_FAULT)
    state = simulator.drive_state(0)
    assert (state["state"], state["fault"], state["fault_number"]) == (Ds402State.FAULT, "following_error", 439)
    assert cycle.drive_status(0).state == Ds402State.FAULT
    # The cycle thread took the drive's emergency from its mailbox and made it an event.
    emergency = wait_for(
        "the emergency",
        lambda: [e["fault"] for e in cycle.events() if e["kind"] == "fault" and e["fault"].source == "emergency"],
    )
    assert [f.code for f in emergency] == [0x8611]
    cycle.stop()
    # Back with the master: the drive reports the fault's CiA code.
    assert master.sdo_read(0, 0x603F, 0) == (0x8611).to_bytes(2, "little")


def test_hardware_enable_low_drops_an_enabled_drive_with_a_warning(rig):
    _, simulator, cycle = rig
    enabled(cycle)
    simulator.set_hardware_enable(0, False)
    wait_for("warning bit", lambda: inputs(cycle)[1] & STATUSWORD_WARNING)
    statusword = inputs(cycle)[1]
    assert statusword & 0x004F == 0x0040, f"not Switch on disabled: 0x{statusword:04X}"
    assert simulator.drive_state(0)["state"] == Ds402State.SWITCH_ON_DISABLED
    simulator.set_hardware_enable(0, True)
    wait_for("warning bit gone", lambda: not inputs(cycle)[1] & STATUSWORD_WARNING)
    enabled(cycle)


def test_input_toggles_change_the_latch_status_where_the_drive_is_and_as_it_moves(rig):
    _, simulator, cycle = rig
    # Bits 15, 14, 13, 12 of 0x20A5 are the levels of inputs 1, 2, 3, 4; all low at power-up.
    assert inputs(cycle)[2] & 0xF000 == 0
    # Input 1 toggling below where the drive stands is high there.
    simulator.set_input_toggles(0, 1, [-1000.0])
    wait_for("input 1 high", lambda: inputs(cycle)[2] & 0x8000)
    # Input 2 toggles ahead of the drive: low until the drive moves past it.
    simulator.set_input_toggles(0, 2, [150_000.0])
    enabled(cycle)
    assert inputs(cycle)[2] & 0x4000 == 0
    cycle.set_outputs(0, CSP_OUTPUTS.pack(300_000, 0, 0))
    wait_for("the drive past 150000", lambda: inputs(cycle)[0] > 160_000)
    assert inputs(cycle)[2] & 0xC000 == 0xC000
    assert simulator.drive_state(0)["position"] > 150_000.0


def test_bad_values_are_refused_naming_the_allowed_ones():
    with _native.Master("sim:2?missed=lost") as master:
        simulator = master.simulator
        assert len(simulator) == 2
        with pytest.raises(_native.ConfigError, match=r"no fault named \"F1\".*following_error \(F439\)"):
            simulator.inject_fault(0, "F1")
        with pytest.raises(_native.ConfigError, match="no slave at position 2: the bus has 2 slave"):
            simulator.set_hardware_enable(2, False)
        with pytest.raises(_native.ConfigError, match="digital input 8: the AKD has inputs 1 to 7"):
            simulator.set_input_toggles(0, 8, [1.0])
        with pytest.raises(_native.ConfigError, match="toggle position NaN of digital input 1 is not a finite"):
            simulator.set_input_toggles(1, 1, [0.0, math.nan])
        with pytest.raises(_native.ConfigError, match="digital input 0: the AKD has inputs 1 to 7"):
            simulator.set_input(0, 0, True)
        with pytest.raises(_native.ConfigError, match='switch "brake" is not one of negative_limit, positive_limit'):
            simulator.set_switch(0, "brake", True)
        with pytest.raises(_native.ConfigError, match=r"analog input inf V: allowed a finite voltage within ±10"):
            simulator.set_analog_input(1, math.inf)
        with pytest.raises(_native.ConfigError, match="timeout -1 s: allowed a finite number of seconds >= 0"):
            simulator.drive_state(0, timeout=-1)
        # Nobody exchanges frames: the query says so instead of waiting for ever.
        with pytest.raises(_native.ConfigError, match=r"not answered within 50ms.*idle in-process master"):
            simulator.drive_state(0, timeout=0.05)
    with pytest.raises(_native.ConfigError, match="virtual AKDs are gone"):
        simulator.inject_fault(0, "F439")
    with pytest.raises(_native.ConfigError, match='in-process links "sim" and "sim:N" only'):
        _ = _native.Master("udp://127.0.0.1:9").simulator


def test_akd_sim_takes_commands_on_stdin_while_a_master_talks_to_it(udp_port):
    argv = [*console_script("akd-sim"), "--udp", f"127.0.0.1:{udp_port}"]
    sim = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        lines = Lines(sim.stdout)
        assert lines.next() == f"akd-sim: starting 1 virtual AKD on udp 127.0.0.1:{udp_port}"
        wait_for("akd-sim bound", lambda: udp_port_bound(udp_port) or sim.poll() is not None)

        def command(line: str) -> str:
            sim.stdin.write(line + "\n")
            sim.stdin.flush()
            return lines.next()

        assert command("fault 0 F125") == "ok fault 0 F125"
        # A master on UDP: its frames run the drive's firmware, which raises the fault.
        with _native.Master(f"udp://127.0.0.1:{udp_port}") as master:
            assert len(master.scan()) == 1
            master.request_state("preop")
            assert master.sdo_read(0, 0x603F, 0) == (0x8700).to_bytes(2, "little")
        reply = command("state 0")
        assert reply.startswith("ok {")
        state = json.loads(reply[3:])
        assert (state["state"], state["fault"], state["fault_number"]) == ("Fault", "sync_lost", 125)
        assert command("hardware_enable 0 low") == "ok hardware_enable 0 low"
        assert command("toggles 0 1 -100,250.5") == "ok toggles 0 1 -100,250.5"
        assert command("input 0 3 high") == "ok input 0 3 high"
        assert command("switch 0 negative_limit on") == "ok switch 0 negative_limit on"
        assert command("analog_input 0 -2.5") == "ok analog_input 0 -2.5"
        assert command("help").startswith("ok commands: fault POSITION NAME | hardware_enable")
        for bad, named in (
            ("fault 0 F1", "following_error (F439)"),
            ("fault 1 F439", "no slave at position 1: the bus has 1 slave"),
            ("hardware_enable 0 maybe", "high or low"),
            ("toggles 0 8 1", "inputs 1 to 7"),
            ("toggles 0 1 1,x", "counts separated by commas"),
            ("input 0 8 high", "inputs 1 to 7"),
            ("input 0 1 up", "high or low"),
            ("switch 0 limit on", 'switch "limit" is not one of negative_limit, positive_limit, home_switch'),
            ("switch 0 home_switch yes", "on or off"),
            ("analog_input 0 12", "allowed a finite voltage within ±10.0000 V"),
            ("analog_input 0 nan", "allowed a finite voltage"),
            ("analog_input 0 volts", "a voltage such as 2.5"),
            ("state x", "POSITION must be a whole number 0..0"),
            ("state", "usage: state POSITION"),
            (
                "jog 0",
                "allowed are fault, hardware_enable, toggles, input, switch, analog_input, state, power_cycle, homing, "
                "cable, link, crc, counters, drop, corrupt, wrong_wkc, help",
            ),
        ):
            reply = command(bad)
            assert reply.startswith("error: ") and named in reply, (bad, reply)
        # The end of stdin ends the commands, not the simulator.
        sim.stdin.close()
        with _native.Master(f"udp://127.0.0.1:{udp_port}") as master:
            assert len(master.scan()) == 1
        assert sim.poll() is None
        sim.send_signal(signal.SIGTERM)
        assert sim.wait(timeout=10) == 0, sim.stderr.read()
        # What it served, over UDP without the lateness of its replies, which only an interface stamps.
        served = r"akd-sim: served \d+ frames \(0 malformed, 0 lost on the line, 0 unsent\)"
        serving = r"; its own serving of a frame took (\d+ over [\d.]+ ms, ){5}slowest [\d.]+ ms"
        assert re.fullmatch(served + serving, lines.next())
        assert lines.next() == "akd-sim: stopped"
    finally:
        if sim.poll() is None:
            sim.kill()
            sim.wait()
