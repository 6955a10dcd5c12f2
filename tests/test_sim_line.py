"""`akd-sim --line`: a virtual line of Beckhoff terminals and AKDs, and the stdin commands that reach its terminals.

akd-sim serves the line over UDP; no master talks to it here (tests/test_soem_line.py drives one to Op with SOEM):
the commands and their answers are what is judged, and a terminal's inputs pass its filter on akd-sim's own time,
which runs between frames too. The waits have deadlines only so that a failure does not hang.
"""

from __future__ import annotations

import json
import signal
import subprocess
import time

import pytest

from akd_ros import _native
from support.netns import console_script, udp_port_bound
from support.waiting import Lines

LINE = "ek1100,el1004,el2004,el3102,akd"


@pytest.fixture
def sim(udp_port):
    """akd-sim serving LINE on UDP, and a function that sends it a command and gives its answer."""
    argv = [*console_script("akd-sim"), "--udp", f"127.0.0.1:{udp_port}", "--line", LINE]
    process = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        lines = Lines(process.stdout)
        assert lines.next() == f"akd-sim: starting line {LINE} on udp 127.0.0.1:{udp_port}"
        # Said once its socket is bound: a docs page's next command, started on this line, finds it there.
        assert udp_port_bound(udp_port)

        def command(line: str) -> str:
            process.stdin.write(line + "\n")
            process.stdin.flush()
            return lines.next()

        yield command
        process.send_signal(signal.SIGTERM)
        assert process.wait(timeout=10) == 0, process.stderr.read()
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


def state(command, position: int) -> dict:
    reply = command(f"state {position}")
    assert reply.startswith("ok {"), reply
    return json.loads(reply[3:])


def wait_for_inputs(command, position: int, levels: list[bool]) -> None:
    deadline = time.monotonic() + 10
    while (inputs := state(command, position)["inputs"]) != levels:
        assert time.monotonic() < deadline, inputs
        time.sleep(0.01)


def test_akd_sim_line_commands_reach_the_terminals(sim):
    assert state(sim, 0) == {
        "product": "ek1100",
        "al_state": "Init",
        "al_status": 1,
        "inputs": [],
        "outputs": [],
        "analog_inputs": [],
        "watchdog_expired": False,
    }
    assert state(sim, 1)["inputs"] == [False] * 4
    assert state(sim, 2)["outputs"] == [False] * 4
    # An input at the EL1004's connector reaches what a master reads once its 3 ms filter let it through, on
    # akd-sim's time, which runs between frames too.
    assert sim("input 1 2 high") == "ok input 1 2 high"
    wait_for_inputs(sim, 1, [False, True, False, False])
    assert sim("analog_input 3 2 -5.5") == "ok analog_input 3 2 -5.5"
    assert sim("analog_input 3 2.25") == "ok analog_input 3 2.25"
    assert state(sim, 3)["analog_inputs"] == [2.25, -5.5]
    # The AKD at the end answers as ever.
    drive = state(sim, 4)
    assert drive["fault"] is None and drive["dc"]["sync0_active"] is False
    assert sim("input 4 7 high") == "ok input 4 7 high"
    # Power and cables are any slave's.
    assert sim("power_cycle 1") == "ok power_cycle 1"
    assert state(sim, 1)["al_state"] == "Init"
    # The connector's level stays through a power cycle, and passes the filter again.
    wait_for_inputs(sim, 1, [False, True, False, False])
    assert sim("cable 2 pulled") == "ok cable 2 pulled"
    assert sim("cable 2 plugged") == "ok cable 2 plugged"


@pytest.mark.parametrize(
    ("line", "named"),
    [
        ("fault 1 F439", "a fault needs an AKD: the slave at position 1 is an el1004"),
        ("hardware_enable 0 low", "the hardware enable needs an AKD: the slave at position 0 is an ek1100"),
        ("homing 2 ok", "homing needs an AKD: the slave at position 2 is an el2004"),
        ("toggles 1 1 100", "input toggles needs an AKD: the slave at position 1 is an el1004"),
        ("input 1 5 high", "digital input 5: the el1004 at position 1 has digital inputs 1 to 4"),
        ("input 2 1 high", "digital input 1: the el2004 at position 2 has no digital inputs"),
        ("input 0 1 high", "digital input 1: the ek1100 at position 0 has no digital inputs"),
        ("analog_input 3 3 1", "analog input 3: the el3102 at position 3 has analog inputs 1 to 2"),
        ("analog_input 3 1 10.5", "analog input of 10.5 V: allowed are -10 to 10 V"),
        ("analog_input 1 1", "analog input 1: the el1004 at position 1 has no analog inputs"),
        ("analog_input 4 2 1", "analog input 2: the akd at position 4 has analog inputs 1 to 1"),
        ("state 5", "no slave at position 5: the bus has 5 slave(s)"),
        ("input 5 1 high", "no slave at position 5: the bus has 5 slave(s)"),
    ],
)
def test_akd_sim_line_refuses_what_a_slave_does_not_take_in_one_line(sim, line, named):
    reply = sim(line)
    assert reply.startswith("error: ") and named in reply, (line, reply)


@pytest.mark.parametrize(
    ("line", "named"),
    [
        ("ek1100,el9999,akd", 'the slave at position 1, "el9999", is no product the simulator makes: allowed are akd'),
        ("el1004,akd", "the slave at position 0, el1004, is an E-bus terminal: an ek1100 or another terminal"),
        ("ek1100,,akd", 'the slave at position 1, "", is no product'),
    ],
)
def test_akd_sim_refuses_a_bad_line_in_one_line(udp_port, line, named):
    argv = [*console_script("akd-sim"), "--udp", f"127.0.0.1:{udp_port}", "--line", line]
    result = subprocess.run(argv, capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode != 0
    # One line (after the warning a root user gets, where the suite runs as root).
    errors = [line for line in result.stderr.splitlines() if not line.startswith("akd-sim: warning: running as root")]
    assert len(errors) == 1 and errors[0].startswith(f'akd-sim: error: configuration: line "{line}": '), errors
    assert named in errors[0] and "starting" not in result.stdout


def test_akd_sim_takes_a_line_or_a_count_not_both(udp_port):
    argv = [*console_script("akd-sim"), "--udp", f"127.0.0.1:{udp_port}", "--line", "akd", "--count", "2"]
    result = subprocess.run(argv, capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 2 and "not allowed with argument" in result.stderr, result.stderr


def test_a_virtual_bus_of_a_line_names_its_slaves_and_their_images():
    bus = _native.VirtualBus(line="ek1100,el1008,el2008,akd", immediate=True)
    assert bus.products == ["ek1100", "el1008", "el2008", "akd"] and len(bus) == 4
    assert list(_native.SIM_PRODUCTS) == ["akd", "ek1100", "el1004", "el1008", "el2004", "el2008", "el3102"]
    el1008 = _native.parse_sii(_native.sim_sii_image("el1008"))
    assert (el1008["order"], el1008["product_code"]) == ("EL1008", 0x03F03052)
    assert [e["index"] for p in el1008["tx_pdos"] for e in p["entries"]] == [0x6000 + 0x10 * n for n in range(8)]
    el2008 = _native.parse_sii(_native.sim_sii_image("el2008"))
    assert [e["index"] for p in el2008["rx_pdos"] for e in p["entries"]] == [0x7000 + 0x10 * n for n in range(8)]
    assert bus.terminal_state(1)["inputs"] == [False] * 8
    with pytest.raises(_native.ConfigError, match="a drive state needs an AKD: the slave at position 2 is an el2008"):
        bus.drive_state(2)
    with pytest.raises(_native.ConfigError, match="a terminal state needs a terminal: the slave at position 3 is an"):
        bus.terminal_state(3)
    with pytest.raises(_native.ConfigError, match='"el9", is no product the simulator makes: allowed are akd, ek1100'):
        _native.sim_sii_image("el9")
