"""akd_node's live view (live_view.port): Foxglove's WebSocket protocol served by the foxglove-sdk, seen by a client
speaking that protocol (tests/support/foxglove.py, on the `websockets` package) with every message decoded by
rosbags against the schema the server advertised.

On each transport (rclpy; zenoh from .venv-noros with every ROS import refused; both) the node runs two joints on
`akd-sim --count 2 --udp`: the client finds every topic advertised as a ros2msg channel, decodes /joint_states,
/diagnostics and a fault injected into a virtual AKD (a message the node builds as an object rather than bytes). On
rclpy alone: a client that advertises, publishes, calls a service, sets a parameter or fetches a file is refused each
time and the enabled joints do not move; a client that stops reading (its socket full, its queue overflowing) holds
up neither the node nor another client; the live view off maps no foxglove library, listens on no port and starts no
thread of it; a port in use (rclpy and zenoh) stops the node with one line before anything opens.
"""

from __future__ import annotations

import os
import re
import socket
import struct
import time
from contextlib import contextmanager
from pathlib import Path

import pytest
import yaml
from sensor_msgs.msg import JointState

from akd_ros.params import ParameterError, read_parameters_file, settings
from akd_ros.recorder import message_type
from akd_ros.zenoh.types import Types
from support.foxglove import MESSAGE_DATA, FoxgloveClient
from support.netns import free_udp_port
from support.ros import WAIT_S, NodeProcess, Sim, ros_environment, stop
from support.waiting import wait_for

DOMAINS = range(70, 80)
JOINTS = ["joint_1", "joint_2"]
NODE = "/akd_node/"
LIVE = "live view: Foxglove WebSocket on"
F439_CODE = 0x8611
PARAMETERS = {
    "cycle_time": 0.002,
    "mode": "cyclic_synchronous_position",
    "joints": JOINTS,
    "joint_states_rate": 50.0,
    "diagnostics_rate": 5.0,
}
"""What every node of this module is given, besides its transport, link and live_view.port."""


def params_file(folder: Path, transport: str, link: str, port: int, **more) -> Path:
    """A parameters file of PARAMETERS with `transport`, `link`, live_view.port `port` and `more`."""
    values = PARAMETERS | {"transport": transport, "link": link, "live_view.port": port} | more
    path = folder / f"akd_node_{transport}.yaml"
    path.write_text(yaml.safe_dump({"akd_node": {"ros__parameters": values}}))
    return path


def free_tcp_port() -> int:
    """A TCP port on 127.0.0.1 free right now (the kernel picks it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@pytest.fixture(scope="module")
def ros_domain():
    with ros_environment(DOMAINS) as domain:
        yield domain


def started(node: NodeProcess) -> str:
    """The node's output once it is active (or has exited)."""
    wait_for(
        "the node active",
        lambda: node.process.poll() is not None or "active: publishing" in node.output(),
        WAIT_S,
        0.05,
    )
    assert node.process.poll() is None, node.output()
    return node.output()


@contextmanager
def running(folder: Path, domain: int, *, transport="rclpy", link=None, port=0, **more):
    """akd_node with these parameters (on `link`, else on an akd-sim of two drives, handed out too), active."""
    sim = None if link is not None else Sim(free_udp_port(), count=len(JOINTS))
    path = params_file(folder, transport, link or f"udp://127.0.0.1:{sim.port}", port, **more)
    node = NodeProcess(path, domain, without_ros=transport == "zenoh")
    try:
        started(node)
        yield node, sim
    finally:
        stop(node.process)
        if sim is not None:
            sim.stop()
        print(f"akd_node output:\n{node.output()}")
        assert "Traceback" not in node.output()


@pytest.fixture(scope="module", params=["rclpy", "zenoh", "both"])
def viewed(request, ros_domain, tmp_path_factory):
    """A node of two joints on each transport with its live view on, and a client connected to it."""
    port = free_tcp_port()
    with running(tmp_path_factory.mktemp(request.param), ros_domain, transport=request.param, port=port) as (
        node,
        sim,
    ):
        assert f"{LIVE} ws://127.0.0.1:{port}, view only" in node.output()
        with FoxgloveClient(f"ws://127.0.0.1:{port}") as client:
            yield request.param, node, sim, client


def every_topic() -> set[str]:
    per_joint = {f"{NODE}{j}/{t}" for j in JOINTS for t in ("status", "io", "latch", "fault")}
    return {"/joint_states", "/diagnostics", f"{NODE}trajectory_status", f"{NODE}access", *per_joint}


def test_the_server_offers_no_capability_and_every_topic_as_a_ros2msg_channel(viewed):
    transport, _, _, client = viewed
    channels = client.topics(every_topic())
    assert client.server_info["capabilities"] == [], client.server_info
    assert client.server_info["name"] == "akd_node"
    assert {c.topic for c in channels.values()} == every_topic()
    assert {(c.encoding, c.schema_encoding) for c in channels.values()} == {("cdr", "ros2msg")}
    kinds = {c.topic: c.schema_name for c in channels.values()}
    assert kinds["/joint_states"] == "sensor_msgs/msg/JointState"
    assert kinds["/diagnostics"] == "diagnostic_msgs/msg/DiagnosticArray"
    assert kinds[f"{NODE}joint_2/io"] == "akd_ros/msg/DriveIO"
    assert kinds[f"{NODE}joint_1/fault"] == "akd_ros/msg/DriveFault"
    assert kinds[f"{NODE}trajectory_status"] == "akd_ros/msg/TrajectoryStatus"
    # The schema is the recorder's: the complete definition a bag of the same transport carries.
    if transport == "zenoh":
        store = Types().store
        expected = message_type(store.types["sensor_msgs/msg/JointState"], store).definition
    else:
        expected = message_type(JointState).definition
    assert channels["/joint_states"].schema == expected
    # With its dependencies (rclpy's name them pkg/msg/Type, rosbags' pkg/Type; Foxglove reads both).
    assert re.search(r"^MSG: std_msgs/(msg/)?Header$", expected, re.MULTILINE), expected


def test_joint_states_and_diagnostics_arrive_and_decode_against_the_advertised_schemas(viewed):
    _, _, _, client = viewed
    channels = client.topics({"/joint_states", "/diagnostics"})
    joint_states = client.subscribe(channels["/joint_states"])
    first = client.next_message(channels["/joint_states"], joint_states)
    later = client.next_message(channels["/joint_states"], joint_states)
    assert list(first.name) == JOINTS and len(first.position) == len(first.velocity) == len(first.effort) == 2
    assert (later.header.stamp.sec, later.header.stamp.nanosec) > (first.header.stamp.sec, first.header.stamp.nanosec)
    assert abs(later.header.stamp.sec - time.time()) < 60
    diagnostics = client.subscribe(channels["/diagnostics"])
    array = client.next_message(channels["/diagnostics"], diagnostics)
    statuses = {s.name: s for s in array.status}
    # Each joint's and the bus's status; the line's (its links and error counters) once they were first read.
    joints_and_bus = {"akd_node: joint_1", "akd_node: joint_2", "akd_node: bus"}
    assert joints_and_bus <= set(statuses), statuses
    assert all(name.startswith("akd_node: line") for name in set(statuses) - joints_and_bus), statuses
    values = {v.key: v.value for v in statuses["akd_node: bus"].values}
    assert "lost_frames" in values and values["joints"] == "joint_1, joint_2", values


def test_a_fault_the_node_publishes_as_an_object_arrives_decoded(viewed):
    _, _, sim, client = viewed
    topic = f"{NODE}joint_2/fault"
    channel = client.topics({topic})[topic]
    subscription = client.subscribe(channel)
    # The subscription reaches the server before the fault: a status of the joint's shows it is served.
    status_topic = f"{NODE}joint_2/status"
    status_channel = client.topics({status_topic})[status_topic]
    client.next_message(status_channel, client.subscribe(status_channel))
    sim.command("fault 1 F439")

    def f439(data):
        if data is None or data[0] != subscription:
            return None
        fault = client.decode(channel, data[2])
        return fault if fault.code == F439_CODE else None

    fault = client.pump(f439, "DriveFault F439 of joint_2")
    assert fault.joint == "joint_2" and "F439" in fault.text, fault
    assert fault.ds402_state in ("fault", "fault_reaction_active"), fault


def test_a_client_can_neither_publish_nor_call_nor_set_nor_fetch_and_nothing_moves(ros_domain, tmp_path):
    port = free_tcp_port()
    with (
        running(tmp_path, ros_domain, port=port, enable_on_start=True) as (node, sim),
        FoxgloveClient(f"ws://127.0.0.1:{port}") as client,
    ):
        channels = client.topics({"/joint_states", f"{NODE}joint_1/status"})
        status = channels[f"{NODE}joint_1/status"]
        statuses = client.subscribe(status)
        wait_for(
            "joint_1 enabled",
            lambda: client.next_message(status, statuses).ds402_state == "operation_enabled",
            WAIT_S,
            0.0,
        )
        joint_states = client.subscribe(channels["/joint_states"])
        before = client.next_message(channels["/joint_states"], joint_states).position[0]
        command = f"{NODE}joint_1/position_command"
        client.send(
            {
                "op": "advertise",
                "channels": [{"id": 7, "topic": command, "encoding": "cdr", "schemaName": "std_msgs/msg/Float64"}],
            }
        )
        assert client.reply("status", "clientPublish")["level"] == 2
        # std_msgs/Float64 in CDR: the encapsulation header, then the double: 3 rad from where the joint is.
        message = b"\x00\x01\x00\x00" + struct.pack("<d", before + 3.0)
        for _ in range(20):
            client.send_binary(MESSAGE_DATA, 7, data=message)
        client.send({"op": "setParameters", "id": "p", "parameters": [{"name": "live_view.port", "value": 0}]})
        assert client.reply("status", "parameters")["level"] == 2
        client.send_binary(0x02, 1, 1, 3, data=b"cdr")
        assert "services" in client.reply("serviceCallFailure", "")["message"]
        client.send({"op": "fetchAsset", "uri": f"file://{Path(__file__).resolve()}", "requestId": 1})
        assert client.reply("status", "asset")["level"] == 2
        client.send({"op": "subscribeConnectionGraph"})
        assert client.reply("status", "connection graph")["level"] == 2
        # A second of holding: the joint is where it was, its drive in Operation enabled, no command logged.
        deadline = time.monotonic() + 1.0
        positions = []
        while time.monotonic() < deadline:
            positions.append(client.next_message(channels["/joint_states"], joint_states).position[0])
        assert max(abs(p - before) for p in positions) < 1e-3, (before, positions[-5:])
        assert sim.state(0)["state"] == "Operation enabled"
        assert not any(t["op"] == "advertiseServices" for t in client.texts)
        assert command not in node.output()


def listening_ports(pid: int) -> set[int]:
    """The TCP ports process `pid` listens on (its sockets in /proc/net/tcp and tcp6 in state LISTEN)."""
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    ports = set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            fields = line.split()
            if fields[3] == "0A" and fields[9] in inodes:
                ports.add(int(fields[1].rsplit(":", 1)[1], 16))
    return ports


def thread_names(pid: int) -> set[str]:
    return {(task / "comm").read_text().strip() for task in Path(f"/proc/{pid}/task").iterdir()}


def test_off_it_maps_no_foxglove_listens_on_no_port_and_starts_no_thread(ros_domain, tmp_path):
    port = free_tcp_port()
    seen = {}
    for on in (False, True):
        with running(tmp_path, ros_domain, link="sim:2?missed=lost", port=port if on else 0) as (node, _):
            pid = node.process.pid
            maps = Path(f"/proc/{pid}/maps").read_text()
            seen[on] = ("_foxglove_py" in maps, listening_ports(pid), thread_names(pid))
            assert (LIVE in node.output()) == on
    assert seen[False][:2] == (False, set()), seen[False]
    assert seen[True][:2] == (True, {port}), seen[True]
    # The SDK's runtime threads (tokio's) exist with the view and only with it.
    added = seen[True][2] - seen[False][2]
    assert added, (seen[False][2], seen[True][2])


@pytest.mark.parametrize("transport", ["rclpy", "zenoh"])
def test_a_port_in_use_stops_the_node_with_one_line_before_the_bus_opens(ros_domain, tmp_path, transport):
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        path = params_file(tmp_path, transport, "sim:2?missed=lost", port)
        node = NodeProcess(path, ros_domain, without_ros=transport == "zenoh")
        try:
            status = node.process.wait(timeout=WAIT_S)
        finally:
            stop(node.process)
    text = node.output()
    errors = [line for line in text.splitlines() if line.startswith("akd_node: error:")]
    assert status == 1, text
    assert len(errors) == 1, text
    assert f"parameters live_view.*: the live view did not open on ws://127.0.0.1:{port}" in errors[0]
    assert "in use" in errors[0] and "live_view.port" in errors[0], errors[0]
    assert "Traceback" not in text
    # Nothing opened: the bus was never touched.
    assert "I/O the mappings carry" not in text and "configured:" not in text, text


def test_bad_live_view_parameters_are_refused_naming_what_is_allowed():
    with pytest.raises(ParameterError, match=r"live_view\.address must be an IPv4 or IPv6 address.*'localhost'"):
        settings({"live_view.address": "localhost", "live_view.port": 8765})
    with pytest.raises(ParameterError, match=r"live_view\.port must be an integer in \[0, 65535\], got 70000"):
        settings({"live_view.port": 70000})
    assert settings({}).live_view is None
    assert settings({"live_view.port": 8765, "live_view.address": "::1"}).live_view == ("::1", 8765)


def test_the_shipped_configs_leave_the_live_view_off():
    for config in Path(__file__).resolve().parents[1].glob("config/*.yaml"):
        if "ros__parameters" in config.read_text():
            given = read_parameters_file(str(config))
            assert given.get("live_view.port", 0) == 0, config


def send_queue(local: int, remote: int) -> int | None:
    """The bytes the kernel holds to send on the TCP connection from 127.0.0.1:`local` to :`remote`."""
    for line in Path("/proc/net/tcp").read_text().splitlines()[1:]:
        fields = line.split()
        if int(fields[1].rsplit(":", 1)[1], 16) == local and int(fields[2].rsplit(":", 1)[1], 16) == remote:
            return int(fields[4].split(":")[0], 16)
    return None


def test_a_client_that_stops_reading_holds_up_neither_the_node_nor_another_client(ros_domain, tmp_path):
    # Six joints' /joint_states at 1 kHz and their statuses and ~/io at 100 Hz fill the stuck client's socket within
    # seconds, then its queue of the SDK's.
    port = free_tcp_port()
    url = f"ws://127.0.0.1:{port}"
    joints = [f"joint_{k}" for k in range(1, 7)]
    rates = {"joint_states_rate": 1000.0, "status_rate": 100.0, "io_rate": 100.0, "mapping": "io"}
    with (
        running(tmp_path, ros_domain, link="sim:6?missed=lost", port=port, joints=joints, **rates) as (node, _),
        FoxgloveClient(url, receive_buffer=4096) as stuck,
        FoxgloveClient(url) as watching,
    ):
        for channel in stuck.topics({"/joint_states", f"{NODE}joint_6/io"}).values():
            stuck.subscribe(channel)
        channels = watching.topics({"/joint_states"})
        joint_states = watching.subscribe(channels["/joint_states"])

        # The server's send queue to the stuck client grows until the kernel takes no more: it is full.
        def full() -> bool:
            queued = [send_queue(port, stuck.local_port)]
            time.sleep(1.0)
            queued.append(send_queue(port, stuck.local_port))
            return queued[0] is not None and queued[0] > 100_000 and queued[0] == queued[1]

        wait_for("the stuck client's socket full", full, 3 * WAIT_S, 0.0)
        # Beyond its socket, BACKLOG messages fill its queue in the SDK within a second or two at this rate, its oldest
        # dropped after; the node publishes on, and the other client receives it all along: three seconds of fresh
        # /joint_states (had the node waited for the stuck client, none would come).
        since = time.time()
        stamps = []
        while len(stamps) < 200 or stamps[-1] < since + 3.0:
            message = watching.next_message(channels["/joint_states"], joint_states)
            stamps.append(message.header.stamp.sec + message.header.stamp.nanosec * 1e-9)
        assert stamps == sorted(stamps)
        assert node.process.poll() is None
        assert send_queue(port, stuck.local_port) is not None, "the stuck client was dropped; it should only lose data"
