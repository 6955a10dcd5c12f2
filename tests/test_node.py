"""akd_node against a virtual AKD, seen from another process through real rclpy.

The drive is an `akd-sim --udp` process whose stdin injects faults and input toggles; the node is `.venv/bin/akd_node
--ros-args --params-file FILE` with link udp://127.0.0.1:PORT; this process is the ROS client (subscriptions and
service calls over rmw_fastrtps_cpp, a ROS_DOMAIN_ID of its own, discovery on localhost). Every wait is bounded and
both processes are always ended in teardown. The tests share one node and set up the drive state each needs.
"""

from __future__ import annotations

import json
import math
import os
import queue
import random
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from akd_ros.msg import DriveFault, DriveStatus, LatchEvent
from akd_ros.srv import ArmLatch, SdoRead, SdoWrite, SetMode

BIN = Path(sys.executable).parent
NODE = "/akd_node/"
JOINT = "test_axis"
COUNTS_PER_RAD = 2**20 / (2 * math.pi)
# A bound on every wait, not a timing expectation: discovery and start-up on a loaded 2-core machine take seconds.
WAIT_S = 30.0
JOINT_STATES_RATE = 50.0
MAX_POSITION = 1e4


def lines_of(stream, into: queue.Queue, log: list[str]) -> None:
    """Copies a process's output lines into a queue and a log, until its end."""
    for line in stream:
        log.append(line)
        into.put(line)


class Sim:
    """An akd-sim --udp process and its command line on stdin."""

    def __init__(self, port: int):
        self.log: list[str] = []
        self.lines: queue.Queue = queue.Queue()
        self.process = subprocess.Popen([str(BIN / "akd-sim"), "--udp", f"127.0.0.1:{port}"], stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1)
        threading.Thread(target=lines_of, args=(self.process.stdout, self.lines, self.log), daemon=True).start()
        self.reply("akd-sim: starting")

    def reply(self, prefix: str) -> str:
        """The next output line starting with `prefix`."""
        deadline = time.monotonic() + WAIT_S
        while True:
            try:
                line = self.lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise AssertionError(f"akd-sim gave no line starting {prefix!r}; output:\n{''.join(self.log)}")
            if line.startswith(prefix) or line.startswith("error"):
                assert not line.startswith("error"), line
                return line

    def command(self, line: str) -> str:
        """Sends one command line and gives its answer, which must be 'ok ...'."""
        self.process.stdin.write(line + "\n")
        self.process.stdin.flush()
        return self.reply("ok")

    def state(self) -> dict:
        """The virtual drive's firmware state (state, fault, position in counts, velocity, torque)."""
        return json.loads(self.command("state 0")[3:])

    def stop(self) -> None:
        """Ends the simulator."""
        stop(self.process)


def stop(process: subprocess.Popen) -> None:
    """SIGTERM, then SIGKILL if it does not end in time."""
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(timeout=WAIT_S)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


class Client:
    """This process's ROS side: every topic of the node collected, its services called."""

    def __init__(self, domain: int):
        self.context = rclpy.Context()
        rclpy.init(context=self.context, domain_id=domain)
        self.node = rclpy.create_node("akd_node_test", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.received: dict[str, list] = {}
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        for topic, kind in (("/joint_states", JointState), ("/diagnostics", DiagnosticArray),
                            (NODE + "status", DriveStatus), (NODE + "latch", LatchEvent),
                            (NODE + "fault", DriveFault)):
            self.received[topic] = []
            self.node.create_subscription(kind, topic, self.received[topic].append, qos)
        self.commands = {kind: self.node.create_publisher(Float64, f"{NODE}{kind}_command", qos)
                         for kind in ("position", "velocity", "torque")}

    def spin_until(self, done, what: str, timeout: float = WAIT_S) -> None:
        """Spins until done() is true; fails naming what did not happen."""
        deadline = time.monotonic() + timeout
        while not done():
            assert time.monotonic() < deadline, f"no {what} within {timeout} s"
            self.executor.spin_once(timeout_sec=0.02)

    def spin_for(self, seconds: float) -> None:
        """Spins for `seconds`, collecting what arrives."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.02)

    def call(self, kind, name: str, request=None):
        """Calls service ~/name of the node and gives its response."""
        client = self.node.create_client(kind, NODE + name)
        self.spin_until(client.service_is_ready, f"service {NODE}{name}")
        future = client.call_async(request or kind.Request())
        self.spin_until(future.done, f"answer of {NODE}{name}")
        self.node.destroy_client(client)
        return future.result()

    def trigger(self, name: str) -> str:
        """Calls a Trigger service that must succeed; gives its message."""
        response = self.call(Trigger, name)
        assert response.success, f"{name}: {response.message}"
        return response.message

    def latest(self, topic: str):
        """The last message of `topic` after a fresh one arrived."""
        count = len(self.received[topic])
        self.spin_until(lambda: len(self.received[topic]) > count, f"message on {topic}")
        return self.received[topic][-1]

    def position(self) -> float:
        """The joint's position from a fresh joint_states message."""
        return self.latest("/joint_states").position[0]

    def stream(self, kind: str, values, period: float = 0.02) -> None:
        """Publishes each of `values` as a `kind` command, one every `period` seconds, spinning between (once the
        node's subscription is matched, so none is lost)."""
        publisher = self.commands[kind]
        self.spin_until(lambda: publisher.get_subscription_count() > 0, f"subscriber of {kind} commands")
        for value in values:
            self.commands[kind].publish(Float64(data=float(value)))
            self.spin_for(period)

    def close(self) -> None:
        """Destroys the node and shuts the context down."""
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


PARAMS = """\
akd_node:
  ros__parameters:
    link: udp://127.0.0.1:{port}
    cycle_time: 0.002
    mode: interpolated_position
    joint_name: {joint}
    limits.min_position: -{max_position}
    limits.max_position: {max_position}
    limits.max_velocity: 20.0
    limits.max_torque: 2.0
    joint_states_rate: {rate}
    status_rate: 10.0
    diagnostics_rate: 5.0
    command_timeout: 0.3
    command_timeout_policy: hold
"""


@pytest.fixture(scope="module")
def ros_domain():
    """A ROS_DOMAIN_ID of this module's own, discovery on localhost, Fast DDS; set for the module."""
    domain = random.randint(201, 210)
    settings = {"ROS_DOMAIN_ID": str(domain), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
                "RMW_IMPLEMENTATION": "rmw_fastrtps_cpp"}
    with pytest.MonkeyPatch.context() as patch:
        for key, value in settings.items():
            patch.setenv(key, value)
        patch.delenv("ROS_LOCALHOST_ONLY", raising=False)
        yield domain


@pytest.fixture(scope="module")
def sim():
    """The virtual AKD, served over UDP by akd-sim."""
    from support.netns import free_udp_port

    simulator = Sim(free_udp_port())
    yield simulator
    simulator.stop()


class NodeProcess:
    """akd_node running as `akd_node --ros-args --params-file FILE`, its output collected."""

    def __init__(self, params: Path):
        self.log: list[str] = []
        self.process = subprocess.Popen([str(BIN / "akd_node"), "--ros-args", "--params-file", str(params)],
                                        env=dict(os.environ), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                        text=True, bufsize=1)
        threading.Thread(target=lines_of, args=(self.process.stdout, queue.Queue(), self.log), daemon=True).start()

    def output(self) -> str:
        """What the node printed so far."""
        return "".join(self.log)


@pytest.fixture(scope="module")
def node(ros_domain, sim, tmp_path_factory):
    """The node on the simulator's port."""
    port = sim.process.args[2].rsplit(":", 1)[1]
    params = tmp_path_factory.mktemp("node") / "akd_test.yaml"
    params.write_text(PARAMS.format(port=port, joint=JOINT, max_position=MAX_POSITION, rate=JOINT_STATES_RATE))
    process = NodeProcess(params)
    yield process
    stop(process.process)
    print(f"akd_node output:\n{process.output()}")


@pytest.fixture(scope="module")
def ros(node):
    """The client, once the node publishes."""
    client = Client(int(os.environ["ROS_DOMAIN_ID"]))
    client.spin_until(lambda: client.received["/joint_states"] or node.process.poll() is not None, "joint_states")
    assert node.process.poll() is None, f"akd_node exited:\n{node.output()}"
    yield client
    client.close()


def ready(ros: Client, sim: Sim, mode: str) -> None:
    """The drive without a fault, in `mode`, enabled."""
    if sim.state()["fault"] is not None:
        ros.trigger("reset_fault")
    ros.trigger("disable")
    response = ros.call(SetMode, "set_mode", SetMode.Request(mode=mode))
    assert response.success, response.message
    ros.trigger("enable")


def move_to(ros: Client, target: float, seconds: float = 1.0) -> None:
    """Streams position commands in a ramp from where the axis is to `target`, then waits for it to arrive."""
    start = ros.position()
    steps = max(1, int(seconds / 0.02))
    ros.stream("position", [start + (target - start) * (i + 1) / steps for i in range(steps)])
    ros.spin_until(lambda: abs(ros.position() - target) < 1e-3, f"axis at {target} rad")


def test_joint_states_arrive_at_the_configured_rate_with_the_drive_values(ros, sim):
    ros.trigger("disable")
    start = len(ros.received["/joint_states"])
    ros.spin_for(2.0)
    count = len(ros.received["/joint_states"]) - start
    # About 100 at 50 Hz; the range only tells a publishing rate from a wrong one.
    assert 50 <= count <= 150, count
    message = ros.received["/joint_states"][-1]
    assert message.name == [JOINT]
    assert len(message.position) == len(message.velocity) == len(message.effort) == 1
    drive = sim.state()
    assert abs(ros.position() * COUNTS_PER_RAD - drive["position"]) <= 1.0, (ros.position(), drive)
    assert message.header.stamp.sec > 0


def test_a_position_command_moves_the_axis(ros, sim):
    ready(ros, sim, "interpolated_position")
    target = ros.position() + 1.0
    move_to(ros, target)
    assert abs(sim.state()["position"] - target * COUNTS_PER_RAD) < 1e-3 * COUNTS_PER_RAD


def test_a_velocity_command_turns_the_axis_and_a_stopped_stream_halts_it(ros, sim, node):
    ready(ros, sim, "profile_velocity")
    ros.stream("velocity", [2.0] * 50)
    velocity = ros.latest("/joint_states").velocity[0]
    assert velocity == pytest.approx(2.0, rel=0.05)
    assert sim.state()["velocity"] == pytest.approx(2.0 * COUNTS_PER_RAD, rel=0.05)
    # No more commands: after command_timeout the node halts the axis (policy hold) and it stays enabled.
    ros.spin_until(lambda: abs(ros.latest("/joint_states").velocity[0]) < 0.01, "axis halted")
    assert sim.state()["state"] == "Operation enabled"
    assert "command_timeout" in node.output()


def test_a_torque_command_drives_the_axis_in_torque_mode(ros, sim):
    ready(ros, sim, "profile_torque")
    ros.stream("torque", [0.3] * 10)
    state = ros.latest("/joint_states")
    assert state.effort[0] == pytest.approx(0.3, rel=0.05)
    assert state.velocity[0] > 0.1
    ros.stream("torque", [-0.3] * 10 + [0.0] * 5)
    ros.trigger("disable")


def test_an_injected_fault_shows_on_fault_and_diagnostics_and_reset_clears_it(ros, sim):
    ready(ros, sim, "interpolated_position")
    sim.command("fault 0 F439")
    # Lost frames on a busy machine come as faults too; the one injected is F439 (CiA code 0x8611).
    following = [f for f in ros.received[NODE + "fault"] if f.code == 0x8611]
    ros.spin_until(lambda: following or following.extend(f for f in ros.received[NODE + "fault"]
                                                         if f.code == 0x8611), "DriveFault 0x8611")
    fault = following[-1]
    assert "F439" in fault.text, fault
    assert fault.joint == JOINT and fault.source in ("drive_fault", "emergency")
    assert fault.al_state == "op" and fault.ds402_state in ("fault", "fault_reaction_active"), fault
    assert fault.header.stamp.sec > 0

    def status() -> DiagnosticStatus:
        return ros.latest("/diagnostics").status[0]

    ros.spin_until(lambda: status().level == DiagnosticStatus.ERROR, "ERROR on /diagnostics")
    values = {v.key: v.value for v in status().values}
    assert "F439" in values["last_fault"] and values["ds402_state"] == "Fault", values

    ros.trigger("reset_fault")
    assert sim.state()["fault"] is None
    ros.spin_until(lambda: status().level == DiagnosticStatus.OK, "OK on /diagnostics after the reset")


def test_a_latch_event_arrives_after_the_input_edge(ros, sim):
    ready(ros, sim, "interpolated_position")
    response = ros.call(ArmLatch, "arm_latch", ArmLatch.Request(channel=1, edge=LatchEvent.EDGE_RISING, arm=True))
    assert response.success, response.message
    here = ros.position()
    edge_counts = round((here + 0.5) * COUNTS_PER_RAD)
    sim.command(f"toggles 0 1 {edge_counts}")
    move_to(ros, here + 1.0)
    ros.spin_until(lambda: ros.received[NODE + "latch"], "LatchEvent")
    latch = ros.received[NODE + "latch"][-1]
    assert (latch.joint, latch.channel, latch.edge) == (JOINT, 1, LatchEvent.EDGE_RISING)
    assert abs(latch.position_counts - edge_counts) <= 1, (latch.position_counts, edge_counts)
    assert latch.position == pytest.approx(latch.position_counts / COUNTS_PER_RAD, abs=1e-9)
    sim.command("toggles 0 1")


def test_drive_status_and_the_services_round_trip_with_the_node(ros, sim):
    ready(ros, sim, "interpolated_position")
    status = ros.latest(NODE + "status")
    assert (status.joint, status.ds402_state, status.mode) == (JOINT, "operation_enabled", "interpolated_position")
    assert status.mode_of_operation == 7 and status.statusword & 0x6F == 0x27
    assert status.cycles > 0 and 0 < status.period_mean < 0.01 and status.period_max >= status.period_mean
    response = ros.call(SdoRead, "sdo_read", SdoRead.Request(index=0x6061, subindex=0))
    assert response.success and list(response.data) == [7], response
    response = ros.call(SetMode, "set_mode", SetMode.Request(mode="cyclic_synchronous_velocity"))
    assert not response.success and "interpolated_position" in response.message
    response = ros.call(SdoWrite, "sdo_write", SdoWrite.Request(index=0x5FFF, subindex=0, data=[1, 2]))
    assert not response.success and response.message.startswith("0x5FFF:00: "), response


def test_bad_commands_are_refused_and_the_axis_stays_still(ros, sim, node):
    ready(ros, sim, "interpolated_position")
    before = sim.state()["position"]
    ros.stream("position", [math.nan, MAX_POSITION * 2, -MAX_POSITION * 2] * 5)
    ros.stream("velocity", [1.0] * 5)
    ros.stream("torque", [0.5] * 5)
    ros.spin_for(0.5)
    assert abs(sim.state()["position"] - before) <= 2, "the axis moved"
    log = node.output()
    for what in ("position command refused: position must be a finite number", "beyond the limit max_position",
                 "beyond the limit min_position", "velocity command refused", "torque command refused"):
        assert what in log, f"no warning with {what!r} in:\n{log}"


def test_sigterm_disables_the_drive_and_exits_0(ros, sim, node):
    ready(ros, sim, "interpolated_position")
    node.process.send_signal(signal.SIGTERM)
    assert node.process.wait(timeout=WAIT_S) == 0, node.output()
    # The simulator answers queries only while a master sends frames: a fresh master looks at what the node left.
    from akd_ros import Master

    master = Master(sim.process.args[2].replace("127.0.0.1", "udp://127.0.0.1", 1))
    try:
        assert master.scan()[0]["found_al_state"] == "Init"
        master.request_state("preop")
        statusword = int.from_bytes(master.sdo_read(0, 0x6041, 0), "little")
    finally:
        master.close()
    # Switch on disabled; a drive left enabled would show Fault (F125 after eight missed frames).
    assert statusword & 0x6F == 0x40, hex(statusword)


SECOND_PARAMS = """\
akd_node:
  ros__parameters:
    link: udp://127.0.0.1:{port}
    cycle_time: 0.002
    mode: profile_velocity
    joint_name: {joint}
    joint_states_rate: 50.0
    fault_reset: auto_once
    command_timeout: 0.3
    command_timeout_policy: quick_stop
    enable_on_start: true
    record.enabled: true
    record.folder: {bags}
    record.decimation: 10
"""


@pytest.fixture
def second(tmp_path, ros_domain):
    """Another simulator and node (auto_once fault reset, quick stop on a stopped command stream, enabled at
    start-up), with a client of its own, on a domain of its own so the module's node is not seen."""
    from support.netns import free_udp_port

    simulator = Sim(free_udp_port())
    params = tmp_path / "second.yaml"
    params.write_text(SECOND_PARAMS.format(port=simulator.process.args[2].rsplit(":", 1)[1], joint=JOINT,
                                           bags=tmp_path / "bags"))
    domain = ros_domain + SECOND_DOMAIN_OFFSET
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("ROS_DOMAIN_ID", str(domain))
        process = NodeProcess(params)
    client = Client(domain)
    try:
        client.spin_until(lambda: client.received["/joint_states"] or process.process.poll() is not None,
                          "joint_states of the second node")
        assert process.process.poll() is None, f"akd_node exited:\n{process.output()}"
        yield simulator, process, client, tmp_path / "bags"
    finally:
        client.close()
        stop(process.process)
        simulator.stop()
        print(f"second akd_node output:\n{process.output()}")


SECOND_DOMAIN_OFFSET = 10


def test_quick_stop_on_a_stopped_stream_and_a_fault_reset_once_by_itself_all_recorded(second):
    sim, node, ros, bags = second
    ros.spin_until(lambda: "enable_on_start: Operation enabled" in node.output(), "enable at start-up")
    ros.stream("velocity", [3.0] * 25)
    assert ros.latest("/joint_states").velocity[0] == pytest.approx(3.0, rel=0.05)
    # The stream stops: after command_timeout the node quick-stops the axis.
    ros.spin_until(lambda: "quick stop; call ~/enable to go on" in node.output(), "quick stop on the time-out")
    assert sim.state()["state"] == "Quick stop active"
    ros.trigger("enable")
    sim.command("fault 0 F235")
    ros.spin_until(lambda: any("F235" in f.text for f in ros.received[NODE + "fault"]), "DriveFault F235")
    # auto_once resets the fault and leaves the drive disabled.
    ros.spin_until(lambda: "fault_reset auto_once: fault reset" in node.output(), "the fault reset by the node")
    assert sim.state()["fault"] is None and sim.state()["state"] == "Switch on disabled"

    stop(node.process)
    assert node.process.returncode == 0, node.output()
    (bag,) = bags.iterdir()
    from rosbags.highlevel import AnyReader

    with AnyReader([bag]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        faults = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages()
                  if c.topic == NODE + "fault"]
    assert set(counts) == {"/joint_states", "/diagnostics", NODE + "status", NODE + "latch", NODE + "fault",
                           NODE + "position_command", NODE + "velocity_command", NODE + "torque_command",
                           NODE + "cycle", NODE + "black_box"}, counts
    assert counts["/joint_states"] > 10 and counts[NODE + "cycle"] > 10 and counts[NODE + "black_box"] > 10
    assert counts[NODE + "velocity_command"] == 25, counts
    assert any("F235" in f.text for f in faults)
