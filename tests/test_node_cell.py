"""akd_node driving a whole cell, seen from another process through real rclpy: an EK1100 with an EL1004 and an
EL2004 in front of two AKDs, served by `akd-sim --line ek1100,el1004,el2004,akd,akd` over UDP. The terminals, named
under devices, come to Op with the drives; each one's channels are on ~/<device>/io; an input toggled on akd-sim's
stdin is published at its edge and shown by /diagnostics; an output set through ~/set_outputs reaches the terminal's
pins; bad requests are refused in one line and change nothing; the outputs go off at the fault reaction of a drive's
fault, when a power-cycled terminal is brought back and when the node deactivates, and stay off until set again; and the
bag holds the input's edge and the output as sent. Every wait is bounded; the processes are always ended.
"""

from __future__ import annotations

import subprocess
import time
from pathlib import Path

import pytest
from diagnostic_msgs.msg import DiagnosticArray
from lifecycle_msgs.msg import Transition
from lifecycle_msgs.srv import ChangeState
from rclpy.qos import QoSProfile, ReliabilityPolicy

from akd_ros.msg import DeviceIO
from support.netns import free_udp_port
from support.ros import BIN, NodeProcess, Participant, Sim, module_domain, node_on_sim, stop

DOMAINS = range(90, 96)
"""ROS_DOMAIN_IDs of this module (see tests/test_node_io.py for the others')."""
NODE = "/akd_node/"
LINE = "ek1100,el1004,el2004,akd,akd"

PARAMS = """\
akd_node:
  ros__parameters:
    link: udp://127.0.0.1:{{port}}
    cycle_time: 0.002
    mode: cyclic_synchronous_position
    io_rate: 5.0
    diagnostics_rate: 5.0
    devices: [sensors, valves]
    devices.sensors.slave: 1
    devices.sensors.product: EL1004
    devices.valves.slave: 2
    devices.valves.product: EL2004
    joints: [axis_1, axis_2]
    joints.axis_1.slave: 3
    joints.axis_2.slave: 4
    record.enabled: true
    record.folder: {folder}
    record.black_box_seconds: 0.0
"""


class Client(Participant):
    """Each device's ~/<device>/io and /diagnostics collected; ~/set_outputs called."""

    def __init__(self, domain: int, devices=("sensors", "valves")):
        super().__init__(domain, "akd_node_cell_test")
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
        for topic, kind in {
            **{f"{NODE}{device}/io": DeviceIO for device in devices},
            "/diagnostics": DiagnosticArray,
        }.items():
            self.received[topic] = []
            self.node.create_subscription(kind, topic, self.received[topic].append, qos)

    def io(self, device: str, done=lambda m: True, what: str = "~/io") -> DeviceIO:
        """The first ~/<device>/io message from now on for which `done(message)`."""
        topic = f"{NODE}{device}/io"
        seen = len(self.received[topic])

        def arrived():
            return next((m for m in self.received[topic][seen:] if done(m)), None)

        self.spin_until(arrived, f"{what} of {device}")
        return arrived()

    def values(self, device: str, done, what: str) -> dict[str, str]:
        """The values of the first /diagnostics status of `device` from now on for which `done(values)`."""

        def values_of(status) -> dict[str, str]:
            return {v.key: v.value for v in status.values}

        return values_of(self.status(f"akd_node: {device}", lambda status: done(values_of(status)), what))


def level(message: DeviceIO, name: str) -> float:
    """The value of channel `name` in `message`, input or output."""
    if name in message.input_names:
        return message.inputs[list(message.input_names).index(name)]
    return message.outputs[list(message.output_names).index(name)]


ros_domain = module_domain(DOMAINS)


@pytest.fixture(scope="module")
def run(ros_domain, tmp_path_factory):
    """akd-sim serving the cell, the node on it, and the client once ~/valves/io arrives."""
    folder = tmp_path_factory.mktemp("node_cell")
    params = PARAMS.format(folder=folder / "bags")
    with node_on_sim(params, folder, ros_domain, line=LINE, client_of=Client, ready=f"{NODE}valves/io") as run:
        yield (*run, folder / "bags")


def test_the_cell_comes_to_op_with_each_terminal_on_its_own_topic(run):
    sim, node, ros = run[:3]
    sensors, valves = ros.io("sensors"), ros.io("valves")
    assert (sensors.device, sensors.product, sensors.slave) == ("sensors", "EL1004", 1)
    assert list(sensors.input_names) == [f"channel_{n}_input" for n in range(1, 5)] and not sensors.output_names
    assert list(valves.output_names) == [f"channel_{n}_output" for n in range(1, 5)] and not valves.input_names
    assert list(valves.outputs) == [0.0] * 4 and sensors.fresh
    # The coupler and the terminals are in Op with the drives (whose joints are active).
    assert [sim.state(position)["al_state"] for position in range(3)] == ["Op"] * 3
    log = node.output()
    assert "devices sensors (slave 1, EL1004), valves (slave 2, EL2004)" in log, log
    # The EK1100 is in Op with them, named by neither joints nor devices: the node says so.
    assert "slaves in Op that the parameters name neither as a joint nor as a device" in log and "0 (EK1100)" in log


def test_an_input_toggled_on_the_terminal_is_published_at_its_edge_and_shown_by_diagnostics(run):
    sim, _, ros = run[:3]
    before = ros.io("sensors")
    assert level(before, "channel_2_input") == 0.0
    sim.command("input 1 2 high")
    high = ros.io("sensors", lambda m: level(m, "channel_2_input") == 1.0, "channel_2_input high")
    assert high.cycle > before.cycle
    ros.values("sensors", lambda v: v.get("input channel_2_input") == "high", "the input on /diagnostics")
    sim.command("input 1 2 low")
    ros.io("sensors", lambda m: level(m, "channel_2_input") == 0.0, "channel_2_input low")


def test_an_output_set_through_ros_reaches_the_terminal(run):
    sim, _, ros = run[:3]
    response = ros.set_outputs("valves", ["channel_3_output", "channel_1_output"], [True, False])
    assert response.success, response.message
    assert response.message == "valves: channel_3_output high, channel_1_output low from the next cycle"
    ros.io("valves", lambda m: level(m, "channel_3_output") == 1.0, "channel_3_output on")
    assert sim.state(2)["outputs"] == [False, False, True, False]
    ros.values("valves", lambda v: v.get("output channel_3_output") == "high", "the output on /diagnostics")


def test_bad_requests_of_a_device_are_refused_in_one_line_and_change_nothing(run):
    sim, _, ros = run[:3]
    assert ros.set_outputs("valves", ["channel_2_output"], [True]).success
    ros.io("valves", lambda m: level(m, "channel_2_output") == 1.0, "channel_2_output on")
    before = sim.state(2)["outputs"]
    for joint, outputs, values, analog, refusal in (
        (
            "valves",
            ["channel_2_output", "gripper"],
            [False, True],
            None,
            'slave 2 has no output channel "gripper"; its outputs: channel_1_output, channel_2_output',
        ),
        ("valves", ["channel_1_output"], [], None, "1 outputs with 0 values: give one value per output"),
        ("valves", [], [], None, "nothing to set: give outputs of device valves with their values"),
        ("valves", ["channel_1_output"], [True], 1.0, "set_analog_output is a joint's"),
        ("valves", ["channel_1_output", "channel_1_output"], [True, True], None, "given twice"),
        ("sensors", ["channel_1_input"], [True], None, 'slave 1\'s channel "channel_1_input" is an input'),
        ("lamps", ["1"], [True], None, "joint 'lamps' is not one of this node's joints: axis_1, axis_2, nor of its"),
    ):
        response = ros.set_outputs(joint, outputs, values, analog)
        assert not response.success and "\n" not in response.message, response.message
        assert response.message.startswith("outputs not set: ") and refusal in response.message, response.message
    assert sim.state(2)["outputs"] == before


def test_a_drive_fault_switches_the_outputs_off_and_they_stay_off_after_the_reset(run):
    sim, _, ros = run[:3]
    assert ros.set_outputs("valves", ["channel_1_output", "channel_3_output"], [True, True]).success
    ros.io("valves", lambda m: level(m, "channel_3_output") == 1.0, "channel_3_output on")
    ros.trigger("enable")
    # fault_reaction all: the drives quick-stopped, the gripper's valves closed in the same reaction.
    sim.command("fault 4 F439")
    ros.io("valves", lambda m: not any(m.outputs), "every output off at the fault reaction")
    assert sim.state(2)["outputs"] == [False] * 4
    ros.trigger("reset_fault")
    ros.spin_for(0.5)
    assert not any(ros.io("valves").outputs) and sim.state(2)["outputs"] == [False] * 4, "off until set again"
    assert ros.set_outputs("valves", ["channel_1_output"], [True]).success
    ros.io("valves", lambda m: level(m, "channel_1_output") == 1.0, "channel_1_output on again")
    assert sim.state(2)["outputs"] == [True, False, False, False]
    assert ros.set_outputs("valves", ["channel_1_output"], [False]).success


def test_a_terminal_power_cycled_is_brought_back_with_its_outputs_off_until_set_again(run):
    sim, _, ros = run[:3]
    recoveries = int(ros.values("valves", lambda v: True, "the valves' status")["recoveries"])
    assert ros.set_outputs("valves", ["channel_2_output"], [True]).success
    ros.io("valves", lambda m: level(m, "channel_2_output") == 1.0, "channel_2_output on")
    sim.command("power_cycle 2")
    # Lost and back may fall between two /diagnostics: the count of recoveries says it happened.
    back = ros.values("valves", lambda v: int(v["recoveries"]) > recoveries, "the valves brought back")
    assert back["output channel_2_output"] == "low", back
    ros.spin_for(0.5)
    assert not any(ros.io("valves").outputs) and sim.state(2)["outputs"] == [False] * 4, "off until set again"
    assert [sim.state(p)["al_state"] for p in range(3)] == ["Op"] * 3
    assert ros.set_outputs("valves", ["channel_2_output"], [True]).success
    ros.io("valves", lambda m: level(m, "channel_2_output") == 1.0, "channel_2_output on again")
    assert sim.state(2)["outputs"] == [False, True, False, False]


def test_akd_top_attached_shows_each_devices_channels(run):
    import asyncio

    from akd_ros.top.app import Top
    from akd_ros.top.ros_source import RosSource

    sim, _, ros = run[:3]
    assert ros.set_outputs("valves", ["channel_2_output"], [True]).success
    sim.command("input 1 3 high")

    async def shows(app: Top) -> None:
        def cell(device: str, column: str) -> str:
            table = app.device_table
            return table.get_cell(device, column).plain if device in table.rows else ""

        async with app.run_test(size=(200, 60)) as pilot:
            deadline = time.monotonic() + 30.0
            while (cell("sensors", "inputs"), cell("valves", "outputs")) != ("0010", "0100"):
                assert time.monotonic() < deadline, [
                    cell(d, c) for d in ("sensors", "valves") for c in ("inputs", "outputs")
                ]
                await pilot.pause(0.05)
            assert (cell("valves", "product"), cell("valves", "slave")) == ("EL2004", "2")
            await pilot.press("q")

    source = RosSource("/akd_node")
    try:
        asyncio.run(shows(Top(source, refresh_s=0.05)))
    finally:
        source.close()
        sim.command("input 1 3 low")
        assert ros.set_outputs("valves", ["channel_2_output"], [False]).success


def test_the_outputs_go_off_when_the_node_deactivates(run):
    sim, _, ros = run[:3]
    assert ros.set_outputs("valves", ["channel_4_output"], [True]).success
    ros.io("valves", lambda m: level(m, "channel_4_output") == 1.0, "channel_4_output on")
    for transition in (Transition.TRANSITION_DEACTIVATE, Transition.TRANSITION_ACTIVATE):
        request = ChangeState.Request(transition=Transition(id=transition))
        assert ros.call(ChangeState, "change_state", request).success, transition
    ros.io("valves", lambda m: not any(m.outputs), "every output off")
    assert sim.state(2)["outputs"] == [False] * 4


def test_the_bag_holds_the_inputs_edge_and_the_output_as_sent(run):
    sim, node, ros, bags = run
    sim.command("input 1 4 high")
    edge = ros.io("sensors", lambda m: level(m, "channel_4_input") == 1.0, "channel_4_input high")
    assert ros.set_outputs("valves", ["channel_1_output"], [True]).success
    sent = ros.io("valves", lambda m: level(m, "channel_1_output") == 1.0, "channel_1_output on")
    stop(node.process)
    recorded = read_bag(bags)
    assert any(m.cycle == edge.cycle and level(m, "channel_4_input") == 1.0 for m in recorded["sensors"]), [
        (m.cycle, list(m.inputs)) for m in recorded["sensors"]
    ]
    assert any(level(m, "channel_1_output") == 1.0 for m in recorded["valves"] if m.cycle >= sent.cycle)


def read_bag(folder: Path) -> dict[str, list]:
    """Every DeviceIO of the bag in `folder`, by device, read with rosbags from the bag's own schemas."""
    from rosbags.highlevel import AnyReader

    (bag,) = [p for p in folder.iterdir() if p.is_dir()]
    found: dict[str, list] = {"sensors": [], "valves": []}
    with AnyReader([bag]) as reader:
        connections = [c for c in reader.connections if c.msgtype == "akd_ros/msg/DeviceIO"]
        assert {c.topic for c in connections} == {f"{NODE}sensors/io", f"{NODE}valves/io"}
        for connection, _, raw in reader.messages(connections=connections):
            message = reader.deserialize(raw, connection.msgtype)
            found[message.device].append(message)
    return found


def test_the_node_runs_the_line_on_the_parameters_akd_scan_wrote_for_it_unchanged(ros_domain, tmp_path):
    # Another domain than the module's node, which is still up.
    domain = DOMAINS[(DOMAINS.index(ros_domain) + 1) % len(DOMAINS)]
    sim = Sim(free_udp_port(), line=LINE)
    node = client = None
    try:
        path = tmp_path / "cell.yaml"
        link = f"udp://127.0.0.1:{sim.port}"
        scan = subprocess.run(
            [BIN / "akd-scan", link, "--params", path], capture_output=True, text=True, timeout=120, check=False
        )
        assert scan.returncode == 0, scan.stderr
        assert "devices: [ek1100_0, el1004_1, el2004_2]" in path.read_text(), path.read_text()
        node = NodeProcess(path, domain)
        client = Client(domain, ("el1004_1", "el2004_2"))
        client.spin_until(
            lambda: client.received[f"{NODE}el2004_2/io"] or node.process.poll() is not None, "~/el2004_2/io"
        )
        assert node.process.poll() is None, node.output()
        sim.command("input 1 3 high")
        client.io("el1004_1", lambda m: level(m, "channel_3_input") == 1.0, "channel_3_input high")
        assert client.set_outputs("el2004_2", ["channel_4_output"], [True]).success
        client.io("el2004_2", lambda m: level(m, "channel_4_output") == 1.0, "channel_4_output on")
        assert sim.state(2)["outputs"] == [False, False, False, True]
    finally:
        if client is not None:
            client.close()
        if node is not None:
            stop(node.process)
            print(f"akd_node output:\n{node.output()}")
        sim.stop()
