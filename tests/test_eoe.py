"""Ethernet over EtherCAT as a user runs it: akd-eoe sets the virtual drives' addresses, bridges them to a TAP
interface, and `ping` through it gets replies from the drives' addresses, large pings fragmented in EoE both ways,
with no lost process-data frame and no working-counter error meanwhile. akd-sim serves the drives in a network
namespace of its own over a veth pair; akd-eoe, its TAP interface and ping run in the other one. The addresses are
from the documentation range (192.0.2.0/24) and exist only inside the test's namespace."""

from __future__ import annotations

import json
import os
import re
import socket
import struct
import subprocess
import threading
import time
from pathlib import Path

import pytest
import yaml

import akd_ros
from akd_ros import params
from akd_ros.cli.common import EXIT_INTERRUPTED
from support.netns import (
    akd_sim_in_netns,
    console_script,
    netns_argv,
    run_in_netns,
    run_python_in_netns,
    stop_process,
)
from support.ros import node_command

DRIVES = ("192.0.2.10", "192.0.2.11")
HOST = "192.0.2.1/24"
SUMMARY = re.compile(
    r"akd-eoe: (?P<cycles>\d+) cycles, (?P<lost>\d+) lost frames, (?P<wkc>\d+) WKC errors; "
    r"frames to the drives (?P<to>\d+), from them (?P<from>\d+), dropped (?P<dropped_to>\d+) and (?P<dropped_from>\d+)"
)

# akd-sim's count of replies it sent more than 2 ms late because it was not run (see akd_ros.cli.sim).
LATE_HALF_PERIOD = re.compile(r"replies late because akd-sim was not run: .*?(?P<count>\d+) over 2 ms")


def _late_by_half_a_period(sim: subprocess.Popen) -> int:
    """The replies akd-sim, stopped, says it sent more than half the 4 ms period late because it was not run: the
    frames a master on this shared machine may lose through no fault of its own or of EoE (a virtual CPU its host
    held for milliseconds; a real drive's ESC answers in hardware)."""
    late = LATE_HALF_PERIOD.search(sim.output_text)
    assert late, sim.output_text
    print(sim.output_text)
    return int(late["count"])


def _ready_lines(process: subprocess.Popen, count: int, timeout: float) -> list[str]:
    """The first `count` lines akd-eoe prints once its bridge is up; fails with its stderr otherwise."""
    lines: list[str] = []

    def read() -> None:
        while len(lines) < count and (line := process.stdout.readline()):
            lines.append(line.strip())

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    reader.join(timeout)
    if len(lines) < count:
        _, err = stop_process(process)
        raise AssertionError(f"akd-eoe did not come up within {timeout} s: {err.strip()}")
    return lines


def _received(ping: subprocess.CompletedProcess) -> int:
    match = re.search(r"(\d+) received", ping.stdout)
    assert match, ping.stdout + ping.stderr
    return int(match[1])


def _ping_each_drive(ns: str, small: int, large: int) -> None:
    """`small` pings and `large` ones of 1400 bytes of data (a 1442-byte frame, two EoE fragments each way in the
    AKD's 1 KiB mailbox) to each drive from namespace `ns`, every one answered."""
    for ip in DRIVES:
        done = run_in_netns(ns, ["ping", "-c", str(small), "-i", "0.2", "-W", "2", ip], timeout=30)
        assert _received(done) == small, done.stdout
        done = run_in_netns(ns, ["ping", "-c", str(large), "-i", "0.3", "-s", "1400", "-W", "2", ip], timeout=30)
        assert _received(done) == large, done.stdout
        assert "1408 bytes from " + ip in done.stdout, done.stdout


def test_ping_through_the_tap_reaches_each_drive_with_no_cycle_lost(veth):
    # The virtual AKDs on the cycle thread's CPU: they answer a frame as soon as the thread waits for it, as the ESC
    # does in hardware, whatever runs on the other CPUs (on a shared host a thread woken on one of them may wait there
    # for milliseconds).
    cpu = max(os.sched_getaffinity(0))
    with akd_sim_in_netns(veth.ns_sim, veth.if_sim, count=2, cpu=cpu) as sim:
        argv = [*console_script("akd-eoe"), veth.if_master, "--host", HOST, "--tap", "akdeoe0", "--period", "0.004"]
        # As an integrator runs a line on an interface: the cycle thread under SCHED_FIFO, where permitted.
        argv += ["--priority", "50", "--cpu", str(cpu)]
        for ip in DRIVES:
            argv += ["--ip", f"{ip}/24"]
        process = subprocess.Popen(
            netns_argv(veth.ns_master, argv), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        try:
            lines = _ready_lines(process, 2, timeout=30)
            assert lines[0] == "akd-eoe: drive 0 at 192.0.2.10 (MAC 02:01:05:30:10:01) through akdeoe0", lines
            assert lines[1].startswith("akd-eoe: drive 1 at 192.0.2.11 (MAC 02:01:05:30:10:02)"), lines
            _ping_each_drive(veth.ns_master, small=5, large=3)
            # An address no drive has is not answered.
            nobody = run_in_netns(veth.ns_master, ["ping", "-c", "2", "-i", "0.2", "-W", "1", "192.0.2.99"], timeout=30)
            assert _received(nobody) == 0
        finally:
            out, err = stop_process(process)
    summary = SUMMARY.search(out)
    assert summary, out + err
    print(summary[0])
    # SIGTERM ends the tool as SIGINT does: the summary, then status 130.
    assert process.returncode == EXIT_INTERRUPTED, err
    # The EoE traffic costs no cycle: a frame is lost only where akd-sim itself was late.
    assert int(summary["lost"]) <= _late_by_half_a_period(sim), summary[0]
    assert int(summary["wkc"]) == 0, summary[0]
    assert (int(summary["dropped_to"]), int(summary["dropped_from"])) == (0, 0), summary[0]
    # 16 pings answered and the ARP exchanges: frames went both ways.
    assert int(summary["from"]) >= 16 and int(summary["to"]) >= 16, summary[0]


def test_set_ip_is_answered_and_the_drive_announces_itself():
    master = akd_ros.Master("sim")
    try:
        master.scan()
        master.request_state("preop")
        mac = master.eoe_set_ip(0, "192.0.2.10", subnet_mask="255.255.255.0", dns_name="Drive_1__AKD_")
        assert mac == "02:01:05:30:10:01"
        announcement = master.eoe_receive(0, 1.0)
        assert announcement is not None
        # A broadcast ARP request from the drive's MAC for its own address.
        assert announcement[:6] == b"\xff" * 6 and announcement[6:12] == bytes.fromhex("020105301001")
        assert announcement[12:14] == b"\x08\x06" and announcement[28:32] == announcement[38:42] == bytes(
            [192, 0, 2, 10]
        )
    finally:
        master.close()


def test_bad_addresses_are_refused_with_their_form():
    master = akd_ros.Master("sim")
    try:
        master.scan()
        master.request_state("preop")
        for kwargs, message in (
            ({"ip": "192.0.2"}, 'IP address "192.0.2" is not of the form a.b.c.d (IPv4)'),
            ({"ip": "192.0.2.10", "mac": "02:01"}, 'MAC address "02:01" is not of the form aa:bb:cc:dd:ee:ff'),
        ):
            try:
                master.eoe_set_ip(0, **kwargs)
            except akd_ros.ConfigError as error:
                assert message in str(error)
            else:
                raise AssertionError(f"{kwargs} was taken")
    finally:
        master.close()


def test_akd_eoe_without_cap_net_admin_says_so():
    # setpriv drops every capability, as for a user without CAP_NET_ADMIN; the tool says what it needs, on one line.
    argv = [
        "setpriv",
        "--inh-caps=-all",
        "--bounding-set=-all",
        *console_script("akd-eoe"),
        "sim",
        "--ip",
        "192.0.2.10/24",
    ]
    result = subprocess.run(argv, capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 1, result.stdout + result.stderr
    assert result.stderr.strip().splitlines()[-1] == (
        "akd-eoe: error: opening a TAP interface needs CAP_NET_ADMIN (run as root, or setcap cap_net_admin)"
    ), result.stderr


def _who_has(ip: str) -> bytes:
    """A host's ARP request for `ip`: from 02:aa:00:00:00:01 at 192.0.2.1, to everyone."""
    host_mac, host_ip = bytes.fromhex("02aa00000001"), bytes([192, 0, 2, 1])
    arp = struct.pack("!HHBBH", 1, 0x0800, 6, 4, 1) + host_mac + host_ip + b"\0" * 6 + socket.inet_aton(ip)
    return b"\xff" * 6 + host_mac + b"\x08\x06" + arp


def test_a_joints_eoe_ip_parameter_gives_the_drive_its_address():
    values = {"link": "sim:2", "joints": ["a", "b"], "joints.b.eoe.ip": "192.0.2.11/24"}
    joints = params.settings(values).joints
    assert [j.eoe_ip for j in joints] == [None, "192.0.2.11/24"]
    for bad in ("192.0.2.11", "192.0.2/24", "drive"):
        with pytest.raises(params.ParameterError, match=r"parameter joints\.a\.eoe\.ip must be an IPv4 address"):
            params.settings({**values, "joints.a.eoe.ip": bad})
    bus = akd_ros.Bus("sim:2", [joint.drive() for joint in joints])
    try:
        # Drive 1 answers an ARP request for its address through the running cycle, from its MAC.
        assert bus.cycle.eoe_send(1, _who_has("192.0.2.11"))
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline:
            received = bus.cycle.eoe_receive(0.5)
            if received and received[1][20:22] == b"\x00\x02":  # an ARP reply (the announcement is a request)
                break
        else:
            raise AssertionError("no ARP reply from drive 1")
        assert received[0] == 1 and received[1][22:28] == bytes.fromhex("020105301002")
        assert socket.inet_ntoa(received[1][28:32]) == "192.0.2.11"
    finally:
        bus.close()


NODE_DOMAIN, NODE_WITHOUT_CAP_DOMAIN = 231, 232
"""The ROS domains of the node tests here (Fast DDS takes none above 232)."""


def _node_parameters(path: Path, link: str, tap: str, cpu: int = -1) -> Path:
    """A parameters file of two joints on `link`, each drive given its address, the bridge on TAP `tap`, the cycle
    thread on `cpu` (-1: any)."""
    path.write_text(
        yaml.safe_dump(
            {
                "akd_node": {
                    "ros__parameters": {
                        "link": link,
                        "joints": ["a", "b"],
                        "cycle_time": 0.004,
                        "rt.priority": 50,
                        "rt.cpu": cpu,
                        "joints.a.eoe.ip": f"{DRIVES[0]}/24",
                        "joints.b.eoe.ip": f"{DRIVES[1]}/24",
                        "eoe.tap": tap,
                        "eoe.host": HOST,
                        "autostart": True,
                    }
                }
            }
        )
    )
    return path


def _node_env(domain: int) -> dict:
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    env.pop("ROS_LOCALHOST_ONLY", None)
    return env


def _start_node(argv: list[str], domain: int) -> subprocess.Popen:
    """The node started with `argv` on ROS domain `domain`, its output (stderr too) in one pipe."""
    return subprocess.Popen(argv, env=_node_env(domain), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def _log_until(process: subprocess.Popen, log: list[str], text: str, timeout: float) -> None:
    """Reads the node's output into `log` until a line holds `text`; fails with the log otherwise."""

    def read() -> None:
        while not any(text in line for line in log) and (line := process.stdout.readline()):
            log.append(line)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    reader.join(timeout)
    assert any(text in line for line in log), f"no {text!r} from the node within {timeout} s:\n" + "".join(log)


def test_the_node_with_eoe_tap_bridges_the_machine_to_each_drive(veth, tmp_path):
    # The node in the master's namespace (DDS on its loopback), akd-sim's two drives in the other, over the veth.
    # The virtual AKDs on the cycle thread's CPU, as for akd-eoe above.
    cpu = max(os.sched_getaffinity(0))
    parameters = _node_parameters(tmp_path / "eoe.yaml", veth.if_master, "akdeoe1", cpu)
    argv, _ = node_command(parameters)
    with akd_sim_in_netns(veth.ns_sim, veth.if_sim, count=2, cpu=cpu) as sim:
        node = _start_node(netns_argv(veth.ns_master, argv), NODE_DOMAIN)
        log: list[str] = []
        try:
            _log_until(node, log, "active:", timeout=60)
            assert any("EoE bridge: a at 192.0.2.10, b at 192.0.2.11 through akdeoe1" in line for line in log), log
            _ping_each_drive(veth.ns_master, small=4, large=2)
        finally:
            out, _ = stop_process(node, timeout=20)
    log.append(out)
    text = "".join(log)
    closed = re.search(
        r"EoE bridge closed: (?P<to>\d+) frames to the drives, (?P<from>\d+) from them, dropped (?P<dropped_to>\d+) "
        r"and (?P<dropped_from>\d+); the cycle: \d+ cycles, (?P<lost>\d+) lost frames, (?P<wkc>\d+) WKC errors",
        text,
    )
    assert closed, text
    print(closed[0])
    # 12 pings answered, and the ARP exchanges; nothing dropped, and no process-data frame lost meanwhile but where
    # akd-sim was late.
    assert int(closed["to"]) >= 12 and int(closed["from"]) >= 12, closed[0]
    assert [int(closed[k]) for k in ("dropped_to", "dropped_from", "wkc")] == [0, 0, 0], closed[0]
    assert int(closed["lost"]) <= _late_by_half_a_period(sim), closed[0]
    assert "closed: drives disabled, bus in Init" in text, text
    assert "Traceback" not in text, text


def test_the_node_without_cap_net_admin_warns_and_runs_without_the_bridge(tmp_path):
    parameters = _node_parameters(tmp_path / "eoe.yaml", "sim:2", "akdeoe2")
    argv, _ = node_command(parameters)
    # setpriv drops every capability, as for a user without CAP_NET_ADMIN.
    node = _start_node(["setpriv", "--inh-caps=-all", "--bounding-set=-all", *argv], NODE_WITHOUT_CAP_DOMAIN)
    log: list[str] = []
    try:
        _log_until(node, log, "active:", timeout=60)
    finally:
        out, _ = stop_process(node, timeout=20)
    text = "".join(log) + out
    warnings = [line for line in text.splitlines() if "eoe.tap" in line]
    assert len(warnings) == 1 and warnings[0].endswith(
        "parameter eoe.tap: no EoE bridge: opening a TAP interface needs CAP_NET_ADMIN (run as root, or setcap "
        "cap_net_admin)"
    ), text
    assert "EoE bridge" not in text.replace(warnings[0], ""), text


def test_eoe_tap_and_host_are_refused_with_their_form():
    values = {"link": "sim:2", "joints": ["a", "b"], "joints.a.eoe.ip": "192.0.2.10/24", "eoe.tap": "akd-eoe0"}
    chosen = params.settings({**values, "eoe.host": HOST})
    assert (chosen.eoe_tap, chosen.eoe_host) == ("akd-eoe0", HOST)
    for name, bad, message in (
        ("eoe.tap", "a-name-too-long-1", r"parameter eoe\.tap must be a network interface name of 1 to 15 bytes"),
        ("eoe.tap", "akd/eoe", r"parameter eoe\.tap must be a network interface name"),
        ("eoe.host", "192.0.2.1", r"parameter eoe\.host must be an IPv4 address with its prefix"),
    ):
        with pytest.raises(params.ParameterError, match=message):
            params.settings({**values, name: bad})
    with pytest.raises(params.ParameterError, match=r"parameter eoe\.host is the address of eoe\.tap"):
        params.settings({**values, "eoe.tap": "", "eoe.host": HOST})
    with pytest.raises(params.ParameterError, match=r"give at least one joint an eoe\.ip"):
        params.settings({**values, "joints.a.eoe.ip": ""})


_CLEANUP_SCRIPT = """
import json, subprocess
import rclpy
from rclpy.parameter import Parameter
from akd_ros.node.lifecycle import AkdNode

def link_exists():
    return subprocess.run(["ip", "link", "show", "akdeoe3"], capture_output=True).returncode == 0

def pings():
    done = subprocess.run(["ping", "-c", "2", "-i", "0.2", "-W", "2", "192.0.2.10"], capture_output=True, text=True)
    return done.stdout.count("bytes from 192.0.2.10")

rclpy.init()
overrides = [
    Parameter("link", value="sim:2"),
    Parameter("joints", value=["a", "b"]),
    Parameter("joints.a.eoe.ip", value="192.0.2.10/24"),
    Parameter("eoe.tap", value="akdeoe3"),
    Parameter("eoe.host", value="192.0.2.1/24"),
]
node = AkdNode(args=[], parameter_overrides=overrides)
seen = []
for transition in ("configure", "cleanup", "configure", "shutdown"):
    getattr(node, "trigger_" + transition)()
    seen.append([transition, link_exists(), pings() if link_exists() else 0])
node.destroy_node()
rclpy.shutdown()
print(json.dumps(seen))
"""


def test_the_nodes_eoe_bridge_goes_with_cleanup_and_comes_back_with_configure(veth):
    # In a namespace of the test's own (the TAP interface and its address go nowhere else), in-process on sim:2.
    done = run_python_in_netns(veth.ns_master, _CLEANUP_SCRIPT, timeout=120, env=_node_env(NODE_DOMAIN))
    assert done.returncode == 0, done.stdout + done.stderr
    seen = json.loads(done.stdout.strip().splitlines()[-1])
    # (transition, whether the interface is there after it, pings answered through it)
    assert seen == [["configure", True, 2], ["cleanup", False, 0], ["configure", True, 2], ["shutdown", False, 0]], (
        seen,
        done.stderr,
    )
