"""The line's links and error counters through the Python side: akd-sim's stdin commands (`crc`, `link`, `counters`),
`akd-scan --line` at rest on akd-sim, `Bus.line_health()` while the cycle runs, and `Master.line_health()`; each
against the virtual ESCs, whose own counts (`Simulator.esc_state`, akd-sim's `counters`) are what the master's must
equal. The waits have deadlines only so that a failure does not hang; nothing asserts how fast anything happens.
"""

from __future__ import annotations

import json
import signal
import subprocess
import time

import pytest

from akd_ros import DriveConfig, _native
from akd_ros.bus import Bus
from support.netns import console_script, udp_port_bound
from support.waiting import Lines
from test_sim_control import wait_for


def _answered(call) -> bool:
    """Whether `call()` got its answer (a frame lost on the line is an error the caller goes past)."""
    try:
        call()
    except (_native.TimeoutError, _native.WorkingCounterError):
        return False
    return True


@pytest.fixture
def akd_sim(udp_port):
    """akd-sim serving six AKDs on UDP, and a function sending it one command line and giving its answer."""
    argv = [*console_script("akd-sim"), "--udp", f"127.0.0.1:{udp_port}", "--count", "6", "--missed", "lost"]
    sim = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines = Lines(sim.stdout)
    assert lines.next().startswith("akd-sim: starting 6 virtual AKDs")
    wait_for("akd-sim bound", lambda: udp_port_bound(udp_port) or sim.poll() is not None)

    def command(line: str) -> str:
        sim.stdin.write(line + "\n")
        sim.stdin.flush()
        return lines.next()

    try:
        yield udp_port, command
    finally:
        sim.send_signal(signal.SIGTERM)
        sim.wait(timeout=10)


def test_akd_sim_takes_faulty_cables_and_links_and_counts_as_escs_do(akd_sim):
    port, command = akd_sim
    clean = json.loads(command("counters 3")[3:])
    assert [(p["port"], p["kind"], p["link"], p["loop_closed"]) for p in clean["ports"]] == [
        (0, "MII", True, False),
        (1, "MII", True, False),
    ]
    assert clean["dl_status"] == 0x5A33
    assert command("crc 3 1 5") == "ok crc 3 1 5"
    assert command("crc 2 0 3 2") == "ok crc 2 0 3 2"
    assert json.loads(command("counters 3")[3:])["ports"][1]["spoiling"] == 5
    # Frames on the line until the faults spoiled all they were to (a frame lost is the master's error).
    with _native.Master(f"udp://127.0.0.1:{port}", timeout=0.05) as master:
        wait_for("a scan", lambda: _answered(master.scan))
        for _ in range(40):
            _answered(lambda: master.read_register(0, 0x0130, 2))
    assert json.loads(command("counters 3")[3:])["ports"][1]["spoiling"] == 0
    assert json.loads(command("counters 2")[3:])["ports"][0]["spoiling"] == 0
    result = subprocess.run(
        [*console_script("akd-scan"), f"udp://127.0.0.1:{port}", "--line"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    # The most errors first: 5 entering slave 3's port 1, from slave 4; then 3 entering slave 2's port 0.
    assert lines[6] == (
        "line: errors on the cable into slave 3 (AKD) port 1, from slave 4 (AKD) port 0: 5 since power-up or the "
        "last clear"
    ), result.stdout
    # Slave 3's port 1 also forwarded the frames spoiled in front of slave 2, on their way back.
    assert (
        "slave 3 (AKD) port 1 (MII): link, open, to slave 4 (AKD) port 0; 5 invalid frames, 3 forwarded errors" in lines
    )
    assert "slave 0 (AKD) port 1 (MII): link, open, to slave 1 (AKD) port 0; 8 forwarded errors" in lines
    assert "slave 2 (AKD) port 0 (MII): link, open, to slave 1 (AKD) port 1; 3 invalid frames" in lines
    assert "slave 5 (AKD) port 1 (MII): no link; no errors" in lines
    counted = json.loads(command("counters 3")[3:])
    assert counted["ports"][1]["counted"]["invalid_frames"] == 5
    # akd-scan reads without clearing: the registers hold what was counted.
    assert counted["ports"][1]["registers"] == counted["ports"][1]["counted"]
    assert command("link 3 1 down") == "ok link 3 1 down"
    assert json.loads(command("counters 3")[3:])["ports"][1]["link"] is False
    assert command("link 3 1 up") == "ok link 3 1 up"
    after = json.loads(command("counters 4")[3:])
    assert (after["ports"][0]["link"], after["ports"][0]["counted"]["lost_links"]) == (True, 1)
    for bad, named in (
        ("crc 5 1 10", "no cable at port 1 of the akd at position 5: it is the last slave of the line"),
        ("crc 0 2 10", "port 2: the akd at position 0 has ports 0, 1"),
        ("crc 0 0 10 0", "one frame in every 0: allowed are 1 (each frame) or more"),
        ("crc 0 0 x", "COUNT must be a whole number 0 or more"),
        ("crc 0 0", "usage: crc POSITION PORT COUNT [EVERY]"),
        ("link 0 1 sideways", "link takes down or up"),
        ("link 6 0 down", "no slave at position 6: the bus has 6 slave"),
        ("counters 9", "no slave at position 9: the bus has 6 slave"),
    ):
        reply = command(bad)
        assert reply.startswith("error: ") and named in reply, (bad, reply)
    assert "crc POSITION PORT COUNT [EVERY]" in command("help")


def test_a_bus_reads_its_line_while_it_cycles_and_names_its_drives():
    with Bus("sim:6?missed=lost", [DriveConfig(slave=p, name=f"joint_{p + 1}") for p in range(6)]) as bus:
        line = wait_for("a read of the line", lambda: (h := bus.line_health())["reads"] > 1 and h)
        assert line["summary"].startswith("no errors on the line in the last")
        assert line["interval_s"] == pytest.approx(0.25)
        assert [p["peer"] for p in line["slaves"][4]["ports"]] == [
            "slave 3 (joint_4) port 1",
            "slave 5 (joint_6) port 0",
        ]
        bus.simulator.crc_errors(4, 0, 10, 5)
        named = wait_for("the cable named", lambda: (h := bus.line_health())["findings"] and h)
        assert named["findings"][0]["text"].startswith(
            "errors on the cable into slave 4 (joint_5) port 0, from slave 3 (joint_4) port 1: "
        ), named["findings"]
        assert (named["findings"][0]["slave"], named["findings"][0]["port"]) == (4, 0)
        wait_for("the fault's end", lambda: bus.simulator.esc_state(4)["ports"][0]["spoiling"] == 0)
        reads = bus.line_health()["reads"]
        done = wait_for("a read after it", lambda: (h := bus.line_health())["reads"] > reads + 1 and h)
        for slave in range(6):
            esc = bus.simulator.esc_state(slave)
            for port, counted in zip(done["slaves"][slave]["ports"], esc["ports"], strict=True):
                assert port["total"] == counted["counted"], (slave, port)
        statuses = bus.line_diagnostics()
        assert [s[1] for s in statuses] == ["line", *(f"line slave {n}" for n in range(6))]
        assert statuses[0][3] == "EtherCAT line sim:6?missed=lost"


def test_a_cycle_reads_its_line_only_when_asked_to():
    with _native.Master("sim:2") as master:
        master.scan()
        master.request_state("preop")
        for position in range(2):
            master.configure_pdo(position, 0x1724, [[0x60640020, 0x60410010]])
        master.request_state("op")
        at_rest = master.line_health({0: "first"})
        assert at_rest["interval_s"] is None and at_rest["slaves"][0]["name"] == "first"
        with _native.Cycle(master, 0.001, line_health=0) as cycle:
            time.sleep(0.3)
            unread = cycle.line_health()
            assert (unread["reads"], unread["frames"]) == (0, 0)
            assert cycle.line_diagnostics("sim:2")[0][2] == "the line's links and error counters are not read"
        with pytest.raises(_native.ConfigError, match="line health interval"):
            _native.Cycle(master, 0.001, line_health=-1)
